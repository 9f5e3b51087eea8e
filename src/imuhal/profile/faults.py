"""Typed fault specifications for emulated boards (the data; imuhal.emulation.faults runs them).

Each fault names a ``device`` of the profile, a ``start_s`` and an ``end_s`` in simulated
seconds since the board was opened. ``end_s`` omitted: a window fault lasts to the end of the
run; an instantaneous fault (``reset``, ``corrupt_trim``) happens once at ``start_s``; a
one-off value fault (``wild_value``, ``wrong_pressure``) lasts its ``hold_s``, about one
measurement.

They live here, beside the rest of the profile schema, because a profile carries them
(``emulation: faults: [...]``); docs/reliability.md describes what each one yields.
"""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator


class _Fault(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    device: str
    """The profile device the fault hits (its bus line, its chip or its polls)."""
    start_s: float = Field(default=0.0, ge=0.0, allow_inf_nan=False)
    """Simulated time the fault starts, s since the board was opened."""
    end_s: float | None = Field(default=None, gt=0.0, allow_inf_nan=False)
    """Simulated time the fault ends (exclusive), s; None: see the module docstring."""

    #: True for faults that happen once, at ``start_s`` (``end_s`` must then be omitted).
    instantaneous: ClassVar[bool] = False

    @model_validator(mode="after")
    def _window(self) -> _Fault:
        if self.end_s is not None:
            if self.instantaneous:
                raise ValueError(f"{self.kind_name()} happens once at start_s; remove end_s")
            if self.end_s <= self.start_s:
                raise ValueError(f"end_s ({self.end_s:g}) must be after start_s "
                                 f"({self.start_s:g})")
        return self

    def kind_name(self) -> str:
        return str(getattr(self, "kind", type(self).__name__))

    def active(self, t_s: float) -> bool:
        """Whether a window fault is in force at ``t_s``."""
        return self.start_s <= t_s and (self.end_s is None or t_s < self.end_s)


class BusErrors(_Fault):
    """Transient bus errors: each transfer to the device fails (``BusError``) with
    probability ``rate``, as electrical glitches on real wiring do."""

    kind: Literal["bus_errors"] = "bus_errors"
    rate: float = Field(gt=0.0, le=1.0, allow_inf_nan=False)
    """Probability that one transfer fails (0.01: 1 %)."""


class BusOSError(_Fault):
    """The bus plugin raises a plain ``OSError`` (EIO), not one of imuhal's own errors, as a
    third-party bus or the kernel may; ``rate`` as for ``bus_errors``."""

    kind: Literal["os_error"] = "os_error"
    rate: float = Field(default=1.0, gt=0.0, le=1.0, allow_inf_nan=False)


class AllOnes(_Fault):
    """Every byte read from the device is 0xFF (MISO or SDA stuck high, unpowered chip, a
    missing slave behind an I2C master); writes still reach the chip."""

    kind: Literal["all_ones"] = "all_ones"


class AllZeros(_Fault):
    """Every byte read from the device is 0x00 (MISO stuck low); writes still reach it."""

    kind: Literal["all_zeros"] = "all_zeros"


class CorruptByte(_Fault):
    """On a serial line (a UART), one received byte arrives with the bits of ``mask``
    flipped: the ``byte``-th (0: the first) the host receives at or after ``start_s``. One
    deterministic upset, where ``bus_errors`` is random noise: what a single corrupted
    field (a UBX length byte) costs."""

    kind: Literal["corrupt_byte"] = "corrupt_byte"
    instantaneous: ClassVar[bool] = True
    byte: int = Field(default=0, ge=0)
    """Which byte from ``start_s`` on, counting from 0."""
    mask: int = Field(default=0x01, ge=0x01, le=0xFF)
    """The bits flipped (XOR)."""


class ChipAbsent(_Fault):
    """The chip is unplugged: it answers nothing (NACK / no chip select response). At
    ``end_s`` it is plugged back in and powers up in its reset state."""

    kind: Literal["absent"] = "absent"


class ChipReset(_Fault):
    """The chip resets on its own at ``start_s`` (brown-out, ESD): every register back to
    its power-on state, any conversion lost, nobody told."""

    kind: Literal["reset"] = "reset"
    instantaneous: ClassVar[bool] = True


class StuckDataReady(_Fault):
    """The measurement engine hangs: no new measurement completes and the data-ready
    indication never comes (MS5611: conversions never finish, ADC reads return 0). A soft
    reset of the chip cures it early, as on the chips that document it."""

    kind: Literal["stuck_data_ready"] = "stuck_data_ready"


class FrozenData(_Fault):
    """Conversions hang on one value: the chip keeps producing (and flagging ready) the same
    raw words, whatever the physics does."""

    kind: Literal["frozen"] = "frozen"


class StaleNavigation(_Fault):
    """A GNSS receiver restarts with stale navigation data: from ``start_s`` (to ``end_s``)
    it sends, each epoch, the last solution it had before ``start_s``, claiming a fix (a
    receiver that restored its last solution from battery-backed memory after a brown-out
    and does not mark it, or a clone that never clears its fix flags). ``time``: ``repeated``
    sends that solution's own time again (NAV-PVT's iTOW and UTC, NMEA's UTC: the time does
    not advance); ``unresolved`` sends its running clock's time with NAV-PVT's validDate,
    validTime and fullyResolved cleared (a clock not yet confirmed by the satellites)."""

    kind: Literal["stale_navigation"] = "stale_navigation"
    time: Literal["repeated", "unresolved"] = "repeated"


class CorruptTrim(_Fault):
    """At ``start_s``, ``bits`` random bits of the chip's factory calibration (MS5611 PROM,
    BMP280 trimming, AK8963 ASA) flip in what the driver reads; the sensor element itself is
    unchanged. Takes effect when the driver next reads them (probe, recovery)."""

    kind: Literal["corrupt_trim"] = "corrupt_trim"
    instantaneous: ClassVar[bool] = True
    bits: int = Field(default=1, ge=1, le=16)


class LatePolls(_Fault):
    """Every poll of the device in the window happens ``delay_s`` after it was due (a busy
    host, a stalled thread); the shared clock moves, so the other devices wait too."""

    kind: Literal["late_polls"] = "late_polls"
    delay_s: float = Field(gt=0.0, le=10.0, allow_inf_nan=False)


class TimingJitter(_Fault):
    """Every poll of the device in the window happens a uniformly random 0..``max_delay_s``
    after it was due."""

    kind: Literal["jitter"] = "jitter"
    max_delay_s: float = Field(gt=0.0, le=10.0, allow_inf_nan=False)


class HostStall(_Fault):
    """The host process pauses for ``stall_s`` (a garbage-collector pause, an SD-card write,
    a loaded Raspberry Pi) just before a poll of the device, ``every_s`` apart from
    ``start_s`` (a schedule) or at random at ``rate_hz`` on average (a Poisson process),
    within the window. The one clock moves, so every device waits: what the chips produce
    meanwhile is what their buffering can keep (issue 25 item 6)."""

    kind: Literal["host_stall"] = "host_stall"
    stall_s: float = Field(gt=0.0, le=10.0, allow_inf_nan=False)
    every_s: float | None = Field(default=None, gt=0.0, allow_inf_nan=False)
    """A stall every ``every_s`` seconds, the first at ``start_s``."""
    rate_hz: float | None = Field(default=None, gt=0.0, le=100.0, allow_inf_nan=False)
    """Stalls at random, ``rate_hz`` a second on average (seeded by the run's seed)."""

    @model_validator(mode="after")
    def _one_timing(self) -> HostStall:
        if (self.every_s is None) == (self.rate_hz is None):
            raise ValueError("host_stall needs exactly one of every_s (a schedule) or "
                             "rate_hz (at random)")
        return self


class WildValue(_Fault):
    """The chip measures ``value`` (SI, sensor frame) on ``axis`` of ``channel`` instead of
    the truth, from the device's first poll at or after ``start_s`` for ``hold_s`` (one
    measurement of a 250 Hz IMU: the value is handed over at polls, which come about one
    period apart, so the default is three quarters of a 4 ms period, not a whole one), or up
    to ``end_s``. What the chip reports is then limited
    by its range, as in silicon."""

    kind: Literal["wild_value"] = "wild_value"
    channel: Literal["accel", "gyro", "mag", "pressure", "temperature"]
    axis: int = Field(default=0, ge=0, le=2)
    """0, 1, 2 for x, y, z of a vector channel; ignored for pressure and temperature."""
    value: float
    """May be NaN or infinite (``.nan``, ``.inf`` in YAML): what a chip with a floating-point
    output register would then report."""
    hold_s: float = Field(default=0.003, gt=0.0, le=1.0)
    """How long a one-off (no ``end_s``) lasts: what the chip measures in that time."""


class WrongPressure(_Fault):
    """The barometer measures the true pressure plus ``offset_pa`` (a wrong but in-range
    value: a gust on the port, a glitch in the element) from its first poll at or after
    ``start_s`` for ``hold_s`` (one conversion cycle of a 50 Hz barometer), or up to
    ``end_s``."""

    kind: Literal["wrong_pressure"] = "wrong_pressure"
    offset_pa: float = Field(allow_inf_nan=False)
    hold_s: float = Field(default=0.02, gt=0.0, le=1.0)
    """How long a one-off (no ``end_s``) lasts."""


FaultSpec = Annotated[
    BusErrors | BusOSError | AllOnes | AllZeros | CorruptByte | ChipAbsent | ChipReset
    | StuckDataReady | FrozenData | StaleNavigation | CorruptTrim | LatePolls | TimingJitter
    | HostStall | WildValue | WrongPressure,
    Field(discriminator="kind"),
]
"""One fault of any kind, chosen by its ``kind`` key."""

FAULT_KINDS: tuple[type[_Fault], ...] = (
    BusErrors, BusOSError, AllOnes, AllZeros, CorruptByte, ChipAbsent, ChipReset,
    StuckDataReady, FrozenData, StaleNavigation, CorruptTrim, LatePolls, TimingJitter,
    HostStall, WildValue, WrongPressure)

CHIP_FAULT_KINDS = frozenset({"reset", "stuck_data_ready", "frozen", "corrupt_trim",
                              "stale_navigation"})
"""Kinds the chip emulator itself must model (ChipEmulator.chip_faults says which it does)."""
