"""A poll that comes due while the pipeline's one thread is held (a host stall, another
device's recovery) happens when the thread is free, never at its old due time; through the
fault-injection interface. Found by the soak on every bundled board
(tests/benchmarks/soak.py), before the fix:

- gy91: the MPU-9250's recovery held the thread 0.22-0.44 s; the BMP280 was then polled
  once per missed output slot at each slot's old time, handing out the one output it held
  up to 21 times, stamped 20 ms apart inside the time nothing was read, all valid (3 of them
  more than the error model off the truth in the hour's first 1,320 s);
- seed-gps-vario: the GNSS driver's reconfiguration after a receiver restart held the
  thread 1.25-2.08 s; the emulated board then handed the MS5611 the world of the poll's due
  time (``EmulatedBoard.before_poll``), two seconds old, and its pressure (14-37 Pa off) was
  stamped at the conversion's real end, valid; the vario followed it (-4.5 to -8.5 m/s).

The boards' ``before_poll`` now put a late poll at the clock (a recording keeps it, so a
replay polls then too), and the pipeline puts a poll of a chip with its own output rate off
to the next point of its poll grid (``Pipeline._on_phase``): its reading keeps the phase,
and the frame ledger's count, of the polls before it."""

from __future__ import annotations

from dataclasses import dataclass

import pytest
from tests.support.late_polls import MS5611_NOISE_PA, auto_read_copy_lags, lift_pressure_errors_pa

from imuhal.core.samples import GyroSample, Quantity, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall, LatePolls
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sim.measured import MeasuredInstants

STALL_S = 0.3
STALLS_AT_S = (2.0, 3.0, 4.0)
COPY_LATENCY_NS = 16_000_000
"""An auto-read copy comes at most one AK8963 period (10 ms) plus one MPU-9250 period and its
burst (5.6 ms) after the measurement it carries (tests/integration/test_gps_vario_auto_read)."""
BMP280_MAX_CONVERSION_NS = 22_525_000
"""The gy91 BMP280's longest conversion at x8 pressure, x1 temperature oversampling
(datasheet: 1.25 + 2.3 x 1 + 2.3 x 8 + 0.575 ms)."""
PRESSURE_BOUND_PA = 4 * MS5611_NOISE_PA + 0.4
"""Four times the MS5611's noise at OSR 4096 plus its 9 ms conversion at 4 m/s (0.4 Pa)."""


@dataclass
class Run:
    samples: list[Sample]
    accounted: dict[str, tuple[Quantity, int]]
    """Per device with a frame ledger: its channel and frame period (ns)."""
    measured: dict[str, MeasuredInstants]
    """Per accounted device: its chip's measurement instants (the emulator's record)."""


@pytest.fixture(scope="module")
def stalled_gy91() -> Run:
    """A gy91 whose host stalls 0.3 s before an IMU poll at 2, 3 and 4 s."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    stall = HostStall(device="imu", start_s=STALLS_AT_S[0], end_s=STALLS_AT_S[-1] + 0.5,
                      every_s=1.0, stall_s=STALL_S)
    with open_emulated(profile, registry, seed=1, faults=[stall]) as p:
        samples = [e for e in p.events(5.0) if isinstance(e, Sample)]
        return Run(samples, {n: (d.ledger.channel, d.ledger.period_ns)
                             for n, d in p.devices.items() if d.ledger is not None},
                   {n: p.board.emulators[n].measured_ns for n, d in p.devices.items()
                    if d.ledger is not None})


def test_no_reading_is_stamped_while_the_host_was_stalled(stalled_gy91: Run) -> None:
    """The stall begins at the first IMU poll due at or after each instant (200 Hz: within
    5 ms of it); nothing can be read until it ends. Only a conversion the host started
    before the stall ends in it: the BMP280 in forced mode stamps it at its trigger plus its
    maximum conversion time (22.5 ms), when the chip had finished it, though it is read
    after the stall (one pressure and its temperature at most per stall)."""
    inside = [s for s in stalled_gy91.samples
              if any(at + 0.006 < s.t_ns / 1e9 < at + STALL_S for at in STALLS_AT_S)]
    measured = stalled_gy91.measured["baro"]
    converted = [s for s in inside if s.device == "baro" and 0 <= s.t_ns - measured[
        measured.count_until(s.t_ns) - 1] <= BMP280_MAX_CONVERSION_NS]
    assert [(round(s.t_ns / 1e9, 4), s.device, s.channel.value) for s in inside
            if s not in converted] == []
    assert len(converted) <= 2 * len(STALLS_AT_S)


def test_a_late_poll_keeps_the_phase_of_the_polls_before_it(stalled_gy91: Run) -> None:
    """Every valid frame of each accounted stream, before and after the stalls, is stamped
    on one phase of its chip's period: a poll that fell due in a stall waits for the next
    point of its grid, so its reading has the same lag after its measurement as any other
    (and the frame ledger's count from stamp to stamp is exact). The same lag to within two
    poll guards (a guard is an eighth of a period): the MPU-9250's and AK8963's polls search
    for their chip's instants and sit within a guard after them, and a put-off poll aims a
    guard after its grid point."""
    assert set(stalled_gy91.accounted) == {"imu", "mag", "baro"}
    for device, (channel, period_ns) in stalled_gy91.accounted.items():
        stamps = [s.t_ns for s in stalled_gy91.samples
                  if s.device == device and s.channel is channel and s.valid]
        after = [t for t in stamps if t > STALLS_AT_S[0] * 1e9]
        assert len(after) > 0.5 * (5.0 - STALLS_AT_S[0]) * 1e9 / period_ns, device
        measured = stalled_gy91.measured[device]
        lags = [t - measured[measured.count_until(t) - 1] for t in stamps]
        assert max(lags) - min(lags) <= period_ns // 4, device


def test_an_auto_read_copy_is_never_stamped_before_its_measurement() -> None:
    """seed-gps-vario reads its AK8963 through the MPU-9250's slave 0 (read: auto). Its host
    stalls 43.7 ms before a barometer poll every 0.25 s, so the MPU-9250 falls due inside
    the stall; the MPU copies the AK8963's registers at its own samples, and the copy the
    late burst reads is the one of its latest sample, made after the stall began. Ideal
    chips and a fast turn (0.5 s a revolution, about 4.7 uT between two AK8963 measurements)
    tell which measurement each valid field carries: the one whose truth it equals within
    the quantisation. Each is stamped after that measurement and within the copy latency
    of it (before the fix, stamped at the MPU's old due time: up to 39 ms before it)."""
    got = auto_read_copy_lags(load_registry())
    assert min(got.lags_ns) >= 0 and max(got.lags_ns) <= COPY_LATENCY_NS
    assert len(got.lags_ns) >= 0.5 * got.fields and got.fields >= 150


def test_a_late_conversion_measures_the_world_of_then() -> None:
    """seed-gps-vario climbing 4 m/s in a lift; its host stalls 0.3 s before a magnetometer
    poll every 0.5 s, so the MS5611 falls due inside each stall. It converts when polled
    (``Driver.host_paced``): the conversion starts when the host is free and measures the
    world of then, so every valid pressure lies within the chip's noise (1.2 Pa RMS, this
    run's error model: noise only) and the conversion's 9 ms of climb (0.4 Pa) of the truth
    at its stamp. Before the fix the emulated board handed it the world of its old due time,
    up to 0.3 s (14 Pa) old."""
    off_pa = lift_pressure_errors_pa(load_registry(), stall_s=STALL_S)
    assert max(off_pa) <= PRESSURE_BOUND_PA
    assert len(off_pa) >= 200


def test_a_host_late_at_every_poll_still_reads_the_device() -> None:
    """A poll is put off to its grid PUT_OFF_AT_MOST times in a row at most: a host whose
    every wake-up comes 4 ms late (a coarse timer) against the gy91 IMU's 5 ms period
    would otherwise put it off for ever. The attempt after those reads it, late (about one
    frame in five over the second)."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    late = LatePolls(device="imu", start_s=1.0, end_s=2.0, delay_s=0.004)
    with open_emulated(profile, registry, seed=1, faults=[late]) as p:
        gyro = [e.t_ns for e in p.events(2.5) if isinstance(e, GyroSample) and e.valid]
    assert len([t for t in gyro if 1.1e9 < t < 1.9e9]) >= 0.15 * 0.8 * 200
