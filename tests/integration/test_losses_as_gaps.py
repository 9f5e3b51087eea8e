"""Losses as gaps the estimators see (issue 25 item 5), and "a time-stamp jump or reversal
never reaches an estimator" (its done-when list): on the gy91 board, read by polling, from
its FIFO on a timer, and from its FIFO on data-ready edges, through host stalls, a chip
reset, bus errors and an oscillator 1 % fast that drifts by -0.1 % a second, an estimator that
takes the IMU's gyro frames and their gaps (imuhal.core.gaps.StreamGap) sees

- time stamps that only go forward;
- between two frames, one chip period, or a gap announced just before the second frame
  whose frame count and span are those of the step (never an unexplained jump);
- in the FIFO modes, every frame at its chip's measurement instant;

and the AHRS integrates a step over counted lost frames over its true interval."""

from __future__ import annotations

import types
from bisect import bisect_right
from pathlib import Path
from typing import Any, ClassVar

import pytest

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.gaps import StreamGap
from imuhal.core.samples import AccelSample, Frame, GyroSample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors, ChipReset, FaultSpec, HostStall
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.outputs import Estimate
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

PERIOD_NS = 5_000_000  # the gy91's 200 Hz


class GapSpy(Estimator):
    """Keeps what it is handed: gyro frames and gaps, in order."""

    name: ClassVar[str] = "gap-spy"
    Settings = EstimatorSettings
    consumes: ClassVar[tuple[type, ...]] = (GyroSample, StreamGap)
    seen: ClassVar[list[GyroSample | StreamGap]] = []

    def reset(self) -> None:
        GapSpy.seen = []

    def process(self, item: Any) -> list[Estimate]:
        GapSpy.seen.append(item)
        return []

    def get_state(self) -> dict[str, Any]:
        return {}

    def set_state(self, state: dict[str, Any]) -> None:
        pass


SPY = types.SimpleNamespace(imuhal_register_estimators=hookimpl(
    lambda register: register(GapSpy)))


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry(extra=[("spy", SPY)])


MODES: dict[str, tuple[str, str]] = {
    # mode: (the imu's settings added, its interrupt entry)
    "polling": ("", ""),
    "fifo": ("      read: fifo\n", ""),
    "fifo-on-edges": ("      read: fifo\n",
                      "    interrupt: {chip: gpiochip0, line: 17, edges_per_read: 2}\n"),
}
FAULTS: list[FaultSpec] = [
    HostStall(device="imu", start_s=1.0, stall_s=0.06, every_s=0.7),
    BusErrors(device="imu", rate=0.01, start_s=0.5),
    ChipReset(device="imu", start_s=2.6),
]


def _fly(tmp_path: Path, registry: Registry, mode: str
         ) -> tuple[list[GyroSample | StreamGap], list[int]]:
    settings, interrupt = MODES[mode]
    text = bundled_profiles()["gy91.yaml"].read_text()
    text = text.replace("      aux: bypass\n", "      aux: bypass\n" + settings)
    text = text.replace('    mount: "+X-Y-Z"\n', '    mount: "+X-Y-Z"\n' + interrupt, 1)
    text = text.replace("\nestimators:\n", "\nestimators:\n  spy: {estimator: gap-spy, "
                                           "inputs: [imu]}\n")
    path = tmp_path / "gy91.yaml"
    path.write_text(text)
    with open_emulated(load_profile(path, registry), registry, scenario="thermal", seed=7,
                       faults=FAULTS) as p:
        chip = p.board.emulators["imu"]
        chip.oscillator_error = 0.01
        for _ in p.events(4.0):
            # the oscillator, 1 % fast, drifts by -0.1 % a second (a die heating up far
            # faster than in any flight)
            drifted = round(0.01 - 0.0001 * (p.clock.now_ns() // 100_000_000), 4)
            if drifted != chip.oscillator_error:
                chip.oscillator_error = drifted
        return [s for s in GapSpy.seen if s.device == "imu"], list(chip.measured_ns)


@pytest.mark.parametrize("mode", sorted(MODES))
def test_a_time_stamp_jump_or_reversal_never_reaches_an_estimator(
        tmp_path: Path, registry: Registry, mode: str) -> None:
    seen, instants = _fly(tmp_path, registry, mode)
    gyros = [s for s in seen if isinstance(s, GyroSample)]
    gaps = [s for s in seen if isinstance(s, StreamGap)]
    assert len(gyros) > 400 and gaps  # the faults cost frames, announced
    before: StreamGap | None = None
    previous: GyroSample | None = None
    for item in seen:
        if isinstance(item, StreamGap):
            before = item
            continue
        if previous is not None:
            step = item.t_ns - previous.t_ns
            assert step > 0, (mode, item.t_ns)
            if before is None:
                assert step < 1.5 * PERIOD_NS, (mode, item.t_ns, step)
            else:
                assert (before.t_ns, before.last_ns) == (item.t_ns, previous.t_ns)
                assert before.frames == round(step / PERIOD_NS) - 1 >= 1
        before, previous = None, item
    if mode != "polling":  # stamped on the chip's clock or its edges: the instants
        errors = [min(abs(g.t_ns - x) for x in instants[max(i - 1, 0):i + 1])
                  for g in gyros for i in [bisect_right(instants, g.t_ns)]]
        assert max(errors) < 200_000, mode


def test_a_counted_loss_is_integrated_over_its_true_interval(registry: Registry) -> None:
    """The AHRS's step after a StreamGap of 0.3 s (beyond ``max_dt_s``) turns it through the
    rate times 0.3 s; the same step without the gap (a time stamp nobody explained) turns
    it through one nominal period. (A level accelerometer reading confirms the tilt after
    the unmeasured span, so the estimate is handed out, not withheld.)"""
    ahrs = registry.estimators.get("madgwick")({"beta": 0.0, "use_mag": False,
                                                "initial_attitude": "identity"})
    rate = 0.1  # rad/s about body z (small steps: the first-order update is exact to 1e-4)
    first = GyroSample(t_ns=0, device="imu", frame=Frame.BODY_NED, gyro_rad_s=(0.0, 0.0, rate))
    after = GyroSample(t_ns=300_000_000, device="imu", frame=Frame.BODY_NED,
                       gyro_rad_s=(0.0, 0.0, rate))
    gap = StreamGap(t_ns=after.t_ns, device="imu", stream=GyroSample.channel, frames=59,
                    last_ns=0, cause="host_stall")
    level = AccelSample(t_ns=after.t_ns - 1, device="imu", frame=Frame.BODY_NED,
                        accel_m_s2=(0.0, 0.0, -STANDARD_GRAVITY_M_S2))

    def yaw_after(items: list[Any]) -> float:
        ahrs.reset()
        out = [e for item in items for e in ahrs.process(item)]
        return abs(out[-1].roll_pitch_yaw_deg[2])

    assert yaw_after([first, gap, level, after]) == pytest.approx(
        yaw_after([first]) + 0.3 * rate * 57.29578, rel=1e-3)
    assert yaw_after([first, level, after]) == pytest.approx(2 * yaw_after([first]), rel=1e-3)
