"""The GNSS receiver's vertical values held against the board's barometer
(imuhal.pipeline.crosscheck, issue 26): synthetic streams with a known truth, so each rule
is seen alone. A 50 Hz barometer with 10 cm of altitude noise; a 5 Hz receiver whose height
error is a 30 s Gauss-Markov process of its stated vAcc (4 m) and whose velD has sAcc's
noise, as the emulated u-blox's."""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Iterator

from imuhal.core.atmosphere import pressure_pa_at_altitude
from imuhal.core.samples import PositionSample, PressureSample, Sample, SampleFlag, VelocitySample
from imuhal.pipeline.crosscheck import VerticalCrossCheck

NS = 1_000_000_000
V_ACC_M, S_ACC_M_S, BARO_NOISE_M = 4.0, 0.15, 0.1


def _climb(t_s: float) -> float:
    """The vehicle's climb (m/s, up): a thermal's 2 m/s with a 1 m/s swell every 20 s."""
    return 2.0 + math.sin(2 * math.pi * t_s / 20.0)


def _height(t_s: float) -> float:
    return 900.0 + 2.0 * t_s - 20.0 / (2 * math.pi) * (math.cos(2 * math.pi * t_s / 20.0) - 1)


def _stream(seconds: float, *, gnss_hz: float = 5.0, seed: int = 1,
            height_error: Callable[[float], float] = lambda t: 0.0,
            vel_d_error: Callable[[float], float] = lambda t: 0.0,
            accuracies: bool = True) -> Iterator[Sample]:
    """The two devices' samples in the order a pipeline sees them: each GNSS epoch
    arrives 0.15 s after its time stamp, after the barometer's samples up to then."""
    rng = random.Random(seed)
    gm = 0.0
    tau_s, dt_g = 30.0, 1.0 / gnss_hz
    epochs = [k / gnss_hz for k in range(1, int(seconds * gnss_hz))]
    baro = [k / 50.0 for k in range(int(seconds * 50))]
    i = 0
    for t in epochs:
        while i < len(baro) and baro[i] <= t + 0.15:
            tb = baro[i]
            pressure = pressure_pa_at_altitude(_height(tb) + rng.gauss(0.0, BARO_NOISE_M))
            yield PressureSample(t_ns=round(tb * NS), device="baro", pressure_pa=pressure)
            i += 1
        a = math.exp(-dt_g / tau_s)
        gm = a * gm + math.sqrt(1 - a * a) * V_ACC_M * rng.gauss(0.0, 1.0)
        t_ns = round(t * NS)
        vel_d = -_climb(t) + rng.gauss(0.0, S_ACC_M_S) + vel_d_error(t)
        yield VelocitySample(t_ns=t_ns, device="gps", velocity_ned_m_s=(1.0, 9.0, vel_d),
                             accuracy_m_s=S_ACC_M_S if accuracies else None)
        yield PositionSample(t_ns=t_ns, device="gps", latitude_deg=46.6, longitude_deg=8.0,
                             height_m=_height(t) + 40.0 + gm + height_error(t),
                             vertical_accuracy_m=V_ACC_M if accuracies else None)


def _checked(samples: Iterator[Sample]) -> tuple[VerticalCrossCheck, list[Sample]]:
    check = VerticalCrossCheck("baro")
    out = [check.observe(s) for s in samples]
    return check, [s for s in out if s.device == "gps"]


def _contradicted(samples: list[Sample], kind: type[Sample]) -> list[float]:
    return [s.t_ns / NS for s in samples
            if isinstance(s, kind) and s.flags & SampleFlag.CONTRADICTED]


def test_an_honest_receiver_and_barometer_never_contradict_each_other() -> None:
    check, gps = _checked(_stream(120.0))
    assert all(s.valid for s in gps)
    assert check.stats.checked["height"] > 550 and check.stats.checked["climb"] > 550
    assert max(check.stats.worst_ratio.values()) < 0.5


def test_a_vertical_velocity_spike_under_the_step_limit_is_contradicted() -> None:
    """16.4 m/s of velD in one epoch (the velD flip the UBX checksum misses, under the
    driver's 10 g step limit of 24 m/s at 5 Hz): the barometer climbs at 2-3 m/s."""
    _, gps = _checked(_stream(10.0, vel_d_error=lambda t: 16.384 if t == 6.0 else 0.0))
    assert _contradicted(gps, VelocitySample) == [6.0]
    assert _contradicted(gps, PositionSample) == []


def test_a_vertical_velocity_whose_stated_accuracy_was_hit_with_it_is_still_contradicted(
        ) -> None:
    """The flip that moved velD by 16.4 m/s moved sAcc by as much (bit 6 of both second
    bytes, 12 bytes apart: the UBX checksum misses it): the epoch's own sAcc would widen
    its bound to 83 m/s, so it counts no worse than the last velocity's that passed."""
    def hit(s: Sample) -> Sample:
        if isinstance(s, VelocitySample) and s.t_ns == 6 * NS:
            return VelocitySample(t_ns=s.t_ns, device=s.device,
                                  velocity_ned_m_s=s.velocity_ned_m_s,
                                  accuracy_m_s=16.384 + S_ACC_M_S)
        return s
    stream = (hit(s) for s in _stream(10.0, vel_d_error=lambda t: 16.384 if t == 6.0 else 0.0))
    _, gps = _checked(stream)
    assert _contradicted(gps, VelocitySample) == [6.0]


def test_a_small_vertical_velocity_error_is_contradicted_within_the_fault_matrix_margin(
        ) -> None:
    """The fault matrix counts a valid GNSS velocity more than 2 m/s off as wrong: a 3 m/s
    velD error is caught."""
    _, gps = _checked(_stream(10.0, vel_d_error=lambda t: 3.0 if t == 6.0 else 0.0))
    assert _contradicted(gps, VelocitySample) == [6.0]


def test_a_height_excursion_at_1_hz_is_contradicted() -> None:
    """32.8 m in one epoch at 1 Hz (both heights' second byte, bit 7): a 10 g vehicle can
    leave its ramp by 25 m in a second, so the receiver's own data let it through; the
    barometer says the vehicle climbed 2 m."""
    _, gps = _checked(_stream(20.0, gnss_hz=1.0,
                              height_error=lambda t: 32.768 if t == 9.0 else 0.0))
    assert _contradicted(gps, PositionSample) == [9.0]


def test_an_nmea_height_without_accuracies_is_contradicted() -> None:
    """NMEA states no vAcc and no sAcc: the check takes a poor receiver's (10 m, 2 m/s)
    and still catches a 39.6 m height at 1 Hz."""
    _, gps = _checked(_stream(20.0, gnss_hz=1.0, accuracies=False,
                              height_error=lambda t: 39.6 if t == 9.0 else 0.0))
    assert _contradicted(gps, PositionSample) == [9.0]
    assert all(s.valid for s in gps if s.t_ns != 9 * NS)


def test_a_receiver_whose_height_really_moved_loses_two_epochs() -> None:
    """The receiver's height steps 30 m against the barometer and stays (its satellite set
    changed): the first two epochs after the step are contradicted; the third agrees with
    them and is the new reference, and every epoch from it on is valid."""
    check, gps = _checked(_stream(20.0, height_error=lambda t: 30.0 if t >= 9.0 else 0.0))
    assert _contradicted(gps, PositionSample) == [9.0, 9.2]
    assert check.stats.new_references == 1


def test_without_barometer_altitudes_around_the_epoch_nothing_is_flagged() -> None:
    """A barometer that went quiet (its samples flagged, lost) is no evidence: the GNSS
    values stand on the driver's own rules."""
    check = VerticalCrossCheck("baro")
    for s in _stream(10.0, vel_d_error=lambda t: 16.4):
        if s.device == "baro" and s.t_ns > 3 * NS:
            s = s.flagged(SampleFlag.FROZEN)
        out = check.observe(s)
        if s.t_ns > 4 * NS:
            assert out.flags == s.flags
    assert check.stats.no_evidence > 20
