"""A GNSS receiver whose navigation engine hangs (the ``frozen`` fault): it keeps sending
its last solution with each new epoch's time. The emulator used to ignore the fault; the
driver flags every repeated epoch FROZEN, so no stale velocity reaches the AHRS's turn
compensation as valid, and a receiver at rest that honestly repeats itself is not flagged."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("pynmea2", reason="the gps extra (pynmea2, pyubx2) is not installed")
pytest.importorskip("pyubx2", reason="the gps extra (pynmea2, pyubx2) is not installed")

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.samples import PositionSample, SampleFlag, VelocitySample
from imuhal.emulation import EmulatedBus, open_emulated
from imuhal.emulation.faults import FrozenData
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sim.world import physical_inputs
from imuhal_chips.gnss.driver import GnssDriver, GnssSettings
from imuhal_chips.gnss.emulator import GnssEmulator, GnssErrorModel

VELOCITY_TOLERANCE_M_S = 2.0
"""As tests/integration/test_gnss_recovery.py: 6 sigma of the receiver's speed accuracy plus
what 0.2 s of a manoeuvre moves the velocity."""


def test_a_frozen_receiver_s_repeated_epochs_are_flagged_frozen_never_valid() -> None:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    # the take-off run: the receiver hangs at 7.6 m/s while the aeroplane speeds up to 20
    # (the flight ends before the loop at 16.5 s)
    faults = [FrozenData(device="gps", start_s=5.0, end_s=15.0)]
    with open_emulated(profile, registry, seed=1, faults=faults,
                       scenario="rc-flight") as pipeline:
        scenario = pipeline.board.scenario  # type: ignore[attr-defined]
        gnss = [e for e in pipeline.events(16.5)
                if isinstance(e, VelocitySample | PositionSample) and e.device == "gps"]
        frozen_epochs = pipeline.devices["gps"].driver.stats.frozen_epochs
    velocities = [v for v in gnss if isinstance(v, VelocitySample)]
    frozen = [v for v in velocities if SampleFlag.FROZEN in v.flags]
    # the profile's 5 Hz for 10 s, less the epoch the freeze repeats first
    assert len(frozen) >= 45 and frozen_epochs == len(frozen)
    assert all(5.0 <= v.t_ns / 1e9 <= 15.1 for v in frozen)
    # the positions of those epochs too
    assert sum(SampleFlag.FROZEN in p.flags for p in gnss
               if isinstance(p, PositionSample)) == len(frozen)
    wrong = [(v.t_ns / 1e9, v.velocity_ned_m_s) for v in velocities if v.valid and min(
        math.dist(v.velocity_ned_m_s, scenario.truth(v.t_ns / 1e9 - lag).velocity_ned_m_s)
        for lag in (0.0, 0.1, 0.2)) > VELOCITY_TOLERANCE_M_S]
    assert wrong == []
    # and the receiver is trusted again once it computes new solutions
    assert sum(v.valid for v in velocities if v.t_ns / 1e9 > 15.3) >= 5


def test_a_receiver_at_rest_repeating_its_position_is_not_flagged_frozen() -> None:
    """An ideal receiver at rest (no position or velocity noise) repeats its fix exactly,
    as a u-blox's static hold does: nothing moved, so nothing is wrong."""
    clock = SimulatedClock()
    bus = EmulatedBus("emul://uart", BusKind.SERIAL)
    emulator = bus.attach(0, GnssEmulator(clock=clock))
    emulator.use_model(GnssErrorModel(horizontal_accuracy_m=0.0, vertical_accuracy_m=0.0,
                                      speed_accuracy_m_s=0.0))
    settings = GnssSettings(rate_hz=5.0, protocol="ubx", messages=("NAV-PVT",))
    driver = GnssDriver(bus.link(0), settings, device="gps", clock=clock)
    driver.probe()
    driver.configure()
    scenario = load_registry().scenarios.get("static")(seed=1)
    samples = []
    t = clock.now_ns()
    while t < 20e9:
        clock.sleep_until(t)
        emulator.set_physics(physical_inputs(scenario.truth(t / 1e9)))
        result = driver.poll(t)
        samples += result.samples
        t = result.next_poll_ns
    fixes = [s for s in samples if isinstance(s, PositionSample) and s.valid]
    assert len(fixes) > 80
    assert len({(s.latitude_deg, s.longitude_deg, s.height_m) for s in fixes}) == 1
    assert driver.stats.frozen_epochs == 0
