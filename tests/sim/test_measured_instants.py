"""An emulated chip's record of its measurement instants (``ChipEmulator.measured_ns``) stays
bounded: runs of the chip's period, one per break of its cadence, not one number per
measurement (issue 26: the soak's RSS grew about 3 MB per 1,000 simulated s, this record
at 8 bytes a measurement on every chip), and it answers as the plain sequence did."""

from __future__ import annotations

import random
from bisect import bisect_right

import numpy as np
import pytest

from imuhal.emulation import open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sim.measured import MeasuredInstants


def test_an_hour_at_a_fixed_period_is_one_run() -> None:
    record = MeasuredInstants()
    period_ns = 5_000_000  # 200 Hz, recorded as emulators do: one by one and in catch-ups
    t = 1_234
    for k in range(3600 * 200 // 4):
        count = 1 if k % 2 else 3
        record.add(t, period_ns, count)
        t += count * period_ns
    assert len(record) == 3600 * 200 // 4 * 2
    assert record.runs == 1
    assert record[-1] == 1_234 + (len(record) - 1) * period_ns


def test_each_break_of_the_cadence_costs_one_run() -> None:
    record = MeasuredInstants()
    record.add(0, 10, 100)
    record.add(2_000, 10, 50)  # the schedule restarted (a reset)
    record.add(2_500, 10, 1)
    record.add(2_507, 7, 1)  # another period (a reconfiguration)
    record.add(2_514, 7, 10)
    assert record.runs == 3 and len(record) == 162


def _irregular(seed: int) -> tuple[MeasuredInstants, list[int]]:
    """The same calls into the record and into a plain list of instants."""
    rng = random.Random(seed)
    record, plain = MeasuredInstants(), []
    t = rng.randrange(10**6)
    for _ in range(300):
        period = rng.choice((0, 3, 5, 5, 5, 7))
        count = rng.choice((1, 1, 2, 4))
        if period == 0:
            count = 1
        record.add(t, period, count)
        plain += [t + k * period for k in range(count)]
        t = plain[-1] + rng.choice((0, 5, 5, 9, 40)) if period else plain[-1] + 5
    return record, plain


@pytest.mark.parametrize("seed", range(5))
def test_the_record_reads_as_the_sequence_of_instants(seed: int) -> None:
    record, plain = _irregular(seed)
    assert len(record) == len(plain) and list(record) == plain
    assert [record[i] for i in (0, 1, len(plain) // 2, -1, -2)] == \
        [plain[i] for i in (0, 1, len(plain) // 2, -1, -2)]
    assert record[10:40] == plain[10:40] and record[-5:] == plain[-5:]
    assert np.array_equal(np.asarray(record), np.array(plain, dtype=np.int64))
    for t in range(plain[0] - 3, plain[-1] + 4):
        assert record.count_until(t) == bisect_right(plain, t)
    with pytest.raises(IndexError):
        record[len(plain)]


def test_a_measurement_before_the_last_one_is_refused() -> None:
    record = MeasuredInstants()
    record.add(100, 10, 3)
    with pytest.raises(ValueError, match="before the last one"):
        record.add(110, 10, 1)


def test_a_board_flying_on_keeps_its_records_size() -> None:
    """Every emulated chip of the GPS vario, 10 s and then 20 s more without faults: the
    records hold as many runs as before, while their measurements triple."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1, calibrated=False) as pipeline:
        emulators = pipeline.board.emulators  # type: ignore[attr-defined]  # emulated board
        for _ in pipeline.events(10.0):
            pass
        before = {name: (len(e.measured_ns), e.measured_ns.runs)
                  for name, e in emulators.items()}
        for _ in pipeline.events(20.0):
            pass
        after = {name: (len(e.measured_ns), e.measured_ns.runs)
                 for name, e in emulators.items()}
    recorded = [name for name, (n, _) in before.items() if n]
    assert set(recorded) == {"imu", "mag", "baro"}
    for name in recorded:
        assert after[name][0] > 2.5 * before[name][0]
        assert after[name][1] == before[name][1] <= 2
