"""The seed board's MAX21100, read from its FIFO or one frame at a time, takes the inputs of
its instants from the board computed ahead in one vectorised pass per second of its clock
(``ChipEmulator.physics_ahead``, ``Scenario.chip_truth_columns``, the error model's
``plan_values``), and the run is bit for bit the run that computes them instant by instant:
the vectorised truth and errors give the same floats (tests/sim/test_chip_truths.py,
tests/sim/test_error_plan.py), so every frame, and every event built from the frames, is
the same. In fills of 8 frames and frame by frame, with the datasheet's clock and with a
2 % fast one set after start (pulls announced on the datasheet's clock are computed again
when they come elsewhere)."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from imuhal.emulation import open_emulated
from imuhal.emulation.board import EmulatedBoard
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile
from imuhal.sim.scenario import TruthColumns


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _seed(registry: Registry, fifo: bool) -> BoardProfile:
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    if not fifo:
        return profile
    device = profile.devices["imu"]
    settings = {**device.settings, "read": "fifo", "fifo_frames": 8}
    return profile.model_copy(update={"devices": {
        **profile.devices, "imu": device.model_copy(update={"settings": settings})}})


def _fly(registry: Registry, *, ahead: bool, fifo: bool, oscillator_error: float = 0.0
         ) -> tuple[list[str], int]:
    """(every event's repr, instants whose truth was computed ahead) over 2 s, airborne and
    circling in a thermal from the start (the default waits 5 s on launch, where the truth
    does not change), without the start-up gyro calibration (it waits for rest)."""
    with open_emulated(_seed(registry, fifo), registry, scenario="thermal", seed=2,
                       scenario_params={"launch_s": 0.0, "schedule": [[0.0, 2.5]]},
                       calibrated=False) as p:
        board = EmulatedBoard.of(p)
        imu = board.emulators["imu"]
        assert imu.physics_ahead is not None  # the board wires it for a chip with a clock
        counted = [0]
        scenario = board.scenario
        vectorised = scenario.chip_truth_columns

        def spy(t_s: Sequence[float]) -> TruthColumns | None:
            counted[0] += len(t_s)
            return vectorised(t_s)

        scenario.chip_truth_columns = spy  # type: ignore[method-assign]  # a counting spy
        if not ahead:  # a board that computes no inputs ahead (the MAX21100, the HMC5883L)
            for emulator in board.emulators.values():
                emulator.physics_ahead = None
        # set after start: the instants announced on the datasheet's clock move
        imu.oscillator_error = oscillator_error
        events = [repr(e) for e in p.events(2.0)]
    return events, counted[0]


@pytest.mark.parametrize("fifo", [True, False], ids=["fifo", "one-frame"])
@pytest.mark.parametrize("oscillator_error", [0.0, 0.02])
def test_inputs_computed_ahead_are_bit_for_bit_the_inputs_computed_per_instant(
        registry: Registry, oscillator_error: float, fifo: bool) -> None:
    ahead, computed_ahead = _fly(registry, ahead=True, fifo=fifo,
                                 oscillator_error=oscillator_error)
    per_instant, none_ahead = _fly(registry, ahead=False, fifo=fifo,
                                   oscillator_error=oscillator_error)
    assert none_ahead == 0
    assert computed_ahead >= 2 * 250  # every instant of the 2 s, and the next second's
    rates = {e.split("gyro_rad_s=")[1] for e in ahead
             if e.startswith("GyroSample(") and "nan" not in e}
    assert len(rates) > 400  # the truth moves: a frame with another instant's truth shows
    assert ahead == per_instant
