"""BMP280 emulator: the register file and measurement cycle on a bus, fed by true physics.

Bus face:
- I2C: the first written byte is the register pointer; a longer write is (register, data)
  pairs, as the chip wants (no auto-increment on writes). Reads auto-increment.
- SPI: the control byte's bit 7 is RW (1 = read) and its low 7 bits are the address with bit 7
  implied (every BMP280 register is >= 0x80); writes are (control, data) pairs.
- Identity 0xD0, soft reset (only 0xB6 written to 0xE0 has an effect; 0xE0 reads 0x00),
  read-only trimming, status (``measuring`` while converting, ``im_update`` for 2 ms after
  a reset while the NVM is copied), ctrl_meas and config (config writes in normal mode are
  ignored, as the datasheet warns they may be).
- Timing on ``self.clock``: a measurement takes the datasheet's *typical* time for its
  oversampling; forced mode (mode 01 or 10) measures once and returns to sleep (mode bits
  read 00 afterwards); normal mode cycles measurement + standby t_sb. The IIR filter runs on
  the ADC values of successive measurements, seeded with the first.
- Its own clock: every time above divided by 1 + ``oscillator_error`` (default 0; the
  datasheet gives typical and maximum measurement times, not the oscillator's tolerance, so
  tests and scripts set up to +-2 %, issue 25); each measurement takes the truth of the
  instant it completes (``pull_physics``), whenever the host reads it.

Physics face: ``physics.pressure_pa`` and ``physics.temperature_degc`` (defaults 101325 Pa,
25 degC) are turned into ADC counts by ``emulator_encoding``, the closed-form inverse of the
datasheet's floating-point compensation written independently of the driver, with the part's
trimming (default: the datasheet worked example), at the configured resolution.

Faults: ``chip_id`` (a clone or another part), ``stuck_data_ready`` (conversions never finish:
``measuring`` stays set, forced mode never returns to sleep, data freeze; what finished
before the hang began is measured. When it ends, normal mode's cycles it held complete at
their own instants; a forced conversion it held resumes where it stopped and completes the
time it had left after the hang's end, measuring the world of then: nothing is dated inside
the hang, when every status read said ``measuring``. A trigger written during the hang
starts its conversion over, as a trigger written while the chip measures does here: the
datasheet says nothing of either, so this is the model's choice, stated), ``silent_reset()``,
absence (``absent``) and bus errors via ``EmulatedBus.fail_transfers``.

Source of facts: BMP280 datasheet BST-BMP280-DS001-19; imuhal shared chip facts section 2.
"""

from __future__ import annotations

import random

from imuhal.bus.base import BusKind
from imuhal.core.clock import Clock
from imuhal.core.samples import Quantity
from imuhal.emulation import ChipEmulator, HangsBetweenTransfers
from imuhal_chips.bmp280 import registers as r
from imuhal_chips.bmp280.emulator_encoding import (
    DATASHEET_TRIMMING,
    FactoryTrimming,
    adc_p_for,
    adc_t_for,
    pressure_pa_of,
    t_fine_of,
    temperature_degc_of,
)
from imuhal_chips.bmp280.error_spec import BMP280_ERROR_SPEC

DEFAULT_PRESSURE_PA = 101325.0
DEFAULT_TEMPERATURE_DEGC = 25.0


# Register-field meanings written here from the datasheet (sections 3.3-3.8, 4.3), never taken
# from the driver's setting tables, so a wrong code in the driver shows as a wrong rate or
# resolution.
_OVERSAMPLING_BY_CODE = (0, 1, 2, 4, 8, 16, 16, 16)
"""osrs_t / osrs_p [2:0] -> oversampling factor (000: measurement skipped)."""
_IIR_BY_CODE = (0, 2, 4, 8, 16, 16, 16, 16)
"""config filter [4:2] -> IIR coefficient (000: off)."""
_STANDBY_MS_BY_CODE = (0.5, 62.5, 125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0)
"""config t_sb [7:5] -> normal-mode standby time."""
_ADC_BITS = {1: 16, 2: 17, 4: 18, 8: 19, 16: 20}
"""Oversampling factor -> ADC resolution (table 4 and 5: 16 to 20 bit; the IIR filter gives 20)."""
_ADC_SKIPPED = 0x80000
"""What a skipped or never-run measurement reads (datasheet: 0x80000)."""
_ADC_FULL = (1 << 20) - 1
_STARTUP_S = 0.002
"""Start-up time after power-on or soft reset (NVM copy, im_update set)."""


def _measurement_ms(osrs_t: int, osrs_p: int) -> float:
    """Typical measurement time (datasheet 9.1 / 3.8.1): 1 + 2 osrs_t + (2 osrs_p + 0.5) ms,
    the pressure term dropped when pressure is skipped."""
    return 1.0 + 2.0 * osrs_t + ((2.0 * osrs_p + 0.5) if osrs_p else 0.0)


def _adc_registers(adc: int) -> bytes:
    """msb, lsb, xlsb of a 20-bit ADC value: bits 19..12, 11..4 and 3..0 in xlsb[7:4]."""
    return bytes([(adc >> 12) & 0xFF, (adc >> 4) & 0xFF, (adc & 0x0F) << 4])


class BMP280Emulator(HangsBetweenTransfers, ChipEmulator):
    """Register-level stand-in for a BMP280 on I2C or SPI."""

    chip = "bmp280"
    error_spec = BMP280_ERROR_SPEC
    measures_motion = False  # pressure and temperature only: a light truth is enough
    models_stuck_data_ready = True
    pulls_physics = True
    conformance_sweep = True
    # Normal mode at x1/x1 oversampling and the shortest standby: measurement + 0.5 ms.
    min_output_period_s = (_measurement_ms(1, 1) + _STANDBY_MS_BY_CODE[0]) / 1e3
    _forced_done: int | None
    """When the forced conversion under way completes (None: none is)."""
    _forced_start: int
    """When the latest forced conversion was triggered."""

    def __init__(
        self, clock: Clock | None = None, *, trim: FactoryTrimming = DATASHEET_TRIMMING
    ) -> None:
        super().__init__(clock)
        self.trim = trim
        self._trim_image = bytearray(trim.register_image())
        """What the trimming registers read (fault injection may flip bits of it)."""
        self.chip_id = r.CHIP_ID
        """What 0xD0 reads (fault injection: 0x60 is a BME280, anything else a clone)."""
        self._hung = False
        self._hung_ns = 0
        """When the current hang began (``stuck_data_ready``)."""
        self._pointer = 0
        self.resets = 0
        self._oscillator_error = 0.0
        self._reset()
        self.resets = 0
        """Resets seen (soft reset command or silent reset), for tests."""

    # -- fault injection --------------------------------------------------------------------

    @property
    def stuck_data_ready(self) -> bool:
        """The measurement engine hangs (fault injection): no measurement completes."""
        return self._hung

    @stuck_data_ready.setter
    def stuck_data_ready(self, hung: bool) -> None:
        if hung == getattr(self, "_hung", hung):  # ChipEmulator's __init__ sets it first
            self._hung = hung
            return
        self._advance()  # what finished before the hang began (HangsBetweenTransfers)
        now = self.now_ns()
        if hung:
            self._hung_ns = now
        elif self._forced_done is not None:
            # the engine resumes the forced conversion it held where it stopped: completed
            # at its own instant, it would be dated inside the hang, when every status read
            # said ``measuring`` (a driver stamping it at the read that found it done put
            # that stamp 128 ms after such an instant: gy91, the fault matrix at 1 %)
            held_from = max(self._hung_ns, self._forced_start)
            self._forced_done = now + max(0, self._forced_done - held_from)
        self._hung = hung

    def _measurement_due(self) -> bool:
        """Always (HangsBetweenTransfers): ``_advance`` finds by itself what each mode has
        finished, so a hang first measures what finished before it began; when it ends, the
        cycles it held complete at their own instants."""
        return True

    def corrupt_trim(self, rng: random.Random, bits: int = 1) -> str:
        """Flip ``bits`` random bits of the 24 trimming bytes the driver reads; the sensor
        element keeps encoding with the true ``trim``."""
        changed = []
        for _ in range(bits):
            index, bit = rng.randrange(r.CALIB_LENGTH), rng.randrange(8)
            self._trim_image[index] ^= 1 << bit
            changed.append(f"0x{r.REG_CALIB + index:02X} bit {bit}")
        return "trimming " + ", ".join(changed)

    def silent_reset(self) -> None:
        """The chip resets without being asked (brown-out): back to sleep, defaults."""
        self._reset()

    # -- physics helpers --------------------------------------------------------------------

    def _true_values(self) -> tuple[float, float]:
        p = self.physics.pressure_pa
        t = self.physics.temperature_degc
        return (DEFAULT_PRESSURE_PA if p is None else p,
                DEFAULT_TEMPERATURE_DEGC if t is None else t)

    def _oversampling(self) -> tuple[int, int]:
        """(temperature, pressure) oversampling factors from ctrl_meas (0 = skipped)."""
        return (_OVERSAMPLING_BY_CODE[self._ctrl >> 5 & 0b111],
                _OVERSAMPLING_BY_CODE[(self._ctrl >> 2) & 0b111])

    def _bits(self, oversampling: int) -> int:
        iir = _IIR_BY_CODE[(self._config >> 2) & 0b111]
        return 20 if iir else _ADC_BITS[oversampling]

    def noise_period_s(self, channel: Quantity) -> float | None:
        """Normal mode: measurement plus standby (:meth:`_period_ns`); None in forced and
        sleep mode, where the host sets the pace."""
        if channel in (Quantity.PRESSURE, Quantity.TEMPERATURE) and self._mode() == r.MODE_NORMAL:
            return self._period_ns() / 1e9
        return None

    def resolution(self, channel: Quantity) -> float:
        """One output LSB at the current settings and physics, in Pa or degC.

        Temperature is reported by the driver in 0.01 degC steps, so that is its floor.
        """
        osrs_t, osrs_p = self._oversampling()
        pressure, temperature = self._true_values()
        if channel is Quantity.TEMPERATURE:
            step = 1 << (20 - self._bits(max(osrs_t, 1)))
            adc = adc_t_for(temperature, self.trim)
            t0 = temperature_degc_of(adc, self.trim)
            t1 = temperature_degc_of(adc + step, self.trim)
            return max(abs(t1 - t0), 0.01)
        if channel is Quantity.PRESSURE:
            step = 1 << (20 - self._bits(max(osrs_p, 1)))
            t_fine = t_fine_of(adc_t_for(temperature, self.trim), self.trim)
            adc = adc_p_for(pressure, t_fine, self.trim)
            p0 = pressure_pa_of(adc, t_fine, self.trim)
            p1 = pressure_pa_of(adc + step, t_fine, self.trim)
            return abs(p1 - p0)
        raise ValueError(f"the BMP280 has no {channel.value} channel")

    def full_scale(self, channel: Quantity) -> float:
        """Upper end of the datasheet operating range: 110000 Pa, 85 degC."""
        if channel is Quantity.PRESSURE:
            return 110_000.0
        if channel is Quantity.TEMPERATURE:
            return 85.0
        raise ValueError(f"the BMP280 has no {channel.value} channel")

    # -- state ------------------------------------------------------------------------------

    def _reset(self) -> None:
        self.resets += 1
        self._ctrl = 0x00
        self._config = 0x00
        self._data = bytearray(_adc_registers(_ADC_SKIPPED) * 2)
        self._im_update_until = self.now_ns() + round(_STARTUP_S * 1e9)
        self._cycle_start = 0
        self._cycles_done = 0
        self._forced_done = None
        self._forced_start = 0
        self._filter: tuple[float, float] | None = None

    def _mode(self) -> int:
        return self._ctrl & r.MODE_MASK

    @property
    def oscillator_error(self) -> float:
        """The internal oscillator's frequency error as a fraction (0.02: 2 % fast, every
        measurement and standby time 1/1.02 of the datasheet's); measurements already made
        stay where they were."""
        return self._oscillator_error

    @oscillator_error.setter
    def oscillator_error(self, fraction: float) -> None:
        self.checked_oscillator_error(fraction)
        self._advance()
        if self._mode() == r.MODE_NORMAL:
            # count the cycles on from the last one completed, at the new rate
            self._cycle_start += self._cycles_done * self._period_ns()
            self._cycles_done = 0
        self._oscillator_error = fraction

    def _on_clock(self, ms: float) -> int:
        """A datasheet time (ms) on the chip's own oscillator, in ns."""
        return round(ms * 1e6 / (1.0 + self._oscillator_error))

    def _meas_ns(self) -> int:
        osrs_t, osrs_p = self._oversampling()
        return self._on_clock(_measurement_ms(osrs_t, osrs_p))

    def _period_ns(self) -> int:
        standby = _STANDBY_MS_BY_CODE[self._config >> 5 & 0b111]
        return self._meas_ns() + self._on_clock(standby)

    def _advance(self) -> None:
        """Complete the measurements that have finished by now."""
        if self.stuck_data_ready:
            return
        now = self.now_ns()
        mode = self._mode()
        if mode == r.MODE_NORMAL:
            elapsed = now - self._cycle_start - self._meas_ns()
            if elapsed >= 0:
                period = self._period_ns()
                done = elapsed // period + 1
                first_ns = self._cycle_start + self._meas_ns()  # cycle 1 completes
                # the last 64 cycles at most: the IIR filter forgets anything older
                for cycle in range(max(self._cycles_done + 1, done - 63), done + 1):
                    self.pull_physics(first_ns + (cycle - 1) * period)
                    self._measure()
                self.record_measurements(first_ns + self._cycles_done * period, period,
                                         done - self._cycles_done)
                self._cycles_done = done
        elif self._forced_done is not None and now >= self._forced_done:
            self.record_measurements(self._forced_done, 0, 1)
            self.pull_physics(self._forced_done)
            self._measure()
            self._forced_done = None
            self._ctrl &= ~r.MODE_MASK  # back to sleep

    def _measuring(self) -> bool:
        now = self.now_ns()
        mode = self._mode()
        if mode == r.MODE_NORMAL:
            if self.stuck_data_ready:
                return True
            return (now - self._cycle_start) % self._period_ns() < self._meas_ns()
        return mode != r.MODE_SLEEP and self._forced_done is not None

    def _measure(self) -> None:
        pressure, temperature = self._true_values()
        osrs_t, osrs_p = self._oversampling()
        # The ADC delivers 20-bit words: a world beyond the chip's range saturates the ADC
        # before the filter sees it (the filter runs on ADC output, datasheet 3.4.3).
        adc_t = min(max(adc_t_for(temperature, self.trim), 0), _ADC_FULL)
        adc_p = min(max(adc_p_for(pressure, t_fine_of(adc_t, self.trim), self.trim), 0),
                    _ADC_FULL)
        iir = _IIR_BY_CODE[(self._config >> 2) & 0b111]
        if self._filter is None or not iir:
            self._filter = (float(adc_p), float(adc_t))
        else:
            fp, ft = self._filter
            self._filter = ((fp * (iir - 1) + adc_p) / iir, (ft * (iir - 1) + adc_t) / iir)
        fp, ft = self._filter
        out_p = self._quantise(fp, osrs_p) if osrs_p else _ADC_SKIPPED
        out_t = self._quantise(ft, osrs_t) if osrs_t else _ADC_SKIPPED
        self._data[:] = _adc_registers(out_p) + _adc_registers(out_t)

    def _quantise(self, adc: float, oversampling: int) -> int:
        step = 1 << (20 - self._bits(oversampling))
        return min(max(round(adc / step) * step, 0), _ADC_FULL)

    # -- bus face ---------------------------------------------------------------------------

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        self._advance()
        pointer: int | None = None
        if kind is BusKind.SPI:
            if write and write[0] & 0x80:
                pointer = write[0]
            else:
                for i in range(0, len(write) - 1, 2):
                    self._write(write[i] | 0x80, write[i + 1])
        else:
            if write:
                self._pointer = write[0]
            for i in range(0, len(write) - 1, 2):
                self._write(write[i], write[i + 1])
            pointer = self._pointer
        if not read_len or pointer is None:
            return bytes(read_len)
        if kind is BusKind.I2C:
            # Auto-increment: a following read without a register byte continues here.
            self._pointer = (pointer + read_len) & 0xFF
        return bytes(self._read((pointer + i) & 0xFF) for i in range(read_len))

    def _read(self, address: int) -> int:
        if r.REG_CALIB <= address < r.REG_CALIB + r.CALIB_LENGTH:
            return self._trim_image[address - r.REG_CALIB]
        if address == r.REG_CHIP_ID:
            return self.chip_id
        if address == r.REG_STATUS:
            im_update = self.now_ns() < self._im_update_until
            return (r.STATUS_MEASURING if self._measuring() else 0) | (
                r.STATUS_IM_UPDATE if im_update else 0)
        if address == r.REG_CTRL_MEAS:
            return self._ctrl
        if address == r.REG_CONFIG:
            return self._config
        if r.REG_PRESS_MSB <= address < r.REG_PRESS_MSB + 6:
            return self._data[address - r.REG_PRESS_MSB]
        return 0x00

    def _write(self, address: int, value: int) -> None:
        if address == r.REG_RESET:
            if value == r.RESET_COMMAND:
                self._reset()
        elif address == r.REG_CTRL_MEAS:
            self._ctrl = value
            mode = value & r.MODE_MASK
            now = self.now_ns()
            if mode == r.MODE_NORMAL:
                self._cycle_start, self._cycles_done = now, 0
                self._forced_done = None
            elif mode == r.MODE_SLEEP:
                self._forced_done = None
            else:
                self._forced_start = now
                self._forced_done = now + self._meas_ns()
        elif address == r.REG_CONFIG and self._mode() != r.MODE_NORMAL:
            self._config = value & 0xFD  # bit 1 is reserved
            self._filter = None
        # every other register is read-only: writes are ignored, as on the chip
