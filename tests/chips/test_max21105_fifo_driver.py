"""The MAX21105 driver's FIFO reader (read: fifo; issue 25) on a bare emulated chip: the
same reader as the MAX21100's at the MAX21105's own FIFO registers (FIFO_STORE 0x17,
FIFO_THS 0x18, FIFO_CFG 0x19). Frames read the chip's values at its instants; a host
pause longer than the FIFO, or a shifted FIFO, is a counted overflow and a reset."""

from __future__ import annotations

import numpy as np
from tests.chips.test_max2110x_driver import AT_REST, Rig, make_rig
from tests.chips.test_max2110x_fifo_driver import pause_past_the_fifo, shift_the_fifo

from imuhal.core.samples import AccelSample, GyroSample, Sample
from imuhal.core.streams import TimeSource
from imuhal_chips.max2110x.driver import Max21105Driver
from imuhal_chips.max2110x.emulator import Max21105Emulator

PERIOD_NS = 5_000_000  # the MAX21105's default 200 Hz
DEPTH_NS = 10 * PERIOD_NS  # 64 words hold 10 frames of 6 words [UNVERIFIED depth]


def _fifo_rig() -> Rig:
    return make_rig(Max21105Driver, Max21105Emulator, read="fifo")


def _valid(samples: list[Sample], cls: type[Sample]) -> list[Sample]:
    return [s for s in samples if isinstance(s, cls) and s.valid]


def _at_rest(gyros: list[Sample], rig: Rig) -> bool:
    lsb = rig.emu.resolution(GyroSample.channel)
    return all(np.max(np.abs(np.subtract(g.gyro_rad_s, AT_REST.angular_rate_rad_s))) <= lsb
               for g in gyros if isinstance(g, GyroSample))


def test_configure_sets_the_max21105s_own_fifo_registers() -> None:
    rig = _fifo_rig()
    fifo = rig.emu.fifo
    assert (fifo.store, fifo.cfg, fifo.threshold_words) == (0x03, 0x08, 6)
    assert fifo.storing == (True, True)


def test_fifo_frames_read_the_chips_values_stamped_at_its_instants() -> None:
    rig = _fifo_rig()
    rig.emu.oscillator_error = -0.02
    samples = rig.run(2.0)
    gyros = _valid(samples, GyroSample)
    instants = np.asarray(rig.emu.measured_ns)
    assert len(gyros) == len(_valid(samples, AccelSample)) >= len(instants) - 2
    late = np.asarray([g.t_ns for g in gyros if g.t_ns > 1_000_000_000])  # clock learned
    i = np.minimum(np.searchsorted(instants, late), len(instants) - 1)
    nearest = np.minimum(np.abs(instants[i] - late), np.abs(instants[i - 1] - late))
    assert len(late) > 150 and np.max(nearest) < 50_000
    assert _at_rest(gyros, rig)
    gyro = next(s for s in rig.driver.streams() if s.quantity is GyroSample.channel)
    assert gyro.time_source is TimeSource.CHIP_CLOCK


def test_a_host_pause_longer_than_the_fifo_is_a_counted_overflow_and_a_reset() -> None:
    rig = _fifo_rig()
    samples = pause_past_the_fifo(rig, DEPTH_NS, PERIOD_NS)
    assert rig.driver.health.fifo_overflows == 1
    assert rig.emu.fifo.frames_dropped >= 3
    gyros = _valid(samples, GyroSample)
    assert len(gyros) > 80 and _at_rest(gyros, rig)  # frames come again after the reset


def test_a_shifted_fifo_is_reset_and_no_wrong_frame_comes_out() -> None:
    rig = _fifo_rig()
    samples = shift_the_fifo(rig)
    assert rig.driver.health.fifo_overflows == 1
    gyros = _valid(samples, GyroSample)
    assert len(gyros) > 80 and _at_rest(gyros, rig)
