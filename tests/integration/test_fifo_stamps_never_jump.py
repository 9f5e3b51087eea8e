"""FIFO time stamps under host stalls longer than the FIFO (overflow resets), a chip reset
and the chip's oscillator drifting through the flight (issue 25: a time-stamp jump or reversal never
reaches an estimator): every sample an estimator can take is stamped after the one before,
consecutive frames a period apart within the stated bound, and each within 200 us of the
chip's own measurement instant."""

from __future__ import annotations

from bisect import bisect_right

import numpy as np

from imuhal.core.samples import GyroSample, MagSample, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import ChipReset, HostStall
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

PERIOD_NS = 5_000_000


def _flight() -> tuple[list[Sample], list[int], int]:
    """seed-gps-vario, MPU-9250 FIFO with the AK8963 in it, 10 s of ``thermal``: stalls of
    150 ms (longer than the FIFO's 115 ms) twice a second on average, the MPU-9250 reset at
    6 s, its oscillator 1 % fast at first and drifting by -0.05 % a second (a die heating
    up far faster than in any flight). Returns the valid samples, the chip's instants and
    its FIFO overflows."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    imu = profile.devices["imu"]
    profile = profile.model_copy(update={"devices": {**profile.devices, "imu": imu.model_copy(
        update={"settings": {**imu.settings, "read": "fifo"}})}})
    faults = [HostStall(device="imu", start_s=1.0, rate_hz=2.0, stall_s=0.15),
              ChipReset(device="imu", start_s=6.0)]
    valid: list[Sample] = []
    with open_emulated(profile, registry, scenario="thermal", seed=5, faults=faults,
                       calibrated=False) as p:
        chip = p.board.emulators["imu"]
        chip.oscillator_error = 0.01
        for event in p.events(10.0):
            drifted = 0.01 - 0.0005 * round(p.clock.now_ns() / 1e8) / 10
            if drifted != chip.oscillator_error:
                chip.oscillator_error = drifted
            if isinstance(event, GyroSample | MagSample) and event.valid:
                valid.append(event)
        return valid, list(chip.measured_ns), p.devices["imu"].driver.health.fifo_overflows


def test_no_reversal_or_jump_and_every_stamp_at_its_chip_instant() -> None:
    valid, instants, overflows = _flight()
    assert overflows >= 5
    for kind in (GyroSample, MagSample):
        stamps = np.asarray([s.t_ns for s in valid if isinstance(s, kind)])
        steps = np.diff(stamps)
        assert np.all(steps > 0), kind
        consecutive = steps[steps < 1.5 * PERIOD_NS * (2 if kind is MagSample else 1)]
        period = PERIOD_NS * (2 if kind is MagSample else 1)
        if kind is GyroSample:
            # one chip period (within the +-5 % tolerance) corrected by at most 5 %
            assert np.all(np.abs(consecutive - period) <= 0.11 * period)
    gyros = [s.t_ns for s in valid if isinstance(s, GyroSample)]
    assert len(gyros) > 1000
    errors = []
    for t in gyros:
        i = bisect_right(instants, t)
        errors.append(min(abs(t - x) for x in instants[max(i - 1, 0):i + 1]))
    assert max(errors) < 200_000
