"""BMP280 (Bosch) barometer driver: pressure and temperature on I2C or SPI.

Source of the register facts: BMP280 datasheet BST-BMP280-DS001-19 rev 1.19 (register map,
SPI/I2C protocol, timing) and the rev 1.14 worked example; cross-checked with Bosch
BMP280_driver v3.3.4 and Linux ``bmp280-core.c`` (imuhal shared chip facts, section 2).

One poll reads the coherent burst 0xF3..0xFC (status, ctrl_meas, config, pressure,
temperature): the chip's shadowing guarantees consistency only within one burst, and the
config bytes in it reveal a silent reset at no extra cost. Compensation uses the datasheet's
32-bit temperature and 64-bit pressure integer formulas with the chip's own trimming.

Modes: ``normal`` lets the chip cycle (measurement + standby) and polls once per cycle;
``forced`` triggers one measurement per poll at ``odr_hz`` and reads it when ``measuring``
clears and the mode bits have returned to sleep. The BMP280 has no data-ready flag: in forced
mode a measurement that has not finished after three times its maximum conversion time is
reported STALE; in normal mode staleness is only visible as the never-measured value 0x80000.

Frames accounted for: the chip has neither a data-ready bit nor a conversion counter, so in
normal mode, where its own oscillator paces the cycle (the datasheet's typical measurement
time, up to 15 % shorter than its maximum), the poll grid on the nominal cycle cannot tell a
repeat from a new output nor see one it skipped when the chip runs off that cycle
(docs/acquisition.md, "Ledgers with the chips' clocks off"). In forced mode the host starts
every conversion, as it does the MS5611's: each trigger that completes is one frame, a
trigger the schedule let slide past its slot made none (``DeviceHealth.not_converted_ns``),
and the ledger equals the chip's count whatever its oscillator does (``host_paced``).
"""

from __future__ import annotations

import math
from functools import partial
from typing import ClassVar, Literal

from pydantic import Field, field_validator, model_validator

from imuhal.bus.base import Bus, BusKind, Link
from imuhal.bus.register_plan import IN_PLACE_ATTEMPTS, RegisterPlan, RegisterSetting, retried
from imuhal.bus.registers import RegisterConvention, RegisterView
from imuhal.core.clock import Clock
from imuhal.core.errors import ConfigurationError, DeviceNotFoundError, NackError
from imuhal.core.samples import (
    Frame,
    PressureSample,
    Quantity,
    Sample,
    SampleFlag,
    TemperatureSample,
)
from imuhal.core.streams import StreamSpec
from imuhal.drivers.base import (
    DeviceIdentity,
    Driver,
    DriverSettings,
    PollResult,
    SettingsInput,
)
from imuhal.drivers.polling import PollGrid, ResetWatch
from imuhal.drivers.validity import FilterMemory, LearnedFrozenWatch, iir_memory_outputs
from imuhal_chips.bmp280 import registers as r
from imuhal_chips.bmp280.compensation import (
    Trim,
    compensate_pressure_int64,
    compensate_temperature_int32,
    decode_adc,
)

TRIGGER_CHECK_PLAN = 4
"""The poll plan (imuhal.core.poll_plan) from which a forced trigger write that failed is
checked by the retry's burst (``BMP280Driver._after_failed_trigger``), not sorted out by
the full recovery."""

PRESSURE_RANGE_PA = (30_000.0, 110_000.0)
TEMPERATURE_RANGE_DEGC = (-40.0, 85.0)
"""Datasheet operating ranges; readings outside are flagged OUT_OF_RANGE."""

KNOWN_IDS: dict[int, str] = {
    0x60: "a BME280 (pressure + humidity) answers here; use a BME280 driver",
    0x61: "a BME680 answers here",
    0x55: "a BMP180/BMP085 answers here (older register map)",
    0x00: "the id register reads 0x00: check power, SDO/CSB wiring and pull-ups",
    0xFF: "the id register reads 0xFF: MISO/SDA floats high (check CSB, wiring, SPI mode)",
}


class BMP280Settings(DriverSettings):
    """BMP280 settings in physical terms.

    ``odr_hz`` is the wanted measurement rate. In normal mode the driver picks the longest
    standby time whose cycle (typical measurement time + standby) still reaches ``odr_hz``,
    unless ``standby_ms`` names one; in forced mode it triggers at ``odr_hz``.
    """

    renamed: ClassVar[dict[str, str]] = {"iir_filter": "iir_coefficient"}

    mode: Literal["normal", "forced"] = "normal"
    pressure_oversampling: Literal[1, 2, 4, 8, 16] = 8
    temperature_oversampling: Literal[1, 2, 4, 8, 16] = 1
    iir_coefficient: Literal[0, 2, 4, 8, 16] = 4
    """IIR filter coefficient; 0 switches the filter off."""
    odr_hz: float = Field(25.0, gt=0)
    standby_ms: float | None = None
    """Normal-mode standby t_sb (ms); one of 0.5, 62.5, 125, 250, 500, 1000, 2000, 4000."""

    @field_validator("standby_ms")
    @classmethod
    def _standby_known(cls, value: float | None) -> float | None:
        if value is not None and value not in r.STANDBY_CODES_MS:
            allowed = ", ".join(f"{v:g}" for v in r.STANDBY_CODES_MS)
            raise ValueError(f"standby_ms must be one of {allowed} (got {value:g})")
        return value

    @model_validator(mode="after")
    def _rate_reachable(self) -> BMP280Settings:
        if self.mode == "forced":
            if self.standby_ms is not None:
                raise ValueError("standby_ms applies to normal mode only; forced mode uses odr_hz")
            t_max = r.measurement_time_s(self.temperature_oversampling,
                                         self.pressure_oversampling, maximum=True)
            if self.odr_hz > 1.0 / t_max:
                raise ValueError(
                    f"odr_hz {self.odr_hz:g} is faster than one forced measurement at these "
                    f"oversamplings allows (at most {1.0 / t_max:.1f} Hz: each takes up to "
                    f"{t_max * 1e3:.2f} ms); lower odr_hz or the oversampling")
        elif self.standby_ms is None:
            self.chosen_standby_ms()
        return self

    def measurement_time_s(self, *, maximum: bool) -> float:
        return r.measurement_time_s(self.temperature_oversampling, self.pressure_oversampling,
                                    maximum=maximum)

    def chosen_standby_ms(self) -> float:
        """The normal-mode standby time: ``standby_ms`` or the longest one reaching odr_hz."""
        if self.standby_ms is not None:
            return self.standby_ms
        t_meas_ms = self.measurement_time_s(maximum=False) * 1000.0
        fitting = [sb for sb in r.STANDBY_CODES_MS if 1000.0 / (t_meas_ms + sb) >= self.odr_hz]
        if not fitting:
            fastest = 1000.0 / (t_meas_ms + 0.5)
            raise ValueError(
                f"odr_hz {self.odr_hz:g} is out of reach in normal mode at these oversamplings "
                f"(at most {fastest:.1f} Hz); lower the oversampling or odr_hz")
        return max(fitting)


class BMP280Driver(Driver):
    """Bosch BMP280 pressure + temperature sensor."""

    name = "bmp280"
    description = "Bosch BMP280 barometer (pressure, temperature), I2C 0x76/0x77 or SPI"
    Settings = BMP280Settings
    channels: ClassVar[tuple[Quantity, ...]] = (Quantity.PRESSURE, Quantity.TEMPERATURE)
    bus_kinds: ClassVar[frozenset[BusKind]] = frozenset({BusKind.I2C, BusKind.SPI})
    resumes_in_a_row = IN_PLACE_ATTEMPTS
    """The burst a resumed poll reads carries ctrl_meas and config: it checks them again."""

    STALE_AFTER_MAX_TIMES = 3
    """Forced mode: a measurement unfinished after this many maximum conversion times is stale."""
    FROZEN_AFTER_FRAMES = 25
    """Identical pressure + temperature ADC words in a row that mean the conversions hung
    (normal mode keeps the last result readable forever). Unfiltered, the quietest setting
    (x1 oversampling, 2.6 Pa/LSB, 1.3 Pa noise) repeats the pair with probability about
    FROZEN_REPEAT_X1; 25 in a row (1 s at 25 Hz), about 1e-13 per sample. The IIR filter
    makes consecutive outputs follow each other over about ``iir_coefficient`` samples, so
    this fixed window grows by ``FROZEN_IIR_FACTOR`` times the coefficient (41 at 4).

    That fixed window is the ceiling. A frozen gy91 BMP280 (IIR 4) handed out valid
    pressures up to 32 Pa off in a climb before it was flagged (the soak): its filtered
    20-bit words repeat far less often than the x1 chip's 16-bit ones. How much less
    depends on the part's noise against its LSB, which the datasheet gives only as a typical
    figure (a window from it flagged a quieter chip, the conformance sweep's sub-LSB
    dithered one, FROZEN at every setting). So the driver learns the odds from the chip:
    over its first FROZEN_LEARN_PAIRS outputs it counts the repeats, and the window becomes
    the one whose false-alarm chance matches the fixed window's design
    (``FROZEN_REPEAT_X1 ** (FROZEN_AFTER_FRAMES - 1)``) at an upper bound of the learned
    odds (``LearnedFrozenWatch``): 13 outputs for the emulated gy91 (0.33 s at its
    40 Hz in forced mode), the ceiling for a chip quieter than one LSB."""
    FROZEN_REPEAT_X1 = 0.3
    FROZEN_LEARN_PAIRS = 100
    """Consecutive output pairs counted before the window is shortened (2.5 s at 40 Hz; the
    ceiling holds meanwhile)."""
    FROZEN_IIR_FACTOR = 4
    NOISE_PA = 1.3
    """The datasheet's RMS pressure noise of one conversion (its typical figure at the
    oversampling the emulated gy91 uses): what a hung word can differ from the filter's
    state by, at 6 sigma."""
    FILTERED_PA_PER_LSB = 0.16
    """One LSB of the filtered 20-bit pressure word (datasheet: 0.16 Pa resolution)."""

    def __init__(self, link: Link, settings: SettingsInput, *, device: str,
                 clock: Clock) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self.settings: BMP280Settings
        # Writes are (address, data) pairs on both buses; SPI reads set bit 7, writes clear it.
        convention = (
            RegisterConvention(read_set=0x80, write_clear=0x80, pairwise_burst_write=True)
            if link.kind is BusKind.SPI
            else RegisterConvention(pairwise_burst_write=True)
        )
        self.regs = RegisterView(link, convention)
        self.trim: Trim | None = None
        self._ctrl = 0
        self._config = 0
        self._period_ns = 0
        self._readback = b""
        self.plan = RegisterPlan(self.describe(), [])
        """ctrl_meas and config as read back from the chip (the stream specs' source)."""
        self._triggered_ns: int | None = None
        self._next_ns = 0
        self._due_ns = 0
        """Forced mode: when the next trigger is due, one period after the one before (the
        schedule's slot; a later trigger slides the schedule, ``_trigger``)."""
        self._running_ns: int | None = None
        """Forced mode: the latest read since the trigger that found its conversion still
        running past its maximum time (None: none did)."""
        self._late_told_ns = 0
        """Forced mode: how far past its maximum time the reads since the trigger found the
        conversion still running, as told the frame ledger (``_running``)."""
        self._trying_ns: int | None = None
        """Forced mode: when a trigger write that failed was made (``resume``), until a read
        tells whether it started a conversion (``_after_failed_trigger``)."""
        self._last_output: tuple[int, int, int] | None = None
        """(t_ns, adc_P, adc_T) of the last filtered output read since the filter reset."""
        self._grid = PollGrid(1)
        # The BMP280 keeps its configuration in every poll burst, so the watch only counts
        # polls without a measurement; it never schedules a separate read-back.
        self._watch = ResetWatch(check_s=None)
        self._frozen = LearnedFrozenWatch(
            self.FROZEN_AFTER_FRAMES + self.FROZEN_IIR_FACTOR * self.settings.iir_coefficient,
            learn_pairs=self.FROZEN_LEARN_PAIRS,
            false_alarm=self.FROZEN_REPEAT_X1 ** (self.FROZEN_AFTER_FRAMES - 1))
        self._memory = FilterMemory({}, {})

    # -- identity ---------------------------------------------------------------------------

    def _not_found(self, found: str, hint: str) -> DeviceNotFoundError:
        return DeviceNotFoundError(
            driver=self.name, bus=self.link.bus.name, address=self.link.target,
            expected=f"chip id 0x{r.CHIP_ID:02X} at register 0x{r.REG_CHIP_ID:02X}",
            found=found, hint=hint)

    def probe(self) -> DeviceIdentity:
        try:
            chip_id = retried(partial(self.regs.read_u8, r.REG_CHIP_ID))
        except NackError as exc:
            where = ("SDO to GND gives 0x76, SDO to VDDIO 0x77"
                     if self.link.kind is BusKind.I2C else "check CSB and the SPI wiring")
            raise self._not_found("no answer (NACK)", f"is the BMP280 powered? {where}") from exc
        note = ""
        if chip_id in r.SAMPLE_CHIP_IDS:
            note = f"engineering sample id 0x{chip_id:02X} (accepted as a BMP280)"
        elif chip_id != r.CHIP_ID:
            raise self._not_found(f"0x{chip_id:02X}",
                                  KNOWN_IDS.get(chip_id, "another chip or a clone answers here"))
        self.identity = DeviceIdentity(self.name, self.link.bus.name, self.link.target,
                                       f"chip_id=0x{chip_id:02X}", note)
        return self.identity

    # -- configuration ----------------------------------------------------------------------

    def configure(self) -> None:
        s = self.settings
        # every transfer that fails is repeated in place (RegisterPlan.retried), so a
        # glitch does not start the reset and the NVM copy over (issue 26)
        retried(partial(self.regs.write, r.REG_RESET, r.RESET_COMMAND))
        self.clock.sleep(r.STARTUP_S)
        deadline = self.clock.now_ns() + 20_000_000
        while retried(partial(self.regs.read_u8, r.REG_STATUS)) & r.STATUS_IM_UPDATE:
            if self.clock.now_ns() > deadline:
                raise ConfigurationError(
                    f"{self.describe()}: NVM copy (status.im_update) did not finish in 20 ms")
            self.clock.sleep(0.0005)
        trim = Trim.from_bytes(retried(partial(self.regs.read, r.REG_CALIB, r.CALIB_LENGTH)))
        if not trim.plausible():
            raise ConfigurationError(
                f"{self.describe()}: trimming reads blank ({trim}); check the wiring")
        if self.trim is not None and trim != self.trim:
            # The factory trimming never changes and, unlike the MS5611's PROM, has no CRC:
            # a re-probe reading other words than the start-up read is a corrupted read (or
            # another part), and compensating with it would give a constant wrong pressure
            # (7.5 kPa for one flipped bit of dig_P) that no range check sees.
            changed = [name for name, old, new in zip(
                Trim.__dataclass_fields__, _words(self.trim), _words(trim), strict=True)
                if old != new]
            raise ConfigurationError(
                f"{self.describe()}: trimming {', '.join(changed)} reads differently from "
                "start-up: the chip's calibration read is corrupted or another part answers; "
                "refused rather than compensating with a wrong trimming")
        self.trim = trim

        standby = s.chosen_standby_ms() if s.mode == "normal" else 0.5
        self._config = r.config_value(standby, s.iir_coefficient)
        mode = r.MODE_NORMAL if s.mode == "normal" else r.MODE_SLEEP
        self._ctrl = r.ctrl_meas_value(s.temperature_oversampling, s.pressure_oversampling, mode)
        self.plan = self._register_plan()
        back = self.plan.establish(self.regs)
        self._readback = bytes((back[r.REG_CTRL_MEAS], back[r.REG_CONFIG]))
        self._period_ns = self._streams_from(self._readback)[0].period_ns
        # Writing config has reset the IIR filter (datasheet 3.4.3: the next measurement
        # passes unchanged and seeds it), so nothing measured before reaches a later output.
        self._memory = FilterMemory({"adc": self.filter_memory_outputs()},
                                    {"adc": self._period_ns})
        self._last_output = None
        self._grid = PollGrid(self._period_ns)
        self._triggered_ns = self._trying_ns = None  # a recovery ends what was under way

    def _streams_from(self, back: bytes) -> tuple[StreamSpec, StreamSpec]:
        """Pressure (Pa) and temperature (degC) specs from ctrl_meas and config as read
        from the chip: in normal mode the chip's own cycle, the typical measurement time of
        the oversamplings read back (osrs_t, osrs_p) plus the standby time (t_sb); in forced
        mode the driver triggers each measurement on its own grid at ``odr_hz`` (no register
        holds a rate). Scale: the compensated output's resolution (1/256 Pa, 0.01 degC); no
        full scale declared. Latency: the measurement time."""
        ctrl, config = back[0], back[1]
        t_os = r.oversampling_from_code(ctrl >> 5)
        p_os = r.oversampling_from_code((ctrl >> 2) & 0b111)
        t_meas = r.measurement_time_s(t_os, p_os, maximum=False)
        if ctrl & r.MODE_MASK == r.MODE_NORMAL:
            period_s = t_meas + r.standby_ms_from_code(config >> 5) / 1000.0
        else:
            period_s = 1.0 / self.settings.odr_hz
        rate_hz = 1e9 / round(period_s * 1e9)
        return (
            StreamSpec(self.device, Quantity.PRESSURE, Frame.SENSOR, rate_hz, scale=1 / 256,
                       latency_s=t_meas),
            StreamSpec(self.device, Quantity.TEMPERATURE, Frame.SENSOR, rate_hz, scale=0.01,
                       latency_s=t_meas),
        )

    def streams(self) -> tuple[StreamSpec, ...]:
        """Pressure and temperature, as read back at ``configure()``."""
        return self._streams_from(self._readback) if self._readback else ()

    def refresh_streams(self) -> tuple[StreamSpec, ...]:
        self._readback = bytes(self.regs.read(r.REG_CTRL_MEAS, 2))
        return self.streams()

    def start(self, now_ns: int) -> int:
        # recover() passes the time from before configure() waited; never start in the past.
        now_ns = max(now_ns, self.clock.now_ns())
        self._watch.start(now_ns)
        if self.settings.mode == "normal":
            # The first cycle ends one measurement after the ctrl_meas write.
            self._next_ns = now_ns + round(self.settings.measurement_time_s(maximum=True) * 1e9)
            self._grid.anchor(self._next_ns)
        else:
            self._next_ns = self._due_ns = now_ns
        return self._next_ns

    # -- polling ----------------------------------------------------------------------------

    def _read_burst(self) -> tuple[int, int, int, int, int]:
        """(status, ctrl_meas, config, adc_P, adc_T) from one burst 0xF3..0xFC."""
        data = self.regs.read(r.POLL_BURST_START, r.POLL_BURST_LENGTH)
        adc_p, adc_t = decode_adc(data[4:10])
        return data[0], data[1], data[2], adc_p, adc_t

    def _register_plan(self) -> RegisterPlan:
        """config first: the chip may ignore config writes once in normal mode. In forced
        mode the chip returns ctrl_meas's mode bits to sleep after each measurement, so
        they are not checked."""
        forced = self.settings.mode == "forced"
        return RegisterPlan(self.describe(), [
            RegisterSetting(r.REG_CONFIG, self._config, name="config"),
            RegisterSetting(r.REG_CTRL_MEAS, self._ctrl, name="ctrl_meas",
                            mask=0xFF & ~r.MODE_MASK if forced else 0xFF)])

    def _burst_off_plan(self, ctrl: int, config: int) -> bool:
        """Whether ctrl_meas and config, as a poll burst read them, differ from the plan
        (the burst carries both: every poll checks them for free)."""
        return bool(self.plan.mismatches({r.REG_CTRL_MEAS: ctrl, r.REG_CONFIG: config}))

    def poll(self, now_ns: int) -> PollResult:
        if self.settings.mode == "forced":
            return self._poll_forced(now_ns)
        _status, ctrl, config, adc_p, adc_t = self._read_burst()
        if self._burst_off_plan(ctrl, config):
            return PollResult([], self.restart(reset_detected=True))
        stale = adc_p == r.ADC_SKIPPED and adc_t == r.ADC_SKIPPED
        return self._finish(now_ns, adc_p, adc_t, stale, self._grid.next_after(now_ns))

    def _poll_forced(self, now_ns: int) -> PollResult:
        t_max_ns = round(self.settings.measurement_time_s(maximum=True) * 1e9)
        if self._trying_ns is not None:
            return self._after_failed_trigger(now_ns, t_max_ns)
        if self._triggered_ns is None:
            if now_ns < self._next_ns:
                return PollResult([], self._next_ns)
            self._trigger(now_ns)
            return PollResult([], now_ns + t_max_ns)
        status, ctrl, config, adc_p, adc_t = self._read_burst()
        if self._burst_off_plan(ctrl, config):
            return PollResult([], self.restart(reset_detected=True))
        done = not status & r.STATUS_MEASURING and ctrl & r.MODE_MASK == r.MODE_SLEEP
        if not done and now_ns - self._triggered_ns < self.STALE_AFTER_MAX_TIMES * t_max_ns:
            self._running(now_ns, t_max_ns)
            return PollResult([], now_ns + t_max_ns // 10)
        trigger = self._triggered_ns
        running, told = self._running_ns, self._late_told_ns
        self._triggered_ns = self._running_ns = None
        self._late_told_ns = 0
        stale = not done or (adc_p == r.ADC_SKIPPED and adc_t == r.ADC_SKIPPED)
        if not done or running is not None:
            return self._finish_late(now_ns, trigger, t_max_ns, told, adc_p, adc_t,
                                     stale=stale, done=done, running_ns=running)
        self._due_ns = trigger + self._period_ns
        self._next_ns = max(self._due_ns, now_ns)
        # The conversion ended by the datasheet's maximum time after the trigger: stamped
        # there, not at a read the host made late (a stall).
        return self._finish(min(trigger + t_max_ns, now_ns), adc_p, adc_t, stale,
                            self._next_ns)

    def _running(self, now_ns: int, t_max_ns: int) -> None:
        """A read found the conversion triggered still running past its maximum time (a
        chip slower than its datasheet, a hung one): the chip converts nothing else until
        it ends, so the time past that maximum is time its schedule slid, told the frame
        ledger as it passes (``DeviceHealth.not_converted_ns``), before the frame that ends
        it: the pipeline counts a slide told with a frame in the gap after that frame."""
        assert self._triggered_ns is not None
        self._running_ns = now_ns
        late = now_ns - (self._triggered_ns + t_max_ns)
        if late > self._late_told_ns:
            self.health.not_converted_ns += late - self._late_told_ns
            self._late_told_ns = late

    def _finish_late(self, now_ns: int, trigger: int, t_max_ns: int, told_ns: int,
                     adc_p: int, adc_t: int, *, stale: bool, done: bool,
                     running_ns: int | None) -> PollResult:
        """The read after reads that found the conversion triggered at ``trigger`` still
        running past its maximum time (``_running``, ``told_ns`` of it told): it found the
        conversion ended (``done``), or gave up on it (a hung chip). Given up, the chip made
        no frame from the trigger to now, which the ledger counts apart (not converted).
        Ended, it ended between the latest read that found it running and this one, and is
        stamped at this one: more than half a period between the two, and the stamp can lie
        further from its instant than the ledger's rounding allows (a host that stalled
        during a hang: 128 ms after it on gy91 at 1 % ``stuck_data_ready``), so the sample
        is STALE (counted lost, not delivered valid) and the time it took is told as slid.
        The next trigger comes in its slot, or at once when that has passed; the time slid
        up to it is told here."""
        self._due_ns = self._next_ns = max(trigger + self._period_ns, now_ns)
        if not done:
            self.health.not_converted_ns += now_ns - trigger - told_ns
            return self._finish(now_ns, adc_p, adc_t, True, self._next_ns)
        assert running_ns is not None
        measured = not stale
        if 2 * (now_ns - running_ns) >= self._period_ns:
            self.health.not_converted_ns += now_ns - (trigger + t_max_ns) - told_ns
            stale = True
        return self._finish(now_ns, adc_p, adc_t, stale, self._next_ns, measured=measured)

    def _trigger(self, now_ns: int) -> None:
        """Start one forced conversion. A trigger later than its slot (a late poll: a
        stalled host, another device's recovery, a read that came late) slides the
        schedule: the chip converts nothing in the time slid, which the frame ledger is
        told (``DeviceHealth.not_converted_ns``), so that it counts the slots it spans as
        never converted, not as frames lost."""
        self._trying_ns = now_ns
        self.regs.write(r.REG_CTRL_MEAS, (self._ctrl & ~r.MODE_MASK) | r.MODE_FORCED)
        self._trying_ns = None
        self._triggered(now_ns)

    def _triggered(self, now_ns: int) -> None:
        """A forced conversion started at ``now_ns`` (``_trigger``)."""
        if now_ns > self._due_ns:
            self.health.not_converted_ns += now_ns - self._due_ns
        self._triggered_ns = self._due_ns = now_ns
        self._running_ns = None
        self._late_told_ns = 0

    def _finish(self, now_ns: int, adc_p: int, adc_t: int, stale: bool,
                next_ns: int, *, measured: bool = False) -> PollResult:
        """Emit one measurement slot; a chip that keeps producing none is restarted
        (``measured``: it made this one, whatever its flag says)."""
        bad = SampleFlag.STALE if stale else self._frozen_flag(adc_p, adc_t)
        samples = self._emit(now_ns, adc_p, adc_t, bad)
        if not bad or measured:
            self._watch.fresh_poll()
        elif self._watch.stale_poll():
            return PollResult(samples, self.restart(reset_detected=False))
        return PollResult(samples, next_ns)

    def resume(self, now_ns: int) -> int | None:
        """One transfer of a poll failed: read the burst again at once instead of the full
        recovery (soft reset, NVM copy and trimming read). The burst itself carries
        ctrl_meas and config, so the retry still catches a chip that reset. In forced mode a
        failed trigger write may or may not have started a conversion: from poll plan
        TRIGGER_CHECK_PLAN the retry's burst tells (``_after_failed_trigger``); before, the
        full recovery sorted it out (a soft reset, the NVM copy and the trimming read at
        half the bus errors on gy91's barometer: 14 in 30 s at 1 %)."""
        if self.trim is None:
            return None
        if self.settings.mode == "forced" and self._triggered_ns is None and (
                self._trying_ns is None or self.poll_plan < TRIGGER_CHECK_PLAN):
            self._trying_ns = None
            return None
        return max(now_ns, self.clock.now_ns())

    def _after_failed_trigger(self, now_ns: int, t_max_ns: int) -> PollResult:
        """The poll after a trigger write that failed (``resume``): the burst says whether
        the write reached the chip. A conversion under way (``measuring``, or the mode bits
        still forced) started at the write; the chip asleep and idle started none, so the
        trigger is written again. Only while no conversion could have ended since the write
        (the shortest one, the typical time at 2 % fast): later, a chip found idle may have
        converted and gone back to sleep, which the full recovery sorts out."""
        tried = self._trying_ns
        assert tried is not None
        self._trying_ns = None
        status, ctrl, config, _adc_p, _adc_t = self._read_burst()
        if self._burst_off_plan(ctrl, config):
            return PollResult([], self.restart(reset_detected=True))
        if status & r.STATUS_MEASURING or ctrl & r.MODE_MASK != r.MODE_SLEEP:
            self._triggered(tried)
            return PollResult([], tried + t_max_ns)
        shortest_ns = round(self.settings.measurement_time_s(maximum=False) * 1e9 / 1.02)
        if now_ns - tried >= shortest_ns:
            return PollResult([], self.restart(reset_detected=False))
        self._trigger(now_ns)
        return PollResult([], now_ns + t_max_ns)

    @property
    def host_paced(self) -> bool:
        """Forced mode: the driver starts every conversion, so a late poll triggers when the
        host is free (the schedule slides, ``_trigger``) and measures the world of then."""
        return self.settings.mode == "forced"

    def accounted_stream(self) -> tuple[Quantity, int] | None:
        """One pressure per cycle: in normal mode the chip's measurement plus standby
        (typical measurement time), in forced mode the driver's trigger schedule at
        ``odr_hz`` (one conversion per trigger: the count is the host's, exact whatever the
        chip's oscillator does)."""
        if not self._period_ns:
            return None
        return Quantity.PRESSURE, self._period_ns

    def filter_memory_outputs(self) -> int:
        """Outputs after a wrong measurement that the IIR filter can still carry it (0: the
        filter is off). The filter runs on the 20-bit ADC words of both quantities (datasheet
        3.4.3); pressure is compensated with the temperature, so they share one memory."""
        return iir_memory_outputs(self.settings.iir_coefficient, r.ADC_BITS_FILTERED)

    def _measured_flags(self, t_ns: int, adc_p: int, adc_t: int) -> SampleFlag:
        """Flags of what the chip *measured* into this filtered output.

        With the IIR filter on, an output is ``(c - 1) / c`` of the previous one plus
        ``1 / c`` of the new ADC word (datasheet 3.4.3), so a measurement at the ADC's rail or
        outside the operating range can leave an output that looks in range. The driver
        undoes the filter: from the last output ``g`` periods before (``g`` > 1 when outputs
        were lost to bus errors) the weighted mean of the ``g`` ADC words that went in is
        ``(y - a^g y_prev) / (1 - a^g)`` with ``a = (c - 1) / c``. A mean at the rail is
        ``SATURATED``, one whose compensated value lies outside the operating range is
        ``OUT_OF_RANGE``. The tolerance is the output's rounding, ``c`` LSB of the mean.
        Without a previous output since the filter was reset the output is the ADC word."""
        assert self.trim is not None
        c = self.settings.iir_coefficient
        last, self._last_output = self._last_output, (t_ns, adc_p, adc_t)
        if c <= 1 or last is None or t_ns <= last[0]:
            return SampleFlag.OK
        periods = max(1, round((t_ns - last[0]) / self._period_ns))
        keep = ((c - 1) / c) ** periods
        if keep < 1e-6:
            return SampleFlag.OK  # the previous output no longer weighs in: y is the mean
        mean_p = (adc_p - keep * last[1]) / (1.0 - keep)
        mean_t = (adc_t - keep * last[2]) / (1.0 - keep)
        if any(m <= c or m >= r.ADC_MAX - c for m in (mean_p, mean_t)):
            return SampleFlag.SATURATED
        t_centi, t_fine = compensate_temperature_int32(round(mean_t), self.trim)
        pressure = compensate_pressure_int64(round(mean_p), t_fine, self.trim) / 256.0
        if not (TEMPERATURE_RANGE_DEGC[0] <= t_centi / 100.0 <= TEMPERATURE_RANGE_DEGC[1]
                and PRESSURE_RANGE_PA[0] <= pressure <= PRESSURE_RANGE_PA[1]):
            return SampleFlag.OUT_OF_RANGE
        return SampleFlag.OK

    def frozen_detection_outputs(self) -> int:
        """The outputs after its conversions hang that the chip can still hand out valid:
        the tolerance a hang costs, stated. The filter moves ``1 / c`` of the way from its
        state to the hung word at each output (datasheet 3.4.3), so a hung word within 6
        sigma of noise of the state settles to one repeated 20-bit output within
        ``ln(6 sigma / LSB) / ln(c / (c - 1))`` outputs (14 at coefficient 4); then
        ``frozen_window`` identical outputs must come before FROZEN: until the window is full
        a hung chip looks like a quiet one, and a shorter window would flag quiet chips. So
        a valid output of a hung chip carries the world of at most this many outputs ago
        (27 outputs, 0.68 s, for the emulated gy91 at 40 Hz: 18 Pa in a 2.2 m/s climb)."""
        c = self.settings.iir_coefficient
        settle = 0 if c <= 1 else math.ceil(
            math.log(6 * self.NOISE_PA / self.FILTERED_PA_PER_LSB) / math.log(c / (c - 1)))
        return settle + self.frozen_window()

    def frozen_window(self) -> int:
        """Identical outputs in a row that are FROZEN now: the learned window, or the fixed
        ceiling while the driver is still learning the chip's repeat odds."""
        return self._frozen.window("adc")

    def _frozen_flag(self, adc_p: int, adc_t: int) -> SampleFlag:
        return self._frozen.observe("adc", adc_p.to_bytes(3, "big") + adc_t.to_bytes(3, "big"))

    def _emit(self, t_ns: int, adc_p: int, adc_t: int, bad: SampleFlag) -> list[Sample]:
        assert self.trim is not None, "poll() before configure()"
        if bad:
            flags_p = flags_t = bad
            pressure = temperature = math.nan
            if bad & SampleFlag.FROZEN:
                # the hung converter fed its filter the old word too: the outputs after it
                # thaws still blend that in
                self._memory.arm("adc", t_ns)
        else:
            t_centi, t_fine = compensate_temperature_int32(adc_t, self.trim)
            temperature = t_centi / 100.0
            pressure = compensate_pressure_int64(adc_p, t_fine, self.trim) / 256.0
            flags_t = _range_flags(adc_t, temperature, TEMPERATURE_RANGE_DEGC)
            # Pressure is compensated with the temperature, so its flags carry over.
            flags_p = flags_t | _range_flags(adc_p, pressure, PRESSURE_RANGE_PA)
            measured = self._measured_flags(t_ns, adc_p, adc_t)
            flags_p |= measured
            flags_t |= measured
            settling = self._memory.flag("adc", t_ns, flags_p)
            flags_p |= settling
            flags_t |= settling
        return [
            PressureSample(t_ns=t_ns, device=self.device, flags=flags_p, pressure_pa=pressure),
            TemperatureSample(t_ns=t_ns, device=self.device, flags=flags_t,
                              temperature_degc=temperature),
        ]

    def child_buses(self) -> dict[str, Bus]:
        return {}


def _words(trim: Trim) -> tuple[int, ...]:
    return tuple(getattr(trim, name) for name in Trim.__dataclass_fields__)


def _range_flags(adc: int, value: float, limits: tuple[float, float]) -> SampleFlag:
    flags = SampleFlag.OK
    if adc in (0, r.ADC_MAX):
        flags |= SampleFlag.SATURATED
    if not limits[0] <= value <= limits[1]:
        flags |= SampleFlag.OUT_OF_RANGE
    return flags

