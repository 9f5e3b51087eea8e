"""MS5611-01BA03 driver: PROM check on probe, then a non-blocking conversion state machine.

One cycle: [convert D2 (temperature) -> wait -> ADC read] -> convert D1 (pressure) -> wait ->
ADC read -> compensate -> emit. The D2 part runs every ``temperature_every`` cycles. Waits are
the datasheet *maximum* conversion time, so a read never catches a running conversion.
Cycles are placed so that pressure conversions complete on a grid of ``1/odr_hz``; a late
poll slides the cycle rather than reading early.

Validity: an ADC read of 0 (conversion aborted by a reset or a glitch) or all ones (nothing
drives the bus) is no measurement (STALE / BLANK), and the same D1 word FROZEN_AFTER_FRAMES
times in a row is a hung converter (FROZEN, and so is the slot that ends the run: its
temperature may be the hung converter's); such slots carry NaN. A chip that keeps
producing no measurement is reset (the shared reset watch, imuhal.drivers.polling). A
pressure further from the last valid one than ``max_vertical_speed_m_s`` and the noise
allow is IMPLAUSIBLE (value as read): a D1 conversion disturbed while its D2, measured
before it, was not gives an in-range pressure no range check can see.

Transactions: every command is one byte; ADC read (3 bytes) and PROM read (2 bytes) are the
command and the read in one ``Link.transfer`` (I2C: write + repeated-start read; SPI: one
chip-select assertion). The MS5611 has no configuration registers: OSR travels in each
convert command.

Source of facts: MS5611-01BA03 datasheet (DA5611-01BA03_011); AN520; Linux IIO
``ms5611_core.c``; chips.md section 1.
"""

from __future__ import annotations

import math
from enum import Enum
from typing import ClassVar

from pydantic import Field, model_validator

from imuhal.bus.base import BusKind, Link
from imuhal.core.clock import Clock
from imuhal.core.errors import DeviceNotFoundError, NackError
from imuhal.core.samples import (
    Frame,
    PressureSample,
    Quantity,
    Sample,
    SampleFlag,
    TemperatureSample,
)
from imuhal.core.streams import StreamSpec
from imuhal.drivers.base import DeviceIdentity, Driver, DriverSettings, PollResult
from imuhal.drivers.polling import ResetWatch
from imuhal.drivers.validity import FrozenWatch, StepWatch, blank_flag
from imuhal_chips.ms5611.commands import (
    ADC_READ,
    ADC_READ_LEN,
    OSR_TIMING,
    PRESSURE_RMS_PA,
    PROM_READ_LEN,
    PROM_WORDS,
    RESET,
    RESET_RELOAD_MS,
    Measurement,
    Osr,
    convert_command,
    prom_read_command,
)
from imuhal_chips.ms5611.conversion import (
    Coefficients,
    Compensated,
    compensate,
    crc4,
    prom_is_valid,
    stored_crc4,
)

EXPECTED_IDENTITY = "MS5611 PROM with valid CRC4"

STEEPEST_GRADIENT_PA_M = 120_000.0 * 9.80665 / (287.05 * 233.15)
"""The steepest vertical pressure gradient the chip can be in, Pa per metre: rho g at the top
of its pressure range (120 kPa) in the coldest air it works in (-40 degC), 17.6 Pa/m."""
STEP_NOISE_SIGMAS = 10.0
"""Two readings of an unchanged pressure differ by their noise, sqrt(2) RMS: this many of
those, plus the 1 Pa output step, is the allowance beyond what the motion explains."""


def max_rate_hz(pressure_oversampling: int, temperature_oversampling: int) -> float:
    """Highest pressure sample rate at which every sample slot can hold a temperature and a
    pressure conversion, each given its datasheet maximum time."""
    cycle_ms = (OSR_TIMING[pressure_oversampling].max_ms
                + OSR_TIMING[temperature_oversampling].max_ms)
    return 1000.0 / cycle_ms


class MS5611Settings(DriverSettings):
    """MS5611 settings, physical values only.

    ``pressure_oversampling`` / ``temperature_oversampling``: oversampling ratio (OSR) of
    each conversion (higher: less noise, longer conversion). ``odr_hz``: pressure samples
    per second. A temperature
    conversion is made every ``temperature_every`` pressure samples (fewer conversions, less
    self-heating); the sample grid still reserves room for one in every slot so samples stay
    evenly spaced.
    """

    renamed: ClassVar[dict[str, str]] = {
        "pressure_osr": "pressure_oversampling", "temperature_osr": "temperature_oversampling",
        "rate_hz": "odr_hz"}

    pressure_oversampling: Osr = 4096
    temperature_oversampling: Osr = 4096
    odr_hz: float = Field(default=50.0, gt=0)
    temperature_every: int = Field(default=1, ge=1)
    max_vertical_speed_m_s: float = Field(default=1000.0, gt=0)
    """The fastest the board can climb or sink: a pressure moving faster than this at the
    steepest gradient (plus the noise) is IMPLAUSIBLE. The default (about Mach 3) holds for
    any vehicle, rockets included; a paraglider's profile may lower it."""

    @model_validator(mode="after")
    def _rate_fits_conversions(self) -> MS5611Settings:
        limit = max_rate_hz(self.pressure_oversampling, self.temperature_oversampling)
        if self.odr_hz > limit:
            raise ValueError(
                f"odr_hz {self.odr_hz:g} is too high for pressure_oversampling "
                f"{self.pressure_oversampling} and temperature_oversampling "
                f"{self.temperature_oversampling}: the maximum is {limit:.2f} Hz (the two "
                f"conversions take {1000.0 / limit:.2f} ms at their datasheet maximum); "
                "lower odr_hz or choose smaller oversampling ratios"
            )
        return self


class _State(Enum):
    IDLE = "idle"
    """Waiting to start the next cycle (D2 or D1)."""
    CONVERTING_D2 = "converting_d2"
    CONVERTING_D1 = "converting_d1"


class MS5611Driver(Driver):
    """Barometer MS5611-01BA03 on I2C (0x77 with CSB low, 0x76 with CSB high) or SPI."""

    name: ClassVar[str] = "ms5611"
    description: ClassVar[str] = "MEAS/TE MS5611-01BA03 barometric pressure sensor (Pa, degC)"
    Settings: ClassVar[type[DriverSettings]] = MS5611Settings
    channels: ClassVar[tuple[Quantity, ...]] = (Quantity.PRESSURE, Quantity.TEMPERATURE)
    bus_kinds: ClassVar[frozenset[BusKind]] = frozenset({BusKind.I2C, BusKind.SPI})

    FROZEN_AFTER_FRAMES = 5
    """Identical D1 (pressure ADC) words in a row that mean the converter hung. One D1
    count is about 0.019 Pa (SENS / 2^36 with typical coefficients) and the noise is 1.2 Pa
    RMS at OSR 4096, the quietest setting: about 63 counts, so two equal words in a row
    come with probability about 1 / (2 sqrt(pi) 63) = 0.0045 and five about 4e-10 (once
    in about 1,500 years at 50 Hz). A short window matters: the samples a hung converter
    gives before the window fills are emitted valid, and 4 of them (80 ms at 50 Hz) stay
    within the noise of the truth even in a 5 m/s climb."""

    settings: MS5611Settings

    def __init__(
        self, link: Link, settings: DriverSettings, *, device: str, clock: Clock
    ) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self.coefficients: Coefficients | None = None
        self.prom_words: list[int] | None = None
        self.last: Compensated | None = None
        """The last good compensated reading."""
        s = self.settings
        self._t_d1_ns = OSR_TIMING[s.pressure_oversampling].max_ns
        self._t_d2_ns = OSR_TIMING[s.temperature_oversampling].max_ns
        self._period_ns = round(1e9 / s.odr_hz)
        self._watch = ResetWatch(check_s=None)  # no configuration to read back
        self._frozen = FrozenWatch(self.FROZEN_AFTER_FRAMES)
        self._frozen_run = False
        """The last D1 word was FROZEN: the next changed one ends the run."""
        self._steps = StepWatch(
            max_rate_per_s=s.max_vertical_speed_m_s * STEEPEST_GRADIENT_PA_M,
            noise=STEP_NOISE_SIGMAS * math.sqrt(2.0) * PRESSURE_RMS_PA[s.pressure_oversampling]
            + 1.0)
        self._just_reset = False
        self._in_flight: Measurement | str | None = None
        """The poll's transfer under way (a convert command or an ADC read): what
        ``resume`` retries when it failed."""
        self._reset_state()

    # -- probe / configure ------------------------------------------------------------------

    def _not_found(self, found: str, hint: str) -> DeviceNotFoundError:
        return DeviceNotFoundError(
            driver=self.name,
            bus=self.link.bus.name,
            address=self.link.target,
            expected=EXPECTED_IDENTITY,
            found=found,
            hint=hint,
        )

    def _wiring_hint(self) -> str:
        if self.link.kind is BusKind.SPI:
            return ("nothing answering: check the PS pin is low (SPI), the chip select line "
                    "and MISO/SDO wiring")
        return ("nothing answering: check CSB/PS wiring and the address "
                "(0x77 when CSB is low, 0x76 when high)")

    def _command(self, command: int) -> None:
        self.link.transfer(bytes([command]), 0)

    def _read_prom(self) -> list[int]:
        words = []
        for n in range(PROM_WORDS):
            raw = self.link.transfer(bytes([prom_read_command(n)]), PROM_READ_LEN)
            words.append(int.from_bytes(raw, "big"))
        return words

    def probe(self) -> DeviceIdentity:
        """Reset the chip (which reloads its PROM), read the 8 PROM words and check CRC4."""
        try:
            self._command(RESET)
            self.clock.sleep(RESET_RELOAD_MS / 1000.0)
            words = self._read_prom()
        except NackError as err:
            raise self._not_found("no acknowledge (NACK)", self._wiring_hint()) from err
        self._reset_state()
        self._just_reset = True
        if all(w == 0xFFFF for w in words):
            raise self._not_found("all-0xFFFF PROM", self._wiring_hint())
        if all(w == 0x0000 for w in words):
            raise self._not_found(
                "all-0x0000 PROM",
                "data line stuck low or the PROM did not reload: check SDA/MISO and power",
            )
        computed, stored = crc4(words), stored_crc4(words)
        if not prom_is_valid(words):
            raise self._not_found(
                f"CRC4 0x{computed:X} but stored 0x{stored:X}",
                "PROM read with bit errors or another chip: check wiring, lower the bus clock "
                "(SPI <= 16 MHz), or it is not an MS5611",
            )
        self.prom_words = words
        self.coefficients = Coefficients.from_prom(words)
        self.identity = DeviceIdentity(
            driver=self.name,
            bus=self.link.bus.name,
            address=self.link.target,
            identity=f"PROM CRC4=0x{stored:X}",
            note=f"PROM word0=0x{words[0]:04X} word7=0x{words[7]:04X}",
        )
        return self.identity

    def configure(self) -> None:
        """Nothing to program (OSR is part of each convert command); probe if not done and
        start from a clean state machine. probe()'s reset already aborted any conversion;
        a configure() without a probe just before (a restart) resets the chip itself."""
        if self.coefficients is None:
            self.probe()
        elif not self._just_reset:
            self._command(RESET)
            self.clock.sleep(RESET_RELOAD_MS / 1000.0)
        self._just_reset = False
        self._reset_state()

    def streams(self) -> tuple[StreamSpec, ...]:
        """Pressure (Pa) and temperature (degC). The MS5611 keeps no configuration: its
        oversampling travels in each convert command and its rate is this driver's
        conversion grid (one pressure conversion per ``1 / odr_hz``, a temperature one every
        ``temperature_every``), so the rates are the grid the driver runs, not a register.
        Resolution: the compensated output's 0.01 mbar (1 Pa) and 0.01 degC; no full scale
        declared (compensation bounds the output). Latency: the pressure conversion time."""
        if self.coefficients is None:
            return ()
        rate_hz = 1e9 / self._period_ns
        latency_s = self._t_d1_ns * 1e-9
        return (
            StreamSpec(self.device, Quantity.PRESSURE, Frame.SENSOR, rate_hz, scale=1.0,
                       latency_s=latency_s),
            StreamSpec(self.device, Quantity.TEMPERATURE, Frame.SENSOR,
                       rate_hz / self.settings.temperature_every, scale=0.01,
                       latency_s=latency_s),
        )

    @property
    def host_paced(self) -> bool:
        """The MS5611 converts when commanded: a late poll starts its conversion when the
        host is free (the cadence slides, ``_slide_to``), measuring the world of then."""
        return True

    def accounted_stream(self) -> tuple[Quantity, int] | None:
        """One pressure conversion per cycle of the configured rate (the host starts each
        one: the cadence is the driver's, kept by its conversion schedule)."""
        return Quantity.PRESSURE, self._period_ns

    def resume(self, now_ns: int) -> int | None:
        """One transfer of a poll failed; carry on without a reset (which would lose the
        conversion in flight and cost a 2.8 ms PROM reload and a whole cycle):

        - an ADC read: read again at once. If the failed read reached the chip, the result
          is gone and the retry reads 0, a STALE slot, never a wrong value;
        - a convert command: it may have started the conversion, and a second convert
          while one runs gives a wrong result, so wait that conversion's maximum time and
          start it again (a result left unread is simply overwritten).

        Anything else that failed (a reset while restarting a stuck chip): full recovery.
        """
        in_flight, self._in_flight = self._in_flight, None
        if self.coefficients is None or in_flight is None:
            return None
        if in_flight == "adc_read":
            return now_ns
        wait_ns = self._t_d1_ns if in_flight is Measurement.D1 else self._t_d2_ns
        self._state = _State.IDLE  # the conversion starts again at the next poll
        return max(now_ns, self.clock.now_ns()) + wait_ns

    # -- conversion state machine -----------------------------------------------------------

    def _reset_state(self) -> None:
        self._state = _State.IDLE
        self._in_flight = None
        self._need_temperature = True
        self._since_temperature = 0
        self._fresh_temperature = False
        self._d2: int | None = None
        self._conv_start_ns = 0
        self._target_ns = 0
        """When the pressure conversion of the current cycle is due to complete."""

    def _cycle_ns(self, with_temperature: bool) -> int:
        return self._t_d1_ns + (self._t_d2_ns if with_temperature else 0)

    def _cycle_start_ns(self) -> int:
        return self._target_ns - self._cycle_ns(self._need_temperature)

    def start(self, now_ns: int) -> int:
        self._reset_state()
        self._watch.start(now_ns)
        self._target_ns = now_ns + self._cycle_ns(True)
        return now_ns

    def _read_adc(self) -> tuple[int, SampleFlag]:
        """The 24-bit ADC result and why it is no measurement (OK when it is one): 0 means
        no conversion completed (STALE), all ones that nothing drove the bus (BLANK)."""
        self._in_flight = "adc_read"
        raw = self.link.transfer(bytes([ADC_READ]), ADC_READ_LEN)
        self._in_flight = None
        value = int.from_bytes(raw, "big")
        return value, (SampleFlag.STALE if value == 0 else blank_flag(raw))

    def _start_conversion(self, measurement: Measurement, now_ns: int) -> int:
        osr = (self.settings.pressure_oversampling if measurement is Measurement.D1
               else self.settings.temperature_oversampling)
        self._in_flight = measurement
        self._command(convert_command(measurement, osr))
        self._in_flight = None
        # The conversion starts when the command reaches the chip, which may be later than
        # the poll's nominal time (other devices' transfers ran first): wait from then, or
        # the ADC read lands inside the conversion and aborts it.
        start = max(now_ns, self.clock.now_ns())
        self._conv_start_ns = start
        if measurement is Measurement.D2:
            self._state = _State.CONVERTING_D2
            return start + self._t_d2_ns
        self._state = _State.CONVERTING_D1
        # A pressure conversion started more than half a period late (a stalled host)
        # completes in the next slot: the cadence slides with it, so that its slot counts
        # as never converted. Less late, it keeps the grid (the next cycle catches up), or a
        # host's usual microseconds of lateness would slow the cadence below its rate.
        if start + self._t_d1_ns - self._target_ns > self._period_ns // 2:
            self._slide_to(start + self._t_d1_ns)
        return start + self._t_d1_ns

    def _start_pressure_when_due(self, now_ns: int) -> int:
        due = self._target_ns - self._t_d1_ns
        if now_ns < due:
            return due
        return self._start_conversion(Measurement.D1, now_ns)

    def poll(self, now_ns: int) -> PollResult:
        if self._state is _State.IDLE:
            if self._need_temperature:
                start = self._cycle_start_ns()
                if now_ns < start:
                    return PollResult([], start)
                # Late beyond the slack: slide this cycle rather than shorten a wait.
                self._slide_to(now_ns + self._cycle_ns(True))
                return PollResult([], self._start_conversion(Measurement.D2, now_ns))
            self._slide_to(now_ns + self._t_d1_ns)
            return PollResult([], self._start_pressure_when_due(now_ns))

        ready = self._conv_start_ns + (
            self._t_d2_ns if self._state is _State.CONVERTING_D2 else self._t_d1_ns
        )
        if now_ns < ready:
            return PollResult([], ready)

        if self._state is _State.CONVERTING_D2:
            d2, bad = self._read_adc()
            if bad:
                return self._no_measurement(now_ns, bad)
            self._d2 = d2
            self._fresh_temperature = True
            self._need_temperature = False
            self._state = _State.IDLE
            self._slide_to(now_ns + self._t_d1_ns)
            return PollResult([], self._start_pressure_when_due(now_ns))

        d1, bad = self._read_adc()
        if not bad:
            bad = self._frozen_flag(d1)
        if bad:
            return self._no_measurement(now_ns, bad)
        self._watch.fresh_poll()
        samples = self._emit(d1, t_ns=ready)
        self._next_cycle(now_ns)
        return PollResult(samples, self._cycle_start_ns())

    def _frozen_flag(self, d1: int) -> SampleFlag:
        """FROZEN from the FROZEN_AFTER_FRAMES-th identical D1 word on, and for the slot that
        ends a frozen run: its temperature was converted before its pressure, maybe while
        the converter was still hung, and a D2 word cannot tell (the temperature noise is
        under one D2 count, so equal D2 words are normal). The next cycle converts a new
        temperature."""
        flag = self._frozen.observe(Measurement.D1, d1.to_bytes(3, "big"))
        ended = self._frozen_run and not flag
        self._frozen_run = bool(flag)
        return SampleFlag.FROZEN if ended else flag

    def _next_cycle(self, now_ns: int) -> None:
        self._state = _State.IDLE
        self._fresh_temperature = False
        self._since_temperature += 1
        self._need_temperature = self._since_temperature >= self.settings.temperature_every
        if self._need_temperature:
            self._since_temperature = 0
        self._target_ns += self._period_ns
        if self._cycle_start_ns() < now_ns:
            # Behind by more than the slack in a period: re-anchor the grid at now.
            self._slide_to(now_ns + self._cycle_ns(self._need_temperature))

    def _slide_to(self, target_ns: int) -> None:
        """The pressure conversion due at ``_target_ns`` cannot complete before
        ``target_ns`` (the poll came late, a convert command failed): the cadence slides
        there. The chip converts nothing in the time slid, which the frame ledger is told
        (``DeviceHealth.not_converted_ns``) so that it counts those slots as never
        converted, not as frames lost."""
        if target_ns > self._target_ns:
            self.health.not_converted_ns += target_ns - self._target_ns
            self._target_ns = target_ns

    def _emit(self, d1: int, *, t_ns: int) -> list[Sample]:
        assert self.coefficients is not None and self._d2 is not None
        result = compensate(self.coefficients, d1, self._d2)
        temp_flags = SampleFlag.OK if result.temperature_in_range else SampleFlag.OUT_OF_RANGE
        # Pressure is compensated with the temperature, so an invalid TEMP taints it too.
        pressure_flags = temp_flags if result.pressure_in_range else \
            temp_flags | SampleFlag.OUT_OF_RANGE  # (an enum | costs a Python call)
        if pressure_flags == SampleFlag.OK:
            pressure_flags = self._steps.observe(t_ns, result.pressure_pa)
        samples: list[Sample] = [
            PressureSample(t_ns=t_ns, device=self.device, flags=pressure_flags,
                           pressure_pa=result.pressure_pa)
        ]
        if self._fresh_temperature:
            samples.append(TemperatureSample(t_ns=t_ns, device=self.device, flags=temp_flags,
                                             temperature_degc=result.temperature_degc))
        if pressure_flags == SampleFlag.OK:
            self.last = result
        return samples

    def _no_measurement(self, now_ns: int, flags: SampleFlag) -> PollResult:
        """An ADC read carried no measurement (``flags`` says why: the conversion did not
        happen after a chip reset or glitch, nothing drove the bus, or the converter hung).
        Report the slot with NaN values and restart the cycle with a temperature; reset the
        chip when this keeps happening.

        The slot's pressure was converted only when this was a D1 read that found something
        other than 0 (0: no conversion completed); otherwise the chip made no frame there,
        a slot never converted (the frame ledger counts it apart, not as a frame lost)."""
        converted = self._state is _State.CONVERTING_D1 and not flags & SampleFlag.STALE
        samples: list[Sample] = [
            PressureSample(t_ns=now_ns, device=self.device, flags=flags,
                           pressure_pa=math.nan),
            TemperatureSample(t_ns=now_ns, device=self.device, flags=flags,
                              temperature_degc=math.nan),
        ]
        if self._watch.stale_poll():
            return PollResult(samples, self.restart(reset_detected=False))
        self._state = _State.IDLE
        self._need_temperature = True
        self._since_temperature = 0
        self._fresh_temperature = False
        # the next slot of the sample grid: never report missing slots faster than odr_hz
        if converted:
            self._target_ns += self._period_ns
        else:
            self._slide_to(self._target_ns + self._period_ns)
        self._slide_to(now_ns + self._cycle_ns(True))
        return PollResult(samples, self._cycle_start_ns())
