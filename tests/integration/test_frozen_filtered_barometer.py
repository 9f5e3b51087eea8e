"""A BMP280 whose conversions hang behind its IIR filter (the GY-91's barometer), through
the fault-injection interface; found by the soak on every bundled board
(tests/benchmarks/soak.py).

The soak's gy91 run froze the barometer in a glide: the driver waited for 41 identical
outputs (a window sized for the unfiltered x1 chip, then grown with the filter; now the
ceiling of a window learned from the chip's own repeat odds), so the
frozen pressure stayed valid for a second while the flight moved on, and after the chip
thawed its filter blended the frozen word into outputs that left valid, up to 50 Pa off.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pytest

from imuhal.core.samples import PressureSample, SampleFlag
from imuhal.emulation import error_models_for, open_emulated
from imuhal.emulation.faults import FrozenData
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

FROZEN_FROM_S = 8.0
FROZEN_TO_S = 11.0
CLIMB_M_S = 2.2
"""The thermal scenario's climb: 26 Pa a second at the gy91's altitude."""
NOISE_TOLERANCE_PA = 6 * 1.3 + 2 * 0.16
"""The soak's tolerance for a BMP280 pressure: 6 sigma of datasheet noise, two words."""


PERIOD_S = 0.025
"""The gy91 BMP280's output period (forced mode at 40 Hz)."""


@dataclass
class FrozenClimb:
    """Every pressure of a climbing gy91 whose barometer freezes for 3 s, with its error
    against the truth plus the error model's own bias (the closest of the time stamp and
    up to three 25 ms steps before it: the conversion's latency), and with its error
    against the world of up to ``detection_outputs`` outputs before it (the closest)."""

    samples: list[tuple[PressureSample, float]]
    held_errors: list[float]
    detection_outputs: int


@pytest.fixture(scope="module")
def frozen_climb() -> FrozenClimb:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    model = error_models_for(profile, registry, 1)["baro"]
    out: list[tuple[PressureSample, float]] = []
    held: list[float] = []
    with open_emulated(profile, registry, seed=1,
                       faults=[FrozenData(device="baro", start_s=FROZEN_FROM_S,
                                          end_s=FROZEN_TO_S)],
                       scenario_params={"schedule": ((0.0, 0.0), (2.0, CLIMB_M_S))}) as p:
        scenario: Any = p.board.scenario  # type: ignore[attr-defined]
        driver: Any = p.devices["baro"].driver
        outputs = 0

        def error(event: PressureSample, lag_s: float) -> float:
            t_s = max(0.0, event.t_ns / 1e9 - lag_s)
            truth = scenario.truth(t_s)
            bias = float(model.bias("pressure", truth.temperature_degc, t_s))  # type: ignore[arg-type]
            return abs(event.pressure_pa - truth.pressure_pa - bias)

        for event in p.events(FROZEN_TO_S + 3.0):
            if isinstance(event, PressureSample):
                if not outputs and event.t_ns / 1e9 >= FROZEN_FROM_S:
                    # as the driver stated it when the chip hung (it learns the window
                    # again after the recovery that follows)
                    outputs = driver.frozen_detection_outputs()
                out.append((event, min(error(event, k * PERIOD_S) for k in range(4))))
                held.append(min(error(event, k * PERIOD_S) for k in range(max(outputs, 1) + 4)))
    return FrozenClimb(out, held, outputs)


def test_a_frozen_bmp280_behind_its_filter_is_flagged_within_its_stated_detection_time(
        frozen_climb: FrozenClimb) -> None:
    """At coefficient 4 the filtered word is 20 bits: a working chip repeats it far less
    often than the unfiltered x1 chip the fixed window (41) was sized for. The driver learns
    how often this chip repeats at start-up (13 outputs here), so the frozen chip is flagged
    that many outputs after its filter has settled on the hung word: within the
    ``frozen_detection_outputs`` the driver states (27, 0.68 s at 40 Hz)."""
    samples = frozen_climb.samples
    frozen = [s.t_ns / 1e9 for s, _ in samples if s.flags & SampleFlag.FROZEN]
    assert frozen_climb.detection_outputs == 27
    assert frozen and FROZEN_FROM_S < frozen[0] <= \
        FROZEN_FROM_S + frozen_climb.detection_outputs * PERIOD_S
    before = [err for s, err in samples if s.valid and s.t_ns / 1e9 < FROZEN_FROM_S]
    assert max(before) < NOISE_TOLERANCE_PA  # the comparison itself is sound


def test_every_valid_output_of_a_frozen_bmp280_is_the_world_of_its_detection_time(
        frozen_climb: FrozenClimb) -> None:
    """Until the window is full a hung chip looks like a quiet one: its last valid outputs
    hold the world of when it hung, 10.1 and 10.7 Pa from the truth at their stamps in the
    2.2 m/s climb (the noise tolerance is 8.1 Pa). That is the stated cost of a hang: every
    valid output is within noise of the world at most ``frozen_detection_outputs`` before
    it, never a value the world did not have."""
    in_freeze = [(s, err, held) for (s, err), held in
                 zip(frozen_climb.samples, frozen_climb.held_errors, strict=True)
                 if s.valid and FROZEN_FROM_S <= s.t_ns / 1e9 < FROZEN_TO_S]
    assert max(err for _, err, _ in in_freeze) > NOISE_TOLERANCE_PA  # the cost is real
    assert max(held for _, _, held in in_freeze) < NOISE_TOLERANCE_PA


def test_the_outputs_after_a_frozen_bmp280_thaws_are_filter_settling(
        frozen_climb: FrozenClimb) -> None:
    """The hung converter fed its IIR filter the old word, so the outputs after it thaws
    carry it: they are FILTER_SETTLING, and every valid one is within noise of the truth."""
    after = [(s, err) for s, err in frozen_climb.samples if s.t_ns / 1e9 >= FROZEN_TO_S]
    assert any(s.flags & SampleFlag.FILTER_SETTLING for s, _ in after)
    assert [round(err, 1) for s, err in after if s.valid and err > NOISE_TOLERANCE_PA] == []
    assert sum(s.valid for s, _ in after) > 10
