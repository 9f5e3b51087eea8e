"""MPU-9250 emulator: register file, sample timing, bypass and I2C master, fed by physics.

Bus face (I2C: first written byte is the register pointer, further bytes go to successive
registers; SPI: bit 7 of the first byte set = read; both auto-increment):
- A read with no register byte (I2C) continues from the register pointer, which every read
  advances byte by byte (auto-increment), so a driver that writes the register in one
  transaction and reads in the next gets that register.
- Power-on defaults (PWR_MGMT_1 0x01, WHO_AM_I 0x71, the rest 0x00); PWR_MGMT_1.H_RESET
  restores them and self-clears; read-only registers (WHO_AM_I, INT_STATUS, sensor and
  EXT_SENS_DATA, I2C_MST_STATUS, I2C_SLV4_DI) ignore writes.
- Samples are taken every 1 / SAMPLE_RATE on ``self.clock`` (internal rate 1 kHz or 8 kHz or
  32 kHz by DLPF_CFG / Fchoice_b, divided by 1 + SMPLRT_DIV where it applies, all times
  1 + ``oscillator_error``: the chip's own clock), at instants counted from the last
  sampling restart; the newest sample due is latched with the physics of its own instant
  (``pull_physics``: an emulated board hands over the truth of that instant), so the truth
  behind every sample is known exactly whenever the host reads it. Each latches the
  physics into ACCEL/TEMP/GYRO_OUT (big-endian, clipped at the 16-bit limits) and sets
  INT_STATUS.RAW_DATA_RDY_INT when INT_ENABLE.RAW_RDY_EN is set. INT_STATUS clears when
  read (on any read with INT_PIN_CFG.INT_ANYRD_2CLEAR). No samples while SLEEP is set.
- Auxiliary bus ``child_buses()["aux"]`` (an EmulatedBus; attach the AK8963 emulator at 0x0C):
  * bypass: :meth:`connect_bypass` puts gates on the host bus that forward to the aux bus
    while INT_PIN_CFG.BYPASS_EN = 1 and USER_CTRL.I2C_MST_EN = 0, and NACK otherwise;
  * master (USER_CTRL.I2C_MST_EN): writing I2C_SLV4_CTRL with EN performs one single-byte
    transaction on the aux bus, which completes 100 us later (I2C_MST_STATUS.SLV4_DONE, DI
    valid; SLV4_NACK if nobody answered). I2C_MST_STATUS clears when read. Slave 0, when
    enabled for reading (I2C_SLV0_ADDR bit 7 set), copies LENG bytes into EXT_SENS_DATA at
    every sample (BYTE_SW/GRP swap the bytes of each register pair); enabled for writing
    (bit 7 clear), it writes I2C_SLV0_DO to I2C_SLV0_REG of the slave at every sample.
    I2C_SLV0_CTRL.REG_DIS drops the register byte from either transaction. With
    I2C_MST_DELAY_CTRL.I2C_SLV0_DLY_EN slave 0 runs only at every (1 + I2C_MST_DLY)-th
    sample (I2C_SLV4_CTRL[4:0]; register map rev 1.4, I2C_MST_DELAY_CTRL: the facts name the
    register, not its bits); clear (the power-on default), at every sample. A slave-0
    transaction that fails (no acknowledge: a NACK, or a bus or I/O error on the aux wire,
    never an error on the host's bus) sets I2C_MST_STATUS.I2C_SLV0_NACK and leaves
    EXT_SENS_DATA as it was. Slave 0's transactions take place at the sample's own instant
    (``EmulatedBus.transfer_at``): a slave with a clock of its own answers with what it had
    measured by then, also for samples a FIFO catches up on after a host stall. The copy is
    made within the sample, before RAW_DATA_RDY is set: what
    I2C_MST_CTRL.WAIT_FOR_ES guarantees (without it a real chip may raise data-ready before
    the copy; not modelled).

Physics face (sensor frame, SI): ``specific_force_m_s2`` (default (0, 0, 9.80665): lying
flat, face up), ``angular_rate_rad_s`` (default 0), ``temperature_degc`` (default 25).

INT pin (:meth:`MPU9250Emulator.interrupt_after`, register map rev 1.4, INT_PIN_CFG and
INT_ENABLE): asserted at every sample with INT_ENABLE.RAW_RDY_EN (not while
``stuck_data_ready``) and at every sample that overflows a streaming FIFO with
FIFO_OFLOW_EN; active high unless INT_PIN_CFG.ACTL; a 50 us pulse unless
INT_PIN_CFG.LATCH_INT_EN, which holds it until INT_STATUS is cleared (no new edge before).

FIFO: :mod:`imuhal_chips.mpu9250.emulator_fifo` (FIFO_EN incl. slave 0's EXT_SENS_DATA
bytes, FIFO_COUNT, FIFO_R_W, CONFIG.FIFO_MODE, FIFO_OFLOW status, USER_CTRL.FIFO_RST); with
it streaming, every sample is latched with its own instant's inputs and appended.

Faults: ``who_am_i`` (clone: 0x70 MPU-6500, 0x73 MPU-9255), ``stuck_data_ready`` (RAW_RDY
never set), ``silent_reset()``, ``absent`` and bus errors through the bus.

Source of facts: MPU-9250 Register Map RM-MPU-9250A-00 rev 1.4; imuhal shared facts sect. 4.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence

from imuhal.bus.base import BusKind
from imuhal.core.clock import Clock
from imuhal.core.errors import BusError, NackError
from imuhal.core.samples import Quantity
from imuhal.emulation import ChipEmulator, DisturbedLowPass, EmulatedBus, world_counts
from imuhal_chips.mpu9250 import registers as r
from imuhal_chips.mpu9250.emulator_fifo import FifoModel, frame_of
from imuhal_chips.mpu9250.emulator_int import INT_ACTL, INT_LATCH_INT_EN, INT_PULSE_NS
from imuhal_chips.mpu9250.error_spec import MPU9250_ERROR_SPEC

_FIFO_CATCH_UP_SAMPLES = r.FIFO_SIZE_BYTES
"""At most this many samples are pushed at one catch-up (a FIFO holds 512 bytes: any
frame holds at least one, so older samples could not survive)."""

SLV4_TRANSACTION_S = 100e-6
"""A single-byte transaction at 400 kHz, address + register + data with (re)starts."""

_READ_ONLY = {r.WHO_AM_I, r.INT_STATUS, r.I2C_MST_STATUS, r.I2C_SLV4_DI, 0x72, 0x73,
              *range(r.ACCEL_XOUT_H, r.EXT_SENS_DATA_00 + 24)}
# Conversion facts written here from the register map (GYRO_CONFIG / ACCEL_CONFIG FS_SEL
# and the product specification's sensitivity table), never taken from the driver's range
# tables, so a wrong sensitivity in the driver shows as a wrong rate or force.
_GYRO_LSB_PER_DPS_BY_FS_SEL = (131.0, 65.5, 32.8, 16.4)
_ACCEL_LSB_PER_G_BY_FS_SEL = (16384.0, 8192.0, 4096.0, 2048.0)
# Low-pass filter 3 dB bandwidths (Hz) from the register map's CONFIG and ACCEL_CONFIG2
# tables: gyro by DLPF_CFG (Fchoice_b 00), or by Fchoice_b (x1: 8800, 10: 3600) when it
# bypasses the filter; accelerometer by A_DLPF_CFG, or 1130 Hz with accel_fchoice_b set.
_GYRO_BANDWIDTH_HZ_BY_DLPF_CFG = (250.0, 184.0, 92.0, 41.0, 20.0, 10.0, 5.0, 3600.0)
_GYRO_BYPASS_BANDWIDTH_HZ = {0b01: 8800.0, 0b10: 3600.0, 0b11: 8800.0}
_ACCEL_BANDWIDTH_HZ_BY_A_DLPF_CFG = (218.1, 218.1, 99.0, 44.8, 21.2, 10.2, 5.05, 420.0)
_ACCEL_BYPASS_BANDWIDTH_HZ = 1130.0
_TEMP_LSB_PER_DEGC = 333.87
_TEMP_ROOM_DEGC = 21.0
"""TEMP_degC = TEMP_OUT / 333.87 + 21 (RoomTemp_Offset 0)."""
_G_M_S2 = 9.80665
_INSIDE = -32768
"""The lowest int16 word: an output word above it and below 32767 is not at a rail."""
_I2C_MST_DLY = 0x1F
"""I2C_SLV4_CTRL[4:0]: a delayed slave is accessed every 1 + I2C_MST_DLY samples."""


class MPU9250Emulator(ChipEmulator):
    """Register-level stand-in for an MPU-9250 (accel, gyro, temperature, aux I2C)."""

    chip = "mpu9250"
    error_spec = MPU9250_ERROR_SPEC
    models_stuck_data_ready = True
    models_interrupt = True
    pulls_physics = True
    conformance_sweep = True
    min_output_period_s = 1.0 / 32_000.0  # Fchoice_b != 00: 32 kHz

    def __init__(self, clock: Clock | None = None, *, name: str = "mpu9250") -> None:
        super().__init__(clock)
        self.who_am_i = r.WHO_AM_I_MPU9250
        self._oscillator_error = 0.0
        self.stuck_data_ready = False
        self.resets = 0
        self.aux_bus = EmulatedBus(f"{name}.aux", BusKind.I2C)
        self._pointer = 0
        self._reset()

    # -- fault injection --------------------------------------------------------------------

    def silent_reset(self) -> None:
        """The chip resets on its own (brown-out): every register back to its default."""
        self.resets += 1
        self._reset()

    # -- composition ------------------------------------------------------------------------

    def child_buses(self) -> dict[str, EmulatedBus]:
        return {"aux": self.aux_bus}

    def connect_bypass(self, host_bus: EmulatedBus) -> None:
        """Make the chips now attached to the aux bus answer on ``host_bus`` while bypass is
        on (the MPU-9250's aux pins joined to the host I2C bus)."""
        for target in self.aux_bus.targets:
            host_bus.attach(target, _BypassGate(self, target))

    def connect_host(self, host_bus: EmulatedBus) -> None:
        """On an I2C host bus the bypass switch can join the aux bus to it."""
        if host_bus.kind is BusKind.I2C:
            self.connect_bypass(host_bus)

    def bypass_active(self) -> bool:
        return bool(self._regs[r.INT_PIN_CFG] & r.INT_PIN_BYPASS_EN) and not (
            self._regs[r.USER_CTRL] & r.USER_I2C_MST_EN)

    # -- INT pin ------------------------------------------------------------------------

    def interrupt_pin(self) -> tuple[bool, int]:
        """Active high unless INT_PIN_CFG.ACTL; a 50 us pulse unless LATCH_INT_EN."""
        cfg = self._regs[r.INT_PIN_CFG]
        return not cfg & INT_ACTL, 0 if cfg & INT_LATCH_INT_EN else INT_PULSE_NS

    def interrupt_after(self, after_ns: int) -> int | None:
        """The first sample instant after ``after_ns`` at which an enabled interrupt
        asserts the pin: data ready (every sample), FIFO overflow (the samples that find
        the FIFO full); a latched pin still held by an uncleared status asserts nothing."""
        self._advance()
        regs = self._regs
        enable = regs[r.INT_ENABLE] & (r.INT_RAW_RDY | r.INT_FIFO_OFLOW)
        if self.absent or regs[r.PWR_MGMT_1] & r.PWR1_SLEEP or not enable:
            return None
        if regs[r.INT_PIN_CFG] & INT_LATCH_INT_EN and regs[r.INT_STATUS] & enable:
            return None
        period = self.period_ns()
        k = max(0, (after_ns - self._t0) // period) + 1
        if enable & r.INT_RAW_RDY and not self.stuck_data_ready:
            return self._t0 + k * period
        if enable & r.INT_FIFO_OFLOW and self._fifo_streaming():
            room = (self.fifo.size - len(self.fifo)) // len(frame_of(regs))
            return self._t0 + max(k, self._taken + room + 1) * period
        return None

    # -- conformance face -------------------------------------------------------------------

    def _gyro_lsb_per_dps(self) -> float:
        return _GYRO_LSB_PER_DPS_BY_FS_SEL[(self._regs[r.GYRO_CONFIG] >> 3) & 0b11]

    def _accel_lsb_per_g(self) -> float:
        return _ACCEL_LSB_PER_G_BY_FS_SEL[(self._regs[r.ACCEL_CONFIG] >> 3) & 0b11]

    def noise_period_s(self, channel: Quantity) -> float | None:
        """Accel, gyro and temperature are sampled together every :meth:`period_ns`;
        None while the chip sleeps (it outputs nothing at any rate)."""
        if self._regs[r.PWR_MGMT_1] & r.PWR1_SLEEP:
            return None
        if channel in (Quantity.ACCEL, Quantity.GYRO, Quantity.TEMPERATURE):
            return self.period_ns() / 1e9
        return None

    def noise_bandwidth_hz(self, channel: Quantity) -> float | None:
        """The 3 dB bandwidth of the low-pass filter the register map gives for the gyro
        (Fchoice_b in GYRO_CONFIG, DLPF_CFG in CONFIG; temperature shares its path) and the
        accelerometer (accel_fchoice_b and A_DLPF_CFG in ACCEL_CONFIG2)."""
        if channel in (Quantity.GYRO, Quantity.TEMPERATURE):
            fchoice_b = self._regs[r.GYRO_CONFIG] & 0b11
            if fchoice_b:
                return _GYRO_BYPASS_BANDWIDTH_HZ[fchoice_b]
            return _GYRO_BANDWIDTH_HZ_BY_DLPF_CFG[self._regs[r.CONFIG] & 0b111]
        if channel is Quantity.ACCEL:
            cfg2 = self._regs[r.ACCEL_CONFIG2]
            if cfg2 & 0b1000:
                return _ACCEL_BYPASS_BANDWIDTH_HZ
            return _ACCEL_BANDWIDTH_HZ_BY_A_DLPF_CFG[cfg2 & 0b111]
        return None

    def resolution(self, channel: Quantity) -> float:
        """One LSB in SI units at the current ranges."""
        if channel is Quantity.ACCEL:
            return _G_M_S2 / self._accel_lsb_per_g()
        if channel is Quantity.GYRO:
            return math.radians(1.0) / self._gyro_lsb_per_dps()
        if channel is Quantity.TEMPERATURE:
            return 1.0 / _TEMP_LSB_PER_DEGC
        raise ValueError(f"the MPU-9250 has no {channel.value} channel")

    def full_scale(self, channel: Quantity) -> float:
        """The largest magnitude representable (32767 counts) in SI units."""
        if channel is Quantity.TEMPERATURE:
            return 32767 / _TEMP_LSB_PER_DEGC + _TEMP_ROOM_DEGC
        return 32767 * self.resolution(channel)

    # -- state ------------------------------------------------------------------------------

    def _reset(self) -> None:
        self.fifo = FifoModel()
        self._lowpass = {Quantity.ACCEL: DisturbedLowPass(), Quantity.GYRO: DisturbedLowPass()}
        """Per channel: its DLPF on what a value fault changed in the ADC's words
        (imuhal.sim.lowpass; restarted by every reset)."""
        self._regs = bytearray(128)
        self._regs[r.PWR_MGMT_1] = r.PWR1_CLKSEL_AUTO
        self._slv4_done_ns: int | None = None
        self._slv4_result: tuple[int, int] = (0, 0)
        self._restart_sampling()

    def _restart_sampling(self) -> None:
        self._t0 = self.now_ns()
        self._taken = 0

    @property
    def oscillator_error(self) -> float:
        """The chip's clock frequency error as a fraction (0.02: 2 % fast, every sample
        period 1/1.02 of the register map's). Issue 25 asks emulated chips for up to
        +-2 %; the MPU-9250's own tolerance is not in imuhal's chip facts, so the default
        is 0 and a test or script sets it. A change takes effect from the next sample on."""
        return self._oscillator_error

    @oscillator_error.setter
    def oscillator_error(self, fraction: float) -> None:
        self.checked_oscillator_error(fraction)
        # keep the samples already due where they were: count on from the latest one
        self._advance()
        self._t0 += self._taken * self.period_ns()
        self._taken = 0
        self._oscillator_error = fraction

    def period_ns(self) -> int:
        """The sample period the register map gives for CONFIG, GYRO_CONFIG and SMPLRT_DIV:
        Fchoice_b != 00 runs at 32 kHz; DLPF_CFG 0 and 7 at 8 kHz; DLPF_CFG 1..6 at 1 kHz,
        divided by 1 + SMPLRT_DIV (the divider applies only there)."""
        dlpf = self._regs[r.CONFIG] & 0b111
        if self._regs[r.GYRO_CONFIG] & 0b11:
            rate = 32_000.0
        elif dlpf in (0, 7):
            rate = 8_000.0
        else:
            rate = 1_000.0 / (1 + self._regs[r.SMPLRT_DIV])
        return round(1e9 / (rate * (1.0 + self._oscillator_error)))

    def _advance(self) -> None:
        now = self.now_ns()
        if self._slv4_done_ns is not None and now >= self._slv4_done_ns:
            self._slv4_done_ns = None
            di, status = self._slv4_result
            self._regs[r.I2C_SLV4_DI] = di
            self._regs[r.I2C_MST_STATUS] |= status
            self._regs[r.I2C_SLV4_CTRL] &= ~r.SLV_EN
        if self._regs[r.PWR_MGMT_1] & r.PWR1_SLEEP:
            return
        period = self.period_ns()
        due = (now - self._t0) // period
        if due <= self._taken:
            return
        if self._regs[r.INT_ENABLE] & r.INT_RAW_RDY:
            # the samples the driver's data-ready stream announces, latched or not
            self.record_measurements(self._t0 + (self._taken + 1) * period, period,
                                     due - self._taken)
        if self._fifo_streaming():
            # every sample goes into the FIFO, each with its own instant's inputs; more
            # than a FIFO's worth at once: the older ones would be overwritten anyway
            first = max(self._taken + 1, due - _FIFO_CATCH_UP_SAMPLES + 1)
            if first > self._taken + 1:
                self._fifo_overflowed()
            for k in range(first, due + 1):
                self.pull_physics(self._t0 + k * period)
                self._taken = k
                self._latch()
                frame = frame_of(self._regs)
                if self.fifo.push(frame, stop_when_full=bool(
                        self._regs[r.CONFIG] & r.CONFIG_FIFO_MODE)):
                    self._fifo_overflowed()
            return
        # the newest sample is the one measured at its own instant, with that
        # instant's inputs (an emulated board hands them over when asked)
        self.pull_physics(self._t0 + due * period)
        self._taken = due
        self._latch()

    def _fifo_streaming(self) -> bool:
        return bool(self._regs[r.USER_CTRL] & r.USER_FIFO_EN and self._regs[r.FIFO_EN])

    def _fifo_overflowed(self) -> None:
        if self._regs[r.INT_ENABLE] & r.INT_FIFO_OFLOW:
            self._regs[r.INT_STATUS] |= r.INT_FIFO_OFLOW

    def _latch(self) -> None:
        p = self.physics
        force = p.specific_force_m_s2 or (0.0, 0.0, _G_M_S2)
        rate = p.angular_rate_rad_s or (0.0, 0.0, 0.0)
        temp = 25.0 if p.temperature_degc is None else p.temperature_degc
        a_lsb = self._accel_lsb_per_g() / _G_M_S2
        g_lsb = self._gyro_lsb_per_dps() / math.radians(1.0)
        counts = [*(v * a_lsb for v in force),
                  (temp - _TEMP_ROOM_DEGC) * _TEMP_LSB_PER_DEGC,
                  *(v * g_lsb for v in rate)]
        clipped = [max(-32768, min(32767, round(c))) for c in counts]
        lowpass = self._lowpass
        clean = self.undisturbed
        # the ADC cut a word at its rail, a value fault replaced the input, or the filter
        # still carries either: the channel's residual runs through its DLPF
        if clean is not None or lowpass[Quantity.ACCEL].active \
                or not _INSIDE < min(clipped[0:3]) <= max(clipped[0:3]) < 32767:
            clipped[0:3] = self._filtered(
                Quantity.ACCEL, clipped[0:3],
                force if clean is None else clean.specific_force_m_s2 or force, a_lsb)
        if clean is not None or lowpass[Quantity.GYRO].active \
                or not _INSIDE < min(clipped[4:7]) <= max(clipped[4:7]) < 32767:
            clipped[4:7] = self._filtered(
                Quantity.GYRO, clipped[4:7],
                rate if clean is None else clean.angular_rate_rad_s or rate, g_lsb)
        self._regs[r.ACCEL_XOUT_H:r.ACCEL_XOUT_H + 14] = struct.pack(">7h", *clipped)
        if self._regs[r.INT_ENABLE] & r.INT_RAW_RDY and not self.stuck_data_ready:
            self._regs[r.INT_STATUS] |= r.INT_RAW_RDY
        self._slave0()

    def _filtered(self, channel: Quantity, words: list[int], world: Sequence[float],
                  per_unit: float) -> tuple[int, int, int]:
        """``channel``'s output words when its ADC words (``words``, cut at the rail) differ
        from what ``world`` (SI: the chip's input without a rail or a value fault) makes of
        them, or its DLPF still carries such a difference: the world's words plus what the
        filter carries (imuhal.sim.lowpass), at the bandwidth and sample period the
        registers select; ``per_unit``: counts per SI unit."""
        bandwidth = self.noise_bandwidth_hz(channel)
        x, y, z = words
        if bandwidth is None:
            return x, y, z
        counts = world_counts(world, 1.0 / per_unit, 32767)
        t_ns = self.physics_t_ns if self.physics_t_ns is not None else self.now_ns()
        return self._lowpass[channel].output(t_ns, counts, (x, y, z), bandwidth,
                                             self.period_ns() / 1e9, -32768, 32767)

    def _master_on(self) -> bool:
        return bool(self._regs[r.USER_CTRL] & r.USER_I2C_MST_EN)

    def _slave0(self) -> None:
        """Slave 0's transaction of this sample: a write of I2C_SLV0_DO or a read of LENG
        bytes into EXT_SENS_DATA, as I2C_SLV0_ADDR bit 7 says."""
        ctrl = self._regs[r.I2C_SLV0_CTRL]
        address = self._regs[r.I2C_SLV0_ADDR]
        if not (self._master_on() and ctrl & r.SLV_EN):
            return
        if self._regs[r.I2C_MST_DELAY_CTRL] & r.SLV0_DLY_EN:
            every = 1 + (self._regs[r.I2C_SLV4_CTRL] & _I2C_MST_DLY)
            if self._taken % every:
                return
        register = self._regs[r.I2C_SLV0_REG]
        prefix = b"" if ctrl & r.SLV_REG_DIS else bytes([register])
        # the slave answers as at this sample's own instant (a FIFO catch-up runs late)
        instant = self._t0 + self._taken * self.period_ns()
        if not address & r.SLV_READ:
            try:
                self.aux_bus.transfer_at(instant, address & 0x7F,
                                         prefix + bytes([self._regs[r.I2C_SLV0_DO]]), 0)
            except (BusError, OSError):  # an I/O error on the aux wire: no ACK
                self._regs[r.I2C_MST_STATUS] |= r.MST_SLV0_NACK
            return
        length = ctrl & r.SLV_LENG
        if not length:
            return
        try:
            data = bytearray(self.aux_bus.transfer_at(instant, address & 0x7F, prefix, length))
        except (BusError, OSError):
            self._regs[r.I2C_MST_STATUS] |= r.MST_SLV0_NACK
            return
        if ctrl & r.SLV_BYTE_SW:
            # Pairs end on an odd slave register (GRP=0) or on an even one (GRP=1).
            first = 0 if (register % 2 == 0) != bool(ctrl & r.SLV_GRP) else 1
            for i in range(first, length - 1, 2):
                data[i], data[i + 1] = data[i + 1], data[i]
        start = r.EXT_SENS_DATA_00
        self._regs[start:start + length] = data

    def _slv4_start(self) -> None:
        address = self._regs[r.I2C_SLV4_ADDR]
        register = self._regs[r.I2C_SLV4_REG]
        if not self._master_on() or self._regs[r.PWR_MGMT_1] & r.PWR1_SLEEP:
            return  # the master is off: the transaction never runs, DONE never comes
        target = address & 0x7F
        try:
            if address & r.SLV_READ:
                di = self.aux_bus.transfer(target, bytes([register]), 1)[0]
            else:
                self.aux_bus.transfer(target, bytes([register, self._regs[r.I2C_SLV4_DO]]), 0)
                di = self._regs[r.I2C_SLV4_DI]
            self._slv4_result = (di, r.MST_SLV4_DONE)
        except NackError:
            self._slv4_result = (self._regs[r.I2C_SLV4_DI], r.MST_SLV4_NACK | r.MST_SLV4_DONE)
        except (BusError, OSError):
            self._slv4_result = (0xFF, r.MST_SLV4_DONE)  # a glitch: garbage data
        self._slv4_done_ns = self.now_ns() + round(SLV4_TRANSACTION_S * 1e9)

    # -- bus face ---------------------------------------------------------------------------

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        self._advance()
        if not write and kind is BusKind.SPI:
            return bytes(read_len)  # no address byte: nothing is clocked out of the chip
        if write:
            self._pointer = write[0] & 0x7F
            if not (kind is BusKind.SPI and write[0] & r.SPI_READ):
                for offset, value in enumerate(write[1:]):
                    self._write((self._pointer + offset) & 0x7F, value)
        out = bytearray()
        for _ in range(read_len):
            out.append(self._read(self._pointer))
            if self._pointer != r.FIFO_R_W:  # a burst from FIFO_R_W pops the FIFO
                self._pointer = (self._pointer + 1) & 0x7F
        if read_len and self._regs[r.INT_PIN_CFG] & r.INT_PIN_ANYRD_2CLEAR:
            self._regs[r.INT_STATUS] = 0
        return bytes(out)

    def _read(self, address: int) -> int:
        if address == r.WHO_AM_I:
            return self.who_am_i
        if address == r.FIFO_R_W:
            return self.fifo.pop()
        if address in (r.FIFO_COUNTH, r.FIFO_COUNTH + 1):
            return self.fifo.count_registers()[address - r.FIFO_COUNTH]
        value = self._regs[address]
        if address in (r.INT_STATUS, r.I2C_MST_STATUS):
            self._regs[address] = 0  # read to clear
        return value

    def _write(self, address: int, value: int) -> None:
        if address in _READ_ONLY:
            return
        if address == r.PWR_MGMT_1:
            if value & r.PWR1_H_RESET:
                self.resets += 1
                self._reset()
                return
            was_asleep = self._regs[address] & r.PWR1_SLEEP
            self._regs[address] = value
            if was_asleep and not value & r.PWR1_SLEEP:
                self._restart_sampling()
            return
        if address == r.USER_CTRL:
            if value & r.USER_FIFO_RST:
                self.fifo.reset()
            value &= ~0x07  # FIFO/I2C master/signal-path resets self-clear
        if address == r.SIGNAL_PATH_RESET:
            value = 0
        self._regs[address] = value
        if address in (r.SMPLRT_DIV, r.CONFIG, r.GYRO_CONFIG):
            self._restart_sampling()
        if address == r.I2C_SLV4_CTRL and value & r.SLV_EN:
            self._slv4_start()


class _BypassGate(ChipEmulator):
    """Stands at an aux-bus address on the host bus; forwards only while bypass is on."""

    def __init__(self, mpu: MPU9250Emulator, target: int) -> None:
        super().__init__(mpu.clock)
        self.mpu = mpu
        self.target = target

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        if not self.mpu.bypass_active():
            raise NackError(f"no device answered at address 0x{self.target:02X} "
                            "(MPU-9250 bypass is off)", target=self.target)
        return self.mpu.aux_bus.transfer(self.target, write, read_len)
