"""Issue 26 item 3: third-party plugins are contained. Each plugin here is registered as a
third party registers one (hook implementations handed to the plugin manager), on the seed
board: whatever it does wrong stays with it, is named (plugin and distribution) and counted,
and the rest of the board keeps running."""

from __future__ import annotations

import csv
import io
import math
import signal
import time
import types
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

from imuhal.cli import main as cli_main
from imuhal.core.blocks import Block
from imuhal.core.clock import MonotonicClock, SimulatedClock
from imuhal.core.samples import AccelSample, Frame, GyroSample, PressureSample
from imuhal.drivers.base import PollResult
from imuhal.emulation import open_emulated
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.outputs import (
    AttitudeBlock,
    AttitudeEstimate,
    Estimate,
    EstimateFlag,
    RejectedEstimate,
    VerticalEstimate,
)
from imuhal.pipeline import CsvSink
from imuhal.pipeline.containment import (
    BLOCKED_WALL_S,
    DISABLE_AFTER_FAILURES,
    DriverTiming,
    EstimatorGuard,
    PluginFaults,
    driver_timing,
)
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.sinks.builtin import ConsoleSink, event_row
from imuhal_chips.ms5611.driver import MS5611Driver
from imuhal_chips.ms5611.emulator import MS5611Emulator

SECOND_NS = 1_000_000_000


class _Quiet(Estimator):
    """Shared boilerplate of the estimators below."""

    Settings = EstimatorSettings
    consumes: ClassVar[tuple[type, ...]] = (PressureSample,)

    def reset(self) -> None:
        pass

    def process(self, item: Any) -> list[Estimate]:
        return []

    def get_state(self) -> dict[str, Any]:
        return {}

    def set_state(self, state: dict[str, Any]) -> None:
        pass


class RaisesLater(_Quiet):
    """Raises ValueError for every pressure sample after 1 s."""

    name: ClassVar[str] = "acme-raises"

    def process(self, item: Any) -> list[Estimate]:
        if item.t_ns > SECOND_NS:
            raise ValueError("acme: matrix not positive definite")
        return []


class NanAttitude(_Quiet):
    """An AHRS whose state went NaN: every estimate's quaternion is NaN."""

    name: ClassVar[str] = "acme-nan-ahrs"
    consumes: ClassVar[tuple[type, ...]] = (GyroSample,)

    def process(self, item: Any) -> list[Estimate]:
        nan = float("nan")
        return [AttitudeEstimate(t_ns=item.t_ns, source=self.instance,
                                 q_body_to_ned=(nan, nan, nan, nan))]


class ZeroQuaternion(_Quiet):
    """An AHRS that returns the zero quaternion: finite, but no rotation."""

    name: ClassVar[str] = "acme-zero-ahrs"
    consumes: ClassVar[tuple[type, ...]] = (AccelSample,)

    def process(self, item: Any) -> list[Estimate]:
        return [AttitudeEstimate(t_ns=item.t_ns, source=self.instance,
                                 q_body_to_ned=(0.0, 0.0, 0.0, 0.0))]


class Slow(_Quiet):
    """Takes 30 ms per pressure sample (50 Hz): 1.5 s of computing per second of data."""

    name: ClassVar[str] = "acme-slow"

    def process(self, item: Any) -> list[Estimate]:
        time.sleep(0.03)
        return []


class HangingBaro(MS5611Driver):
    """The MS5611 driver of a plugin whose poll never returns after 1 s."""

    name: ClassVar[str] = "acme-ms5611-hangs"

    def poll(self, now_ns: int) -> PollResult:
        while now_ns > SECOND_NS:
            time.sleep(3600)
        return super().poll(now_ns)


class SpinningBaro(MS5611Driver):
    """The MS5611 driver of a plugin whose poll after 1 s loops forever on the CPU."""

    name: ClassVar[str] = "acme-ms5611-spins"

    def poll(self, now_ns: int) -> PollResult:
        while now_ns > SECOND_NS:
            math.fsum(range(1000))
        return super().poll(now_ns)


class StarvedBaro(MS5611Driver):
    """The MS5611 driver as a starved host runs it: one poll after 1 s returns 1.5 s later
    on the wall clock, having used almost no CPU time (as when the scheduler runs other
    processes instead)."""

    name: ClassVar[str] = "acme-ms5611-starved"
    _starved = False

    def poll(self, now_ns: int) -> PollResult:
        if now_ns > SECOND_NS and not self._starved:
            self._starved = True
            time.sleep(1.5)
        return super().poll(now_ns)


class BuggyBaro(MS5611Driver):
    """The MS5611 driver of a plugin with a bug: a plain ValueError from every poll after
    1 s (its probe and configuration still work)."""

    name: ClassVar[str] = "acme-ms5611-buggy"

    def poll(self, now_ns: int) -> PollResult:
        if now_ns > SECOND_NS:
            raise ValueError("acme: unpack requires a buffer of 3 bytes")
        return super().poll(now_ns)


class HangingEmulator(MS5611Emulator):
    chip = "acme-ms5611-hangs"


class BuggyEmulator(MS5611Emulator):
    chip = "acme-ms5611-buggy"


class SpinningEmulator(MS5611Emulator):
    chip = "acme-ms5611-spins"


class StarvedEmulator(MS5611Emulator):
    chip = "acme-ms5611-starved"


ACME = types.SimpleNamespace(
    imuhal_register_estimators=hookimpl(lambda register: [
        register(cls) for cls in (RaisesLater, NanAttitude, ZeroQuaternion, Slow)]),
    imuhal_register_drivers=hookimpl(lambda register: [
        register(cls) for cls in (HangingBaro, BuggyBaro, SpinningBaro, StarvedBaro)]),
    imuhal_register_emulators=hookimpl(lambda register: [
        register(cls) for cls in (HangingEmulator, BuggyEmulator, SpinningEmulator,
                                  StarvedEmulator)]),
)
"""The third party's plugin module: hook implementations, as its entry point would load."""


@pytest.fixture(scope="module")
def acme_registry() -> Registry:
    return load_registry(extra=[("acme", ACME)])


def _board(tmp_path: Path, *, estimator: str | None = None, inputs: str = "[baro]",
           baro_driver: str = "ms5611") -> Path:
    """The seed board, with one more estimator and/or another barometer driver."""
    text = default_profile_path().read_text()
    if estimator is not None:
        text = text.replace("\nestimators:\n", f"\nestimators:\n  acme: {{estimator: {estimator}"
                            f", inputs: {inputs}}}\n")
    text = text.replace("    driver: ms5611\n", f"    driver: {baro_driver}\n")
    path = tmp_path / "board.yaml"
    path.write_text(text)
    return path


def _run(registry: Registry, path: Path, seconds: float, sinks: list[Any] | None = None,
         timing: DriverTiming | None = None) -> tuple[Any, list[Any]]:
    events: list[Any] = []

    class Keep:
        def handle(self, event: Any) -> None:
            events.append(event)

        def close(self) -> None:
            pass

    with open_emulated(load_profile(path, registry), registry, scenario="thermal") as p:
        if timing is not None:
            p.driver_timing = timing
        summary = p.run(seconds, [Keep(), *(sinks or [])])
    return summary, events


def _after(events: list[Any], kind: type, t_ns: int, source: str | None = None) -> list[Any]:
    return [e for e in events if isinstance(e, kind) and e.t_ns > t_ns
            and (source is None or getattr(e, "source", getattr(e, "device", None)) == source)]


def test_an_estimator_that_raises_is_named_counted_and_disabled_alone(
        acme_registry: Registry, tmp_path: Path) -> None:
    summary, events = _run(acme_registry, _board(tmp_path, estimator="acme-raises"), 4.0)
    first = [w for w in summary.warnings if w.startswith("estimator 'acme'")]
    assert first[0].startswith("estimator 'acme' (acme-raises; plugin 'acme') raised "
                               "ValueError: acme: matrix not positive definite at t=1.0")
    assert first[0].endswith("; that input is skipped for it alone")
    assert "disabled after 10 failures within 10 s" in first[1]
    counts = summary.contained["estimator 'acme'"]
    assert counts == {"exceptions": DISABLE_AFTER_FAILURES, "disabled": 1}
    # the board's own estimators go on to the end
    assert _after(events, VerticalEstimate, 3_900_000_000, "vario")
    assert _after(events, AttitudeEstimate, 3_900_000_000, "ahrs")


def test_a_nan_quaternion_never_reaches_a_sink_as_a_number(
        acme_registry: Registry, tmp_path: Path) -> None:
    out = tmp_path / "flight.csv"
    console = io.StringIO()
    board = _board(tmp_path, estimator="acme-nan-ahrs", inputs="[imu]")
    # 2 s: the vario withholds its first estimates for about 0.8 s, until it has settled
    summary, events = _run(acme_registry, board, 2.0,
                           [CsvSink(out), ConsoleSink(console, every_s=0.01)])
    rejected = [e for e in events if isinstance(e, RejectedEstimate) and e.source == "acme"]
    assert rejected and all(e.estimator == "acme-nan-ahrs"
                            and e.flags == EstimateFlag.NOT_FINITE | EstimateFlag.NOT_NORMALISABLE
                            and e.kind == "attitude" for e in rejected)
    # the board's own vertical filters withhold nothing but their first estimates, until
    # they have settled
    others = [e for e in events if isinstance(e, RejectedEstimate) and e.source != "acme"]
    assert all(e.kind == "vertical" and e.flags == EstimateFlag.UNSETTLED
               and e.t_ns < 1.5e9 for e in others)
    assert not [e for e in events if isinstance(e, AttitudeEstimate) and e.source == "acme"]
    with out.open() as f:
        rows = [r for r in csv.DictReader(f) if r["source"] == "acme"]
    assert rows and all(r["flags"] == "3" and r["kind"] == "attitude" and r["qw"] == ""
                        for r in rows)
    assert console.getvalue() and "nan" not in console.getvalue()
    assert summary.contained["estimator 'acme'"]["disabled"] == 1
    assert any("made an attitude estimate that is not finite and not normalisable" in w
               for w in summary.warnings)
    # the vario, fed by the seed's own AHRS, never saw them
    assert _after(events, VerticalEstimate, 1_900_000_000, "vario")


def test_a_zero_quaternion_is_flagged_not_normalisable() -> None:
    from imuhal.estimation.outputs import estimate_flags
    zero = AttitudeEstimate(t_ns=0, source="a", q_body_to_ned=(0.0, 0.0, 0.0, 0.0))
    unit = AttitudeEstimate(t_ns=0, source="a", q_body_to_ned=(1.0, 0.0, 0.0, 0.0),
                            linear_accel_ned_m_s2=(0.0, math.inf, 0.0))
    assert estimate_flags(zero) == EstimateFlag.NOT_NORMALISABLE
    assert estimate_flags(unit) == EstimateFlag.NOT_FINITE
    assert estimate_flags(VerticalEstimate(t_ns=0, source="v", altitude_m=math.nan,
                                           climb_m_s=0.0)) == EstimateFlag.NOT_FINITE
    row = event_row(RejectedEstimate(t_ns=0, source="a", kind="attitude",
                                     flags=EstimateFlag.NOT_NORMALISABLE, estimator="x"))
    assert row == {"t_s": "0.000000", "source": "a", "flags": "2", "kind": "attitude"}


def test_a_driver_whose_poll_never_returns_is_isolated_and_the_board_goes_on(
        acme_registry: Registry, tmp_path: Path) -> None:
    """An emulated run times driver calls on CPU time; one that blocks (a sleep of an
    hour) is cut off by the wall-clock bound (shortened here from BLOCKED_WALL_S)."""
    board = _board(tmp_path, baro_driver="acme-ms5611-hangs")
    t0 = time.monotonic()
    summary, events = _run(acme_registry, board, 3.0,
                           timing=DriverTiming(cpu=True, blocked_wall_s=2.0))
    assert time.monotonic() - t0 < 60
    warning = next(w for w in summary.warnings if w.startswith("driver of 'baro'"))
    assert warning.startswith("driver of 'baro' (acme-ms5611-hangs; plugin 'acme') disabled at "
                              "t=1.0")
    assert "did not return from a call within its deadline of 1 s of CPU time" in warning
    assert "or 2 s on the wall clock" in warning
    assert "device 'baro' is isolated" in warning
    assert summary.contained["driver of 'baro'"] == {"deadlines_missed": 1, "disabled": 1}
    assert not _after(events, PressureSample, 1_100_000_000)
    assert _after(events, GyroSample, 2_900_000_000, "imu")


def test_an_emulated_driver_spinning_on_the_cpu_is_cut_off_at_its_cpu_deadline(
        acme_registry: Registry, tmp_path: Path) -> None:
    t0 = time.monotonic()
    summary, events = _run(acme_registry, _board(tmp_path, baro_driver="acme-ms5611-spins"),
                           3.0)
    assert time.monotonic() - t0 < BLOCKED_WALL_S  # the CPU timer, not the wall bound
    assert summary.contained["driver of 'baro'"] == {"deadlines_missed": 1, "disabled": 1}
    assert not _after(events, PressureSample, 1_100_000_000)
    assert _after(events, GyroSample, 2_900_000_000, "imu")


def test_an_emulated_run_starved_of_the_cpu_keeps_every_device(
        acme_registry: Registry, tmp_path: Path) -> None:
    """A call that took 1.5 s on the wall clock but no CPU time (the host ran others) is not
    a driver overrunning its 1 s deadline: the emulated run's figures stay those of an
    unloaded host."""
    summary, events = _run(acme_registry, _board(tmp_path, baro_driver="acme-ms5611-starved"),
                           3.0)
    assert "driver of 'baro'" not in summary.contained
    assert _after(events, PressureSample, 2_900_000_000, "baro")


def test_on_the_wall_clock_the_same_slow_call_is_cut_off(
        acme_registry: Registry, tmp_path: Path) -> None:
    """A hardware board's timing: a chip that does not answer within the deadline is late,
    whatever the reason."""
    summary, _ = _run(acme_registry, _board(tmp_path, baro_driver="acme-ms5611-starved"), 3.0,
                      timing=DriverTiming(cpu=False))
    warning = next(w for w in summary.warnings if w.startswith("driver of 'baro'"))
    assert "within its deadline of 1 s (from its chip's rate)" in warning
    assert summary.contained["driver of 'baro'"] == {"deadlines_missed": 1, "disabled": 1}


def test_no_watchdog_timer_is_left_running_when_an_emulated_run_loop_ends(
        acme_registry: Registry, tmp_path: Path) -> None:
    """On CPU time the watchdog's timers tick through a run (no system call per driver
    call); a program between runs, or one whose pipeline is still open, gets no signal."""
    board = _board(tmp_path)
    with open_emulated(load_profile(board, acme_registry), acme_registry,
                       scenario="thermal") as pipeline:
        for _ in pipeline.events(0.2):
            assert signal.getitimer(signal.ITIMER_PROF)[1] > 0  # ticking in the run
        assert signal.getitimer(signal.ITIMER_PROF) == (0.0, 0.0)
        assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
        stopped_early = pipeline.events(1.0)
        next(stopped_early)
        stopped_early.close()
        assert signal.getitimer(signal.ITIMER_PROF) == (0.0, 0.0)


def test_hardware_boards_time_driver_calls_on_the_wall_and_others_on_cpu_time() -> None:
    assert driver_timing(types.SimpleNamespace(clock=MonotonicClock())).cpu is False
    assert driver_timing(types.SimpleNamespace(clock=SimulatedClock())).cpu is True


def test_a_driver_raising_a_plain_value_error_is_contained_to_its_device(
        acme_registry: Registry, tmp_path: Path) -> None:
    summary, events = _run(acme_registry, _board(tmp_path, baro_driver="acme-ms5611-buggy"),
                           3.0)
    warnings = [w for w in summary.warnings if w.startswith("driver of 'baro'")]
    assert warnings[0].startswith("driver of 'baro' (acme-ms5611-buggy; plugin 'acme') raised "
                                  "ValueError: acme: unpack requires a buffer of 3 bytes at t=1.")
    assert "device 'baro' is isolated" not in warnings[0]
    assert "disabled after 10 failures within 10 s" in warnings[1]
    assert summary.contained["driver of 'baro'"] == {"exceptions": 10, "disabled": 1}
    assert summary.device_errors["baro"] == 10
    assert _after(events, GyroSample, 2_900_000_000, "imu")


def test_a_slow_estimator_in_a_realtime_run_is_reported_once_with_its_cost(
        acme_registry: Registry, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(cli_main, "load_registry", lambda: acme_registry)
    board = _board(tmp_path, estimator="acme-slow")
    code = cli_main.main(["run", str(board), "--emulate", "static", "--realtime",
                          "--skip-calibration", "--duration", "3.5", "--quiet"])
    err = capsys.readouterr().err
    assert code == 0
    slow = [line for line in err.splitlines() if "is slow" in line]
    assert len(slow) == 1
    words = slow[0].split()
    cost_ms = float(words[words.index("ms") - 1])
    assert 30 <= cost_ms < 500  # the sleep is 30 ms; a loaded host oversleeps
    assert slow[0].startswith("  warning: estimator 'acme' (acme-slow; plugin 'acme') is slow: ")


class BlockAhrs(_Quiet):
    """An AHRS that makes its estimates of a block as AttitudeBlocks (as Madgwick's block
    step does): a good one, then one whose third row's acceleration is NaN."""

    name: ClassVar[str] = "acme-block-ahrs"
    consumes: ClassVar[tuple[type, ...]] = (GyroSample,)

    def estimate_blocks(self, blocks: Sequence[Block]) -> list[Estimate | AttitudeBlock]:
        t = blocks[0].t_ns
        q = np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))
        bad = np.zeros((len(t), 3))
        bad[2, 1] = math.nan
        return [AttitudeBlock(self.instance, t, q, np.zeros((len(t), 3)),
                              lambda: [{} for _ in t]),
                AttitudeBlock(self.instance, t, q, bad, lambda: [{} for _ in t])]


def test_an_attitude_block_with_one_bad_row_is_checked_row_by_row() -> None:
    """The guard passes an AttitudeBlock whose every row passes the estimate check whole (no
    row built); a block with one bad row goes out as its rows, that row refused as a
    single estimate would be (counted, named)."""
    warnings: list[str] = []
    faults = PluginFaults("estimator 'acme'", "acme")
    guard = EstimatorGuard(BlockAhrs(instance="acme"), faults, warnings.append)
    t = np.arange(5, dtype=np.int64) * 4_000_000
    gyro = Block.from_arrays(GyroSample, "imu", 0, t, np.zeros((5, 3)),
                             np.zeros(5, np.int64), frame=Frame.BODY_NED)
    good, *rest = guard.estimate_blocks([gyro])
    assert isinstance(good, AttitudeBlock) and good._rows is None
    assert [type(e) for e in rest] == [AttitudeEstimate] * 2 + [RejectedEstimate] + \
        [AttitudeEstimate] * 2
    assert rest[2].flags == EstimateFlag.NOT_FINITE and rest[2].t_ns == 8_000_000
    assert faults.counts["rejected_attitude_estimates"] == 1
    assert len(warnings) == 1 and "not finite" in warnings[0]
