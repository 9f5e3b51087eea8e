"""MS5611-01BA03 emulator: the chip's command state machine on a bus, fed by true physics.

Bus face (identical on I2C and SPI, since every transaction is "command bytes, then read"):
- RESET (0x1E) aborts any conversion and reloads the PROM, which takes 2.8 ms; commands that
  arrive during the reload are acknowledged but have no effect, and reads return zeros.
- Convert D1/D2 captures the physics at its start and completes after the *typical* time
  for its OSR on ``self.clock``; a convert issued while another runs aborts the running one
  and its own result is garbage (the datasheet: "an incorrect result").
- ADC read (0x00) returns the 24-bit result once per finished conversion; it returns 0 when
  no conversion finished since the last read (so a repeated read returns 0), and a read while
  a conversion runs returns 0 and aborts that conversion.
- PROM read (0xA0 + 2n) returns word n, MSB first.
A read with no command in the same transaction returns what the last command left in the
output register (I2C drivers that write the command and read in two transactions).

Own clock (issue 25 item 1): the MS5611 has no output rate. It converts when the host
commands it, and each conversion runs on the chip's internal oscillator: its time is the
datasheet's typical time for the OSR x 1 / (1 + ``oscillator_error``). The datasheet's
minimum and maximum conversion times lie about 10 % either side of the typical one (OSR
4096: 7.40 / 8.22 / 9.04 ms), so the error may be set within +-9 % (default 0). The cadence
of the conversions is the driver's; the instant each D1 (pressure) conversion completes is
recorded (``measured_ns``), so a test can count what the chip produced.

Physics face: a conversion takes the inputs of the instant it starts, which is the
host's convert command: an emulated board hands the chip the truth of each command's
instant as it polls (the datasheet says no more about which instant within the conversion
a result stands for). ``physics.pressure_pa`` and ``physics.temperature_degc``
(defaults 101325 Pa, 20 degC when not simulated) are encoded with the *factory* coefficients by
``emulator_encoding.counts_for`` (a conversion's count alone: ``d1_for``, ``d2_for``),
written from the datasheet independently of the driver's conversion code: corrupting the
PROM changes what a driver reads, not what the sensor element measures, and a wrong fact in
the driver shows as a wrong pressure.

Source of facts: MS5611-01BA03 datasheet (DA5611-01BA03_011) commands, timing and the
"ADC read returns 0" rules; chips.md section 1.
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from dataclasses import dataclass

from imuhal.bus.base import BusKind
from imuhal.core.clock import Clock
from imuhal.core.samples import Quantity
from imuhal.emulation import ChipEmulator
from imuhal_chips.ms5611.commands import (
    PROM_WORDS,
    Measurement,
    decode_command,
)
from imuhal_chips.ms5611.emulator_encoding import (
    PromCoefficients,
    d1_for,
    d2_for,
    prom_with_crc4,
)
from imuhal_chips.ms5611.error_spec import MS5611_ERROR_SPEC

DATASHEET_COEFFICIENTS = (40127, 36924, 23317, 23282, 33464, 28312)
"""C1..C6 of the datasheet's worked example (p.7)."""

DEFAULT_PROM_WORDS: tuple[int, ...] = tuple(
    prom_with_crc4([0x0A5C, *DATASHEET_COEFFICIENTS, 0x7D30])
)
"""Word 0 (factory data) 0x0A5C and serial bits 0x7D3 in word 7 are arbitrary; the CRC
nibble is computed."""

_CONVERSION_NS = {256: 540_000, 512: 1_060_000, 1024: 2_080_000, 2048: 4_130_000,
                  4096: 8_220_000}
"""Typical ADC conversion time per OSR (datasheet p.3), written here, not the driver's table."""
_RELOAD_NS = 2_800_000
"""PROM reload after a reset (datasheet: 2.8 ms)."""
_ADC_FULL = (1 << 24) - 1

DEFAULT_PRESSURE_PA = 101325.0
DEFAULT_TEMPERATURE_DEGC = 20.0


@dataclass
class _Conversion:
    measurement: Measurement
    done_ns: int
    result: int


class MS5611Emulator(ChipEmulator):
    """Register-level stand-in for an MS5611 on I2C or SPI.

    ``prom_words``: the factory PROM (8 words); default: the datasheet coefficients with a
    valid CRC. ``seed`` makes the garbage of overlapping conversions reproducible.
    """

    chip = "ms5611"
    error_spec = MS5611_ERROR_SPEC
    measures_motion = False  # pressure and temperature only: a light truth is enough
    models_stuck_data_ready = True
    """Stuck: a started conversion never finishes (ADC reads during it return 0)."""
    conformance_sweep = True
    min_output_period_s = min(_CONVERSION_NS.values()) / 1e9  # OSR 256
    MAX_OSCILLATOR_ERROR = 0.09
    """The conversion times' spread the datasheet allows (min and max about 10 % off the
    typical time), kept inside."""

    def __init__(
        self,
        clock: Clock | None = None,
        *,
        prom_words: Sequence[int] | None = None,
        seed: int = 0x5611,
    ) -> None:
        super().__init__(clock)
        words = list(DEFAULT_PROM_WORDS if prom_words is None else prom_words)
        if len(words) != PROM_WORDS:
            raise ValueError(f"MS5611 PROM has {PROM_WORDS} words, got {len(words)}")
        self.factory_prom: list[int] = [w & 0xFFFF for w in words]
        """The PROM contents (fault injection edits these; a reset reloads them)."""
        self.coefficients = PromCoefficients.of(self.factory_prom)
        """The sensor element's true calibration, used to encode physics."""
        self._prom: list[int] = list(self.factory_prom)
        self._reload_until_ns = -1
        self._conversion: _Conversion | None = None
        self._result: int | None = None
        """The finished conversion not yet fetched by an ADC read."""
        self._out = b""
        self._rng = random.Random(seed)
        self.resets = 0
        self.conversions_started = 0
        self.aborted_conversions = 0
        self._osr: dict[Measurement, int] = {}
        """The OSR of the latest conversion started, per measurement (D1, D2)."""
        self._oscillator_error = 0.0

    @property
    def oscillator_error(self) -> float:
        """The internal oscillator's frequency error as a fraction (0.02: 2 % fast, each
        conversion 1/1.02 of its typical time); from the next conversion on."""
        return self._oscillator_error

    @oscillator_error.setter
    def oscillator_error(self, fraction: float) -> None:
        limit = self.MAX_OSCILLATOR_ERROR
        if not -limit <= fraction <= limit:
            raise ValueError(f"oscillator_error {fraction} lies outside the datasheet's "
                             f"conversion times (+-{limit:g})")
        self._oscillator_error = fraction

    def conversion_ns(self, osr: int) -> int:
        """How long a conversion at ``osr`` takes on this chip's oscillator (ns)."""
        return round(_CONVERSION_NS[osr] / (1.0 + self._oscillator_error))

    # -- fault injection --------------------------------------------------------------------

    def noise_period_s(self, channel: Quantity) -> float | None:
        """The conversion time of the OSR the latest D1 (pressure) / D2 (temperature)
        conversion used; None before the first, or for other channels."""
        measurement = {Quantity.PRESSURE: Measurement.D1,
                       Quantity.TEMPERATURE: Measurement.D2}.get(channel)
        osr = None if measurement is None else self._osr.get(measurement)
        return None if osr is None else _CONVERSION_NS[osr] / 1e9

    def resolution(self, channel: Quantity) -> float:
        """The compensated output's step: 1 Pa (0.01 mbar) and 0.01 degC."""
        if channel is Quantity.PRESSURE:
            return 1.0
        if channel is Quantity.TEMPERATURE:
            return 0.01
        raise ValueError(f"the MS5611 has no {channel.value} channel")

    def full_scale(self, channel: Quantity) -> float:
        """Upper end of the datasheet range: 120000 Pa (1200 mbar), 85 degC."""
        if channel is Quantity.PRESSURE:
            return 120_000.0
        if channel is Quantity.TEMPERATURE:
            return 85.0
        raise ValueError(f"the MS5611 has no {channel.value} channel")

    def corrupt_prom(self, word: int, bit: int) -> None:
        """Flip ``bit`` of PROM ``word``; the stored CRC4 then no longer matches."""
        self.factory_prom[word] ^= 1 << bit
        self._prom[word] = self.factory_prom[word]

    def fill_prom(self, value: int) -> None:
        """Make every PROM word read ``value`` (0xFFFF: bus floating high; 0x0000: blank)."""
        self.factory_prom = [value & 0xFFFF] * PROM_WORDS
        self._prom = list(self.factory_prom)

    def corrupt_trim(self, rng: random.Random, bits: int = 1) -> str:
        """Flip ``bits`` random bits of the coefficient words C1..C6 (the CRC then fails)."""
        changed = []
        for _ in range(bits):
            word, bit = rng.randint(1, 6), rng.randrange(16)
            self.corrupt_prom(word, bit)
            changed.append(f"C{word} bit {bit}")
        return "PROM " + ", ".join(changed)

    def silent_reset(self) -> None:
        """The chip resets without the driver asking (brown-out, ESD): any running or
        unread conversion is lost and the PROM reloads for 2.8 ms."""
        self._reset()

    # -- bus face ---------------------------------------------------------------------------

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        for byte in write:
            self._command(byte)
        if read_len == 0:
            return b""
        data, self._out = self._out[:read_len], self._out[read_len:]
        return data + bytes(read_len - len(data))

    def _reloading(self) -> bool:
        return self.now_ns() < self._reload_until_ns

    def _command(self, byte: int) -> None:
        decoded = decode_command(byte)
        if decoded.action == "reset":
            self._reset()
            return
        if self._reloading():
            self._out = b""
            return
        if decoded.action == "adc_read":
            self._out = self._adc_read().to_bytes(3, "big")
        elif decoded.action == "prom_read":
            assert decoded.word is not None
            self._out = self._prom[decoded.word].to_bytes(2, "big")
        elif decoded.action == "convert":
            assert decoded.measurement is not None and decoded.osr is not None
            self._start_conversion(decoded.measurement, decoded.osr)
        else:
            self._out = b""

    def _reset(self) -> None:
        self.resets += 1
        if self._conversion is not None:
            self.aborted_conversions += 1
        self._conversion = None
        self._result = None
        self._out = b""
        self._prom = list(self.factory_prom)
        self._reload_until_ns = self.now_ns() + _RELOAD_NS

    def _start_conversion(self, measurement: Measurement, osr: int) -> None:
        now = self.now_ns()
        self._settle(now)
        self.conversions_started += 1
        self._osr[measurement] = osr
        span = self.conversion_ns(osr)
        if self._conversion is not None:
            # Overlapping conversions: the running one is lost, the new one is garbage.
            self.aborted_conversions += 1
            result = self._rng.randint(1, _ADC_FULL)
        else:
            result = self._measure(measurement)
        self._result = None
        self._conversion = _Conversion(measurement, now + span, result)

    def _measure(self, measurement: Measurement) -> int:
        """The count of ``measurement`` for the inputs standing (only that one worked out:
        a temperature conversion has no use for D1)."""
        physics = self.physics
        t = physics.temperature_degc
        t = DEFAULT_TEMPERATURE_DEGC if t is None else t
        if measurement is not Measurement.D1:
            return d2_for(self.coefficients, t)
        p = physics.pressure_pa
        return d1_for(self.coefficients, DEFAULT_PRESSURE_PA if p is None else p, t)

    def _settle(self, now: int) -> None:
        """Move a conversion that has finished by ``now`` into the result register."""
        if self.stuck_data_ready:
            return
        conversion = self._conversion
        if conversion is not None and now >= conversion.done_ns:
            self._result = conversion.result
            self._conversion = None
            if conversion.measurement is Measurement.D1:
                self.record_measurements(conversion.done_ns, 0, 1)

    def _adc_read(self) -> int:
        self._settle(self.now_ns())
        if self._conversion is not None:
            # Read during a conversion: returns 0 and corrupts (here: aborts) it.
            self._conversion = None
            self.aborted_conversions += 1
            return 0
        result, self._result = self._result, None
        return 0 if result is None else result

    # -- inspection for tests ---------------------------------------------------------------

    @property
    def running(self) -> Measurement | None:
        """The conversion running at the current clock time, if any."""
        self._settle(self.now_ns())
        return None if self._conversion is None else self._conversion.measurement

    @property
    def converting(self) -> bool:
        """True while a conversion is running at the current clock time."""
        return self.running is not None

    @property
    def reloading(self) -> bool:
        """True while the PROM reload after a reset is in progress."""
        return self._reloading()
