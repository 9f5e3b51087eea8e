"""MAX21100 and MAX21105 drivers (Maxim 6-axis IMUs; the MAX21100 adds an aux I2C master).

Register facts: imuhal's chip-facts notes (chips.md) sections 5 (MAX21105 user guide rev 1.4) and 6
(MAX21100, from four independent code bases; no datasheet). Tables live in registers.py,
decoding in decode.py; this module only talks to the bus and keeps time.

Per poll the driver reads one burst from SYSTEM_STATUS through TEMP_L, so the data-ready
bits and every word come from one transaction. Samples are in the chip's sensor frame:
gyro rad/s, accel m/s^2 specific force, temperature degC.
"""

from __future__ import annotations

from typing import ClassVar

from imuhal.bus.base import Bus, BusKind, Link
from imuhal.bus.registers import RegisterView
from imuhal.core.clock import Clock
from imuhal.core.errors import ConfigurationError, DeviceNotFoundError, NackError
from imuhal.core.samples import (
    AccelSample,
    Channel,
    Frame,
    GyroSample,
    Sample,
    SampleFlag,
    TemperatureSample,
)
from imuhal.drivers.base import DeviceIdentity, Driver, DriverSettings, PollResult
from imuhal_chips.max2110x import decode
from imuhal_chips.max2110x.registers import (
    ACCEL_RANGE_G,
    DR_CFG_TEMP_EN,
    GYRO_RANGE_DPS,
    I2C_CFG_I2C_OFF,
    MAX21100,
    MAX21105,
    PARTS_BY_WHO_AM_I,
    RST_SW_RESET,
    PartSpec,
    Reg,
    Scales,
    acc_cfg1,
    convention_for,
    gyro_cfg1,
    pwr_acc_cfg,
)
from imuhal_chips.max2110x.settings import Max2110xSettings, Max21100Settings, Max21105Settings

SOFT_RESET_WAIT_S = 0.010
"""Wait after a soft reset before touching registers. [UNVERIFIED: no documented figure;
10 ms is generous for an OTP reload.]"""
STALE_AFTER_PERIODS = 1.5
"""A channel with no data-ready for longer than this many of its periods is stale."""
STALE_POLLS_BEFORE_RESET = 4
"""Consecutive stale polls after which the driver resets and reconfigures the chip itself."""
TEMPERATURE_PERIOD_NS = 100_000_000
"""Temperature samples are emitted at most every 100 ms (it changes slowly)."""
GUARD_FRACTION = 8
"""Polls aim 1/8 period after the chip's measurement instant, and retry 1/8 period later
when a poll finds no new data (see ``poll``)."""
EARLY_FRACTION = 64
"""The poll grid steps 1/64 period short of the nominal period, so it creeps earlier than a
chip whose clock runs up to ~1.5 % fast instead of falling behind it; with an exact clock one
poll in about eight finds nothing and re-anchors a guard later."""


class Max2110xDriver(Driver):
    """Family base. Subclasses set ``name``, ``Settings`` and ``part``."""

    part: ClassVar[PartSpec]
    channels = (Channel.GYRO, Channel.ACCEL, Channel.TEMPERATURE)
    bus_kinds = frozenset({BusKind.I2C, BusKind.SPI})
    settings: Max2110xSettings

    def __init__(
        self, link: Link, settings: DriverSettings | dict[str, object], *, device: str,
        clock: Clock,
    ) -> None:
        super().__init__(link, settings, device=device, clock=clock)  # type: ignore[arg-type]
        self.regs = RegisterView(link, convention_for(link.kind))
        self.scales: Scales | None = None
        self._expected: dict[int, int] = {}
        self._period_ns = 0
        self._channel_period_ns: dict[Channel, int] = {}
        self._grid_start_ns = 0
        self._grid_k = 0
        self._power_on_ns = 0
        self._fast: Channel = Channel.GYRO
        self._searching = False
        self._last_fresh_ns: dict[Channel, int] = {}
        self._last_temp_ns: int | None = None
        self._stale_polls = 0
        self._next_check_ns = 0

    # --- identity -------------------------------------------------------------------------

    def probe(self) -> DeviceIdentity:
        expected = f"WHO_AM_I=0x{self.part.who_am_i:02X} ({self.part.part})"
        try:
            found = self.regs.read_u8(Reg.WHO_AM_I)
        except NackError as exc:
            raise DeviceNotFoundError(
                driver=self.name, bus=self.link.bus.name, address=self.link.target,
                expected=expected, found="no answer (NACK)",
                hint=self._absent_hint(),
            ) from exc
        if found != self.part.who_am_i:
            raise DeviceNotFoundError(
                driver=self.name, bus=self.link.bus.name, address=self.link.target,
                expected=expected, found=f"WHO_AM_I=0x{found:02X}", hint=self._wrong_hint(found),
            )
        self.identity = DeviceIdentity(
            driver=self.name, bus=self.link.bus.name, address=self.link.target,
            identity=f"WHO_AM_I=0x{found:02X}",
        )
        return self.identity

    def _absent_hint(self) -> str:
        if self.link.kind is BusKind.I2C:
            return ("check power and SDA/SCL wiring; the MAX2110x answers at 0x58 (SA0 low) "
                    "or 0x59 (SA0 high)")
        return "check power, chip select, MISO/MOSI/SCLK wiring and SPI mode 3"

    def _wrong_hint(self, found: int) -> str:
        other = PARTS_BY_WHO_AM_I.get(found)
        if other is not None:
            return f"this is a {other.part}: use driver {other.driver}"
        if found in (0x00, 0xFF):
            return (f"the bus reads all 0x{found:02X}: nothing drives MISO/SDA; check "
                    "wiring, chip select and SPI mode 3")
        return "another chip (or a clone) answers here; check the address/chip select"

    # --- configuration --------------------------------------------------------------------

    def register_plan(self) -> dict[int, int]:
        """Bank-0 register values for the settings (address -> value), in write order."""
        s, p = self.settings, self.part
        i2c_cfg = I2C_CFG_I2C_OFF if self.link.kind is BusKind.SPI else 0x00
        return {
            Reg.I2C_CFG: i2c_cfg,
            Reg.GYRO_CFG1: gyro_cfg1(s.gyro_range_dps, s.gyro_bandwidth_hz),
            Reg.GYRO_CFG2: p.gyro_odr_hz[s.gyro_odr_hz],
            Reg.PWR_ACC_CFG: pwr_acc_cfg(p, s.accel_range_g),
            Reg.ACC_CFG1: acc_cfg1(p, s.accel_lpf, s.accel_odr_hz),
            # data-ready cleared once all words of a channel are read; temperature on
            Reg.DR_CFG: DR_CFG_TEMP_EN,
            Reg.POWER_CFG: p.power_cfg_on,  # last: start measuring with everything set
        }

    def configure(self) -> None:
        """Soft reset, program bank 0 from the tables (power-down while writing), read back
        every register written and cache the active scales."""
        self.regs.write(Reg.BANK_SELECT, 0x00)
        self.regs.write(Reg.RST_REG, RST_SW_RESET)
        self.clock.sleep(SOFT_RESET_WAIT_S)
        self.regs.write(Reg.BANK_SELECT, 0x00)
        self.regs.write(Reg.POWER_CFG, 0x00)
        plan = self.register_plan()
        for reg, value in plan.items():
            self.regs.write(reg, value)
        self._power_on_ns = self.clock.now_ns()  # measurements are timed from here
        self._verify(plan)
        self._expected = plan
        s = self.settings
        self.scales = Scales(
            gyro_lsb_per_dps=GYRO_RANGE_DPS[s.gyro_range_dps][1],
            accel_lsb_per_g=ACCEL_RANGE_G[s.accel_range_g][1],
        )
        self._channel_period_ns = {
            Channel.GYRO: round(1e9 / s.gyro_odr_hz),
            Channel.ACCEL: round(1e9 / s.accel_odr_hz),
        }
        self._period_ns = min(self._channel_period_ns.values())
        self._fast = min(self._channel_period_ns, key=lambda c: self._channel_period_ns[c])

    def _verify(self, plan: dict[int, int]) -> None:
        wrong = self._mismatches(plan)
        if wrong:
            detail = ", ".join(
                f"0x{reg:02X} wrote 0x{want:02X} read 0x{got:02X}" for reg, want, got in wrong
            )
            raise ConfigurationError(
                f"{self.describe()}: configuration did not read back ({detail}); "
                "check the bus (SPI mode 3, signal integrity) and that this is a "
                f"{self.part.part}"
            )

    def _mismatches(self, plan: dict[int, int]) -> list[tuple[int, int, int]]:
        regs = sorted(plan)
        # one burst covering POWER_CFG..ACC_CFG1, single reads for the rest
        block = self.regs.read(Reg.POWER_CFG, Reg.ACC_CFG1 + 1)
        got = {r: block[r] for r in regs if r <= Reg.ACC_CFG1}
        for r in regs:
            if r not in got:
                got[r] = self.regs.read_u8(r)
        return [(r, plan[r], got[r]) for r in regs if got[r] != plan[r]]

    # --- sampling -------------------------------------------------------------------------

    def start(self, now_ns: int) -> int:
        # configure() may have waited on the clock since the caller read it (the base
        # recover() passes the time from before its configure()): never start in the past
        now_ns = max(now_ns, self.clock.now_ns())
        # The chip measures one period after the power mode write and every period after;
        # the poll grid sits a guard after those instants.
        self._grid_start_ns = self._power_on_ns + self._guard_ns()
        self._grid_k = 0
        self._searching = False
        self._last_fresh_ns = {Channel.GYRO: now_ns, Channel.ACCEL: now_ns}
        self._last_temp_ns = None
        self._stale_polls = 0
        self._next_check_ns = now_ns + round(self.settings.reset_check_s * 1e9)
        return self._next_poll(now_ns)

    def _guard_ns(self) -> int:
        return max(1, self._period_ns // GUARD_FRACTION)

    def _next_poll(self, now_ns: int) -> int:
        """Next point of the poll grid strictly after ``now_ns`` (late polls skip ahead)."""
        step = self._period_ns - self._period_ns // EARLY_FRACTION
        k = max(self._grid_k + 1, (now_ns - self._grid_start_ns) // step + 1)
        self._grid_k = k
        return self._grid_start_ns + k * step

    def poll(self, now_ns: int) -> PollResult:
        """Read one burst; emit a sample per channel with new data.

        Scheduling keeps the polls phase-locked just after the chip's measurements, so a
        late poll (another device on the bus, a busy host) still finds its sample unread:
        a poll that finds no new data on the fastest channel retries a guard later and
        re-anchors the grid where the data appeared; an overrun (a sample overwritten
        before it was read) moves the grid half a period earlier to re-acquire the phase.
        """
        if self.scales is None:
            raise ConfigurationError(f"{self.describe()}: poll() before configure()")
        if now_ns >= self._next_check_ns and self._reset_detected(now_ns):
            return PollResult([], self.start(self.clock.now_ns()))
        raw = self.regs.read(self.part.burst_start, self.part.burst_length)
        burst = decode.split_burst(raw)
        samples: list[Sample] = []
        stale = False
        for channel, ready in ((Channel.GYRO, burst.gyro_ready),
                               (Channel.ACCEL, burst.accel_ready)):
            if ready:
                self._last_fresh_ns[channel] = now_ns
                samples.append(self._vector_sample(channel, burst, now_ns, SampleFlag.OK))
            elif now_ns - self._last_fresh_ns[channel] > (
                STALE_AFTER_PERIODS * self._channel_period_ns[channel]
            ):
                stale = True
                samples.append(self._vector_sample(channel, burst, now_ns, SampleFlag.STALE))
        if burst.gyro_ready and (
            self._last_temp_ns is None or now_ns - self._last_temp_ns >= TEMPERATURE_PERIOD_NS
        ):
            self._last_temp_ns = now_ns
            temp = decode.temp_counts_to_degc(burst.temperature)
            samples.append(TemperatureSample(t_ns=now_ns, device=self.device,
                                             temperature_degc=temp))
        if stale:
            self._stale_polls += 1
            if self._reset_detected(now_ns):
                return PollResult(samples, self.start(self.clock.now_ns()))
            if self._stale_polls >= STALE_POLLS_BEFORE_RESET:
                # the chip answers and keeps its configuration but produces no data: a hung
                # measurement engine; a soft reset and reconfiguration is the cure
                self.configure()
                self.health.reconfigurations += 1
                return PollResult(samples, self.start(self.clock.now_ns()))
        else:
            self._stale_polls = 0
        fast_ready = burst.gyro_ready if self._fast is Channel.GYRO else burst.accel_ready
        if fast_ready and burst.overrun:
            self._grid_start_ns, self._grid_k = now_ns - self._period_ns // 2, 0
        elif fast_ready and self._searching:
            self._grid_start_ns, self._grid_k = now_ns, 0
        self._searching = False
        if not fast_ready and not stale:
            self._searching = True
            return PollResult(samples, now_ns + self._guard_ns())
        return PollResult(samples, self._next_poll(now_ns))

    def _vector_sample(
        self, channel: Channel, burst: decode.Burst, now_ns: int, flags: SampleFlag
    ) -> Sample:
        assert self.scales is not None
        if channel is Channel.GYRO:
            counts = burst.gyro
            value = decode.gyro_counts_to_rad_s(counts, self.scales.gyro_lsb_per_dps)
            cls: type[GyroSample] | type[AccelSample] = GyroSample
        else:
            counts = burst.accel
            value = decode.accel_counts_to_m_s2(counts, self.scales.accel_lsb_per_g)
            cls = AccelSample
        if decode.saturated(counts):
            flags |= SampleFlag.SATURATED
        if cls is GyroSample:
            return GyroSample(t_ns=now_ns, device=self.device, frame=Frame.SENSOR,
                              gyro_rad_s=value, flags=flags)
        return AccelSample(t_ns=now_ns, device=self.device, frame=Frame.SENSOR,
                           accel_m_s2=value, flags=flags)

    def _reset_detected(self, now_ns: int) -> bool:
        """Read the configuration back; if the chip lost it (silent reset, brown-out),
        count it and reconfigure. Returns True when it did."""
        self._next_check_ns = now_ns + round(self.settings.reset_check_s * 1e9)
        if not self._mismatches(self._expected):
            return False
        self.health.resets_detected += 1
        self.configure()
        self.health.reconfigurations += 1
        return True

    def full_scale(self, channel: Channel) -> float | None:
        """What the 16-bit data word can hold at the configured range (SI): the most
        negative count through this driver's own conversion."""
        if self.scales is None or channel not in (Channel.GYRO, Channel.ACCEL):
            return None
        if channel is Channel.GYRO:
            return abs(decode.gyro_counts_to_rad_s((-32768, 0, 0),
                                                   self.scales.gyro_lsb_per_dps)[0])
        return abs(decode.accel_counts_to_m_s2((-32768, 0, 0), self.scales.accel_lsb_per_g)[0])


class Max21105Driver(Max2110xDriver):
    """Maxim MAX21105 6-axis IMU on I2C (0x58/0x59) or SPI (mode 3)."""

    name = "max21105"
    description = "Maxim MAX21105 3-axis gyroscope + 3-axis accelerometer (I2C/SPI)"
    Settings = Max21105Settings
    part = MAX21105


class Max21100Driver(Max2110xDriver):
    """Maxim MAX21100 6-axis IMU with an aux I2C master (bus ``aux``) for a magnetometer."""

    name = "max21100"
    description = ("Maxim MAX21100 3-axis gyroscope + 3-axis accelerometer (I2C/SPI) with an "
                   "I2C master exposed as child bus 'aux'")
    Settings = Max21100Settings
    part = MAX21100

    def __init__(
        self, link: Link, settings: DriverSettings | dict[str, object], *, device: str,
        clock: Clock,
    ) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self._aux: Bus | None = None

    def child_buses(self) -> dict[str, Bus]:
        if self._aux is None:
            from imuhal_chips.max2110x.aux_bus import Max21100AuxBus

            self._aux = Max21100AuxBus(self)
        return {"aux": self._aux}
