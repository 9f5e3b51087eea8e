"""The GNSS receiver's reconfiguration never holds the board (issue 26): after a restart at
9600 baud the driver needs 1.3 to 2.1 s to hear the receiver and have each CFG message
acknowledged, and it used to spend them waiting on the clock every device shares, so the
IMU went unread that long (1.2 s on this run). Now each step is one poll of the receiver
(imuhal_chips.gnss.bringup) and the other devices are polled between them."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pyubx2", reason="the gps extra (pynmea2, pyubx2) is not installed")

from imuhal.core.samples import GyroSample, PositionSample, Quantity
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusOSError, ChipReset, FaultSpec
from imuhal.pipeline.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

UBX_HORIZONTAL_ACCURACY_M = 2.5
"""What the emulated receiver reports as hAcc in NAV-PVT (NMEA carries no accuracy): a fix
with it came from the reconfigured receiver."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _fly(registry: Registry, seconds: float, *faults: FaultSpec
         ) -> tuple[list[object], Pipeline]:
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1, faults=faults, calibrated=False) as p:
        return list(p.events(seconds)), p


def test_the_imu_keeps_its_cadence_while_the_receiver_is_reconfigured_after_a_restart(
        registry: Registry) -> None:
    events, pipeline = _fly(registry, 15.0, ChipReset(device="gps", start_s=5.0))
    gps = pipeline.devices["gps"].driver
    assert (gps.health.resets_detected, gps.health.reconfigurations) == (1, 1)
    ubx_fixes = [e.t_ns for e in events if isinstance(e, PositionSample) and e.valid
                 and e.horizontal_accuracy_m == UBX_HORIZONTAL_ACCURACY_M]
    back_ns = min(t for t in ubx_fixes if t > 5.5e9)  # the first UBX fix after the restart
    assert back_ns > 6.5e9  # the receiver did go through its NMEA seconds and the CFG
    period_ns = 1e9 / next(s.rate_hz for s in pipeline.streams["imu"]
                           if s.quantity is Quantity.GYRO)
    gyro_ns = np.array([e.t_ns for e in events if isinstance(e, GyroSample)])
    assert np.diff(gyro_ns).max() <= 1.5 * period_ns
    during = gyro_ns[(gyro_ns >= 5e9) & (gyro_ns < back_ns)]
    assert len(during) >= (back_ns - 5e9) / period_ns - 1


def test_port_errors_between_good_reads_cost_no_reconfiguration(registry: Registry) -> None:
    """A read or write the port reports failed changes nothing in the receiver: the driver
    carries on (``resume``), the error is counted, and fixes go on; only a failure again
    before a poll completes re-probes and reconfigures."""
    events, pipeline = _fly(registry, 12.0, BusOSError(device="gps", start_s=4.0, end_s=10.0,
                                                       rate=0.05))
    assert pipeline.summary().bus_errors["gps"] >= 3
    assert pipeline.devices["gps"].driver.health.reconfigurations == 0
    fixes = [e.t_ns for e in events if isinstance(e, PositionSample) and e.valid]
    assert max(np.diff([t for t in fixes if 4e9 <= t < 10e9])) < 1.5e9
