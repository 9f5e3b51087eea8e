"""Chips bound to Linux kernel IIO drivers: a fake sysfs tree and buffer built from the
kernel ABI, read through the ``iio`` bus kind into SI samples."""

from __future__ import annotations

from pathlib import Path

import pytest
from tests.support.driving import poll_until
from tests.support.fake_iio import Element, FakeIIODevice

from imuhal.bus.linux_iio import LinuxIIOBus
from imuhal.bus.recording.recorder import BusRecorder, run_header
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import DeviceNotFoundError, NackError
from imuhal.core.samples import (
    AccelSample,
    GyroSample,
    MagSample,
    PressureSample,
    TemperatureSample,
)
from imuhal.offline.replay import open_replay, replay_pipeline, replay_run
from imuhal.pipeline import CallbackSink, HardwareBoard, Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import parse_profile
from imuhal_chips.iio.driver import IIODriver
from imuhal_chips.iio.scan import layout, parse_scan_type

G_PER_LSB_4G = 0.001196  # inv_mpu6050 reports accel scale in m/s^2 per LSB
RAD_S_PER_LSB = 0.000266316
TEMP_SCALE_MDEGC = 2.941176
TEMP_OFFSET = 12420


def _mpu(sysfs: Path, dev: Path, number: int = 0) -> FakeIIODevice:
    """What inv_mpu6050 exports for an MPU-9250: raw accel, anglvel, temp; a buffer."""
    attributes = {"in_accel_scale": str(G_PER_LSB_4G), "in_anglvel_scale": str(RAD_S_PER_LSB),
                  "in_temp_scale": str(TEMP_SCALE_MDEGC), "in_temp_offset": str(TEMP_OFFSET),
                  "sampling_frequency": "200", "current_timestamp_clock": "realtime"}
    elements = []
    for i, name in enumerate(["in_accel_x", "in_accel_y", "in_accel_z", "in_temp",
                              "in_anglvel_x", "in_anglvel_y", "in_anglvel_z"]):
        attributes[f"{name}_raw"] = "0"
        elements.append(Element(name, i, "be:s16/16>>0", ">h"))
    elements.append(Element("in_voltage0", 7, "le:u12/16>>4", "<H"))  # not ours: disabled
    elements.append(Element("in_timestamp", 8, "le:s64/64>>0", "<q"))
    return FakeIIODevice(sysfs, dev, number, "mpu9250", attributes, elements)


def _bmp280(sysfs: Path, number: int = 1) -> FakeIIODevice:
    """What the bmp280 kernel driver exports: processed pressure (kPa), temp (milli-degC)."""
    return FakeIIODevice(sysfs, sysfs, number, "bmp280",
                         {"in_pressure_input": "100.125", "in_temp_input": "21500",
                          "in_pressure_oversampling_ratio": "16"})


def _driver(bus: LinuxIIOBus, clock: SimulatedClock, **settings: object) -> IIODriver:
    driver = IIODriver(bus.link(0), settings, device="dev", clock=clock)
    driver.identity = driver.probe()
    driver.configure()
    return driver


def test_scan_types_parse_as_the_abi_describes() -> None:
    t = parse_scan_type("be:s12/16>>4")
    assert (t.big_endian, t.kind, t.bits, t.storage_bits, t.shift) == (True, "s", 12, 16, 4)
    assert t.decode(bytes([0xFF, 0xF0])) == -1.0  # 12 valid bits above 4 status bits
    assert parse_scan_type("le:s16/16>>0").decode(b"\x00\x80") == -32768.0
    assert parse_scan_type("le:u24/32>>0").decode(b"\xff\xff\xff\x7f") == 0xFFFFFF
    with pytest.raises(ValueError, match="not an IIO scan type"):
        parse_scan_type("s16/16")


def test_a_scan_aligns_each_element_to_its_size_and_pads_to_the_largest() -> None:
    s16, s64 = parse_scan_type("le:s16/16>>0"), parse_scan_type("le:s64/64>>0")
    placed, size = layout([("in_timestamp", 9, s64), ("in_accel_x", 0, s16),
                           ("in_accel_y", 1, s16), ("in_accel_z", 2, s16)])
    assert [(e.name, e.offset) for e in placed] == [
        ("in_accel_x", 0), ("in_accel_y", 2), ("in_accel_z", 4), ("in_timestamp", 8)]
    assert size == 16


def test_processed_sysfs_values_come_out_in_si_units(tmp_path: Path) -> None:
    _bmp280(tmp_path, number=3)
    clock = SimulatedClock()
    driver = _driver(LinuxIIOBus(tmp_path, tmp_path), clock, name="bmp280", poll_hz=25)
    samples, _ = poll_until(driver, clock, driver.start(0), 100_000_000)
    pressure = [s for s in samples if isinstance(s, PressureSample)]
    temperature = [s for s in samples if isinstance(s, TemperatureSample)]
    assert len(pressure) == len(temperature) == 2  # 25 Hz over 0.1 s, first poll at 40 ms
    assert pressure[0].pressure_pa == pytest.approx(100_125.0)  # kPa -> Pa
    assert temperature[0].temperature_degc == pytest.approx(21.5)  # milli-degC -> degC


def test_raw_values_get_offset_and_scale_and_gauss_become_microtesla(tmp_path: Path) -> None:
    FakeIIODevice(tmp_path, tmp_path, 0, "hmc5883l",
                  {"in_magn_x_raw": "1090", "in_magn_y_raw": "-545", "in_magn_z_raw": "0",
                   "in_magn_x_scale": "0.000917431", "in_magn_y_scale": "0.000917431",
                   "in_magn_z_scale": "0.001020408", "sampling_frequency": "75"})
    clock = SimulatedClock()
    driver = _driver(LinuxIIOBus(tmp_path, tmp_path), clock, name="hmc5883l")
    samples, _ = poll_until(driver, clock, driver.start(0), 20_000_000)
    mag = [s for s in samples if isinstance(s, MagSample)]
    assert mag and mag[0].mag_ut == pytest.approx((100.0, -50.0, 0.0), abs=1e-3)


def test_buffered_scans_decode_with_the_kernels_timestamps(tmp_path: Path) -> None:
    device = _mpu(tmp_path / "sys", tmp_path / "dev")
    clock = SimulatedClock(1_000_000_000)
    driver = _driver(LinuxIIOBus(tmp_path / "sys", tmp_path / "dev"), clock, name="mpu9250",
                     poll_hz=50)
    assert device.read("buffer/enable") == "1"
    assert device.read("current_timestamp_clock") == "monotonic"
    assert [e.name for e in device.enabled()] == [
        "in_accel_x", "in_accel_y", "in_accel_z", "in_temp", "in_anglvel_x", "in_anglvel_y",
        "in_anglvel_z", "in_timestamp"]
    kernel_t0 = 5_000_000_000
    device.push(*({"in_accel_x": 0, "in_accel_y": 100, "in_accel_z": 8192, "in_temp": 1000,
                   "in_anglvel_x": -i, "in_anglvel_y": 0, "in_anglvel_z": 3754,
                   "in_timestamp": kernel_t0 + i * 5_000_000} for i in range(4)))
    next_ns = driver.start(clock.now_ns())
    clock.sleep_until(next_ns)
    samples = driver.poll(clock.now_ns()).samples
    accel = [s for s in samples if isinstance(s, AccelSample)]
    gyro = [s for s in samples if isinstance(s, GyroSample)]
    temp = [s for s in samples if isinstance(s, TemperatureSample)]
    assert len(accel) == len(gyro) == len(temp) == 4
    assert accel[0].accel_m_s2 == pytest.approx((0.0, 0.1196, 8192 * G_PER_LSB_4G))
    assert gyro[3].gyro_rad_s == pytest.approx((-3 * RAD_S_PER_LSB, 0.0, 3754 * RAD_S_PER_LSB))
    assert temp[0].temperature_degc == pytest.approx((1000 + TEMP_OFFSET) * TEMP_SCALE_MDEGC
                                                     / 1000)
    # The kernel's spacing is kept; the newest scan lands at the poll.
    assert [s.t_ns for s in accel] == [next_ns - 15_000_000, next_ns - 10_000_000,
                                       next_ns - 5_000_000, next_ns]
    assert driver.poll(next_ns + 20_000_000).samples == []  # nothing new queued


def test_a_missing_device_names_what_was_found(tmp_path: Path) -> None:
    _bmp280(tmp_path, number=0)
    with pytest.raises(DeviceNotFoundError, match=r"iio:device0=bmp280"):
        _driver(LinuxIIOBus(tmp_path, tmp_path), SimulatedClock(), name="mpu9250")


PROFILE = """
schema_version: 1
name: kernel-board
buses:
  iio: {{kind: iio, sysfs_root: "{root}", dev_root: "{root}"}}
devices:
  baro: {{driver: iio, bus: iio, address: 0, settings: {{name: bmp280, poll_hz: 10}}}}
  mag:
    driver: iio
    bus: iio
    address: 0
    settings: {{name: hmc5883l, poll_hz: 10}}
"""


@pytest.fixture(scope="module")
def full_registry() -> Registry:
    return load_registry()


def test_a_device_that_disappears_is_retried_while_the_others_run_on(
        tmp_path: Path, full_registry: Registry) -> None:
    baro = _bmp280(tmp_path, number=0)
    FakeIIODevice(tmp_path, tmp_path, 1, "hmc5883l",
                  {f"in_magn_{a}_raw": "100" for a in "xyz"} | {"in_magn_scale": "0.001"})
    profile = parse_profile(PROFILE.format(root=tmp_path), "kernel-board.yaml", full_registry)
    board = HardwareBoard({"iio": LinuxIIOBus(tmp_path, tmp_path)}, SimulatedClock())
    pipeline = Pipeline(profile, full_registry, board)
    times: dict[str, list[float]] = {"baro": [], "mag": []}
    for event in pipeline.events(3.0):
        t = event.t_ns / 1e9
        times[event.device].append(t)  # type: ignore[union-attr]
        if t >= 1.0 and baro.folder.exists() and t < 2.0:
            baro.remove()
        elif t >= 2.0 and not baro.folder.exists():
            baro.create()
    gap = [t for t in times["baro"] if 1.15 < t < 2.0]
    assert gap == []  # nothing made up while it was gone
    assert any(t > 2.1 for t in times["baro"])  # back after it reappeared
    assert len(times["mag"]) >= 29  # the other device never stopped
    summary = pipeline.summary()
    assert summary.bus_errors["baro"] >= 1
    assert [w for w in summary.warnings if w.startswith("baro: recovery failed")
            and "expected IIO device named 'bmp280'" in w]


def test_a_kernel_driven_run_records_and_replays_to_the_same_samples(
        tmp_path: Path, full_registry: Registry) -> None:
    sysfs = tmp_path / "sys"
    baro = _bmp280(sysfs, number=0)
    mag = FakeIIODevice(sysfs, sysfs, 1, "hmc5883l",
                        {f"in_magn_{a}_raw": "100" for a in "xyz"} | {"in_magn_scale": "0.001"})
    text = PROFILE.format(root=sysfs)
    profile = parse_profile(text, "kernel-board.yaml", full_registry)
    recorder = BusRecorder(tmp_path / "run.imurec", run_header(text, "kernel-board.yaml",
                                                               emulate=None, seed=None))
    board = HardwareBoard({"iio": LinuxIIOBus(sysfs, sysfs)}, SimulatedClock())
    live: list[str] = []
    pipeline = Pipeline(profile, full_registry, board, recorder=recorder)
    for event in pipeline.events(2.0):
        live.append(repr(event))
        t = event.t_ns / 1e9
        (mag.folder / "in_magn_x_raw").write_text(f"{round(t * 1000)}\n")  # a changing field
        if 0.5 <= t < 1.0 and baro.folder.exists():
            baro.remove()
        elif t >= 1.0 and not baro.folder.exists():
            baro.create()
    recorder.close()
    replayed: list[str] = []
    replay = open_replay(tmp_path / "run.imurec", full_registry)
    replay_run(replay_pipeline(replay, full_registry),
               [CallbackSink(lambda e: replayed.append(repr(e)))])
    assert len(live) > 40
    assert replayed == live


def test_the_documented_kernel_board_profile_is_valid(full_registry: Registry) -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "drivers.md").read_text()
    section = doc.split("## Chips bound to kernel drivers (Linux IIO)", 1)[1]
    example = section.split("```yaml\n", 1)[1].split("```", 1)[0]
    profile = parse_profile("schema_version: 1\nname: kernel-board\n" + example,
                            "docs/drivers.md", full_registry)
    assert {d.driver for d in profile.devices.values()} == {"iio"}
    assert profile.buses["kernel"].kind == "iio"


def test_a_buffered_device_that_goes_and_comes_back_is_reconfigured(tmp_path: Path) -> None:
    device = _mpu(tmp_path / "sys", tmp_path / "dev")
    clock = SimulatedClock()
    driver = _driver(LinuxIIOBus(tmp_path / "sys", tmp_path / "dev"), clock, name="mpu9250")
    device.remove()
    with pytest.raises(NackError, match="no IIO device iio:device0"):
        driver.poll(driver.start(0))
    with pytest.raises(DeviceNotFoundError, match="no IIO devices"):
        driver.recover(0)
    device.create()  # rebound: scan elements disabled, buffer off, as after a fresh probe
    assert device.read("buffer/enable") == "0"
    next_ns = driver.recover(0)
    assert device.read("buffer/enable") == "1" and len(device.enabled()) == 8
    device.push({e.name: 1 for e in device.enabled()})
    samples = driver.poll(next_ns).samples
    assert [type(s).__name__ for s in samples] == ["AccelSample", "GyroSample",
                                                    "TemperatureSample"]


def test_scans_without_timestamps_are_spaced_by_the_sampling_period(tmp_path: Path) -> None:
    elements = [Element(f"in_magn_{a}", i, "le:s16/16>>0", "<h") for i, a in enumerate("xyz")]
    sysfs, dev = tmp_path / "sys", tmp_path / "dev"
    device = FakeIIODevice(sysfs, dev, 0, "hmc5883l",
                           {f"in_magn_{a}_raw": "0" for a in "xyz"}
                           | {"in_magn_scale": "0.001", "sampling_frequency": "75"}, elements)
    clock = SimulatedClock()
    driver = _driver(LinuxIIOBus(sysfs, dev), clock, name="hmc5883l", poll_hz=25)
    device.push(*({"in_magn_x": 10 * i, "in_magn_y": 0, "in_magn_z": -1} for i in range(3)))
    now = driver.start(0)
    samples = driver.poll(now).samples
    assert [s.t_ns for s in samples] == [now - 2 * 13_333_333, now - 13_333_333, now]
    for sample, x_ut in zip(samples, (0.0, 1.0, 2.0), strict=True):
        assert sample.mag_ut == pytest.approx((x_ut, 0.0, -0.1))  # type: ignore[attr-defined]


def test_a_late_poll_does_not_shift_the_kernels_sample_times(tmp_path: Path) -> None:
    device = _mpu(tmp_path / "sys", tmp_path / "dev")
    clock = SimulatedClock()
    driver = _driver(LinuxIIOBus(tmp_path / "sys", tmp_path / "dev"), clock, name="mpu9250")
    scan = {e.name: 0 for e in device.elements}
    device.push(scan | {"in_timestamp": 7_000_000_000})
    first = driver.start(0)
    assert [s.t_ns for s in driver.poll(first).samples] == [first] * 3
    # Two more scans 5 ms apart, read 30 ms after the first poll: 20 ms late.
    device.push(*(scan | {"in_timestamp": 7_000_000_000 + k * 5_000_000} for k in (1, 2)))
    times = sorted({s.t_ns for s in driver.poll(first + 30_000_000).samples})
    assert times == [first + 5_000_000, first + 10_000_000]


def _accel_scans(numbers: list[int], t0_ns: int = 5_000_000_000,
                 period_ns: int = 5_000_000) -> list[dict[str, float]]:
    return [{"in_accel_x": n, "in_accel_y": 0, "in_accel_z": 0, "in_temp": 0,
             "in_anglvel_x": 0, "in_anglvel_y": 0, "in_anglvel_z": 0,
             "in_timestamp": t0_ns + n * period_ns} for n in numbers]


def _buffered_mpu(tmp_path: Path, buffer_length: int) -> tuple[FakeIIODevice, IIODriver, int]:
    """The fake MPU with its buffer length set through the driver; the first poll time."""
    device = _mpu(tmp_path / "sys", tmp_path / "dev")
    clock = SimulatedClock(1_000_000_000)
    driver = _driver(LinuxIIOBus(tmp_path / "sys", tmp_path / "dev"), clock, name="mpu9250",
                     buffer_length=buffer_length)
    return device, driver, driver.start(clock.now_ns())


def test_scans_a_full_kernel_buffer_dropped_are_counted_from_the_time_stamps(
        tmp_path: Path) -> None:
    device, driver, now = _buffered_mpu(tmp_path, 4)
    assert device.read("buffer/length") == "4"
    device.push(*_accel_scans([0, 1, 2, 3]))  # full: scans 4..9 are dropped by the kernel
    assert len(driver.poll(now).samples) == 4 * 3
    device.push(*_accel_scans([10, 11]))
    driver.poll(now + 20_000_000)
    assert (driver.health.buffer_overflows, driver.health.scans_lost) == (1, 6)
    assert driver.health.counts()["scans_lost"] == 6


def test_late_scans_in_a_buffer_that_never_fills_are_not_counted_as_lost(
        tmp_path: Path) -> None:
    device, driver, now = _buffered_mpu(tmp_path, 8)
    scans = _accel_scans([0, 1, 2])
    scans[2]["in_timestamp"] += 9_000_000  # a scan 2.8 periods after the previous one
    device.push(*scans)
    driver.poll(now)
    device.push(*_accel_scans([4, 5]))
    driver.poll(now + 20_000_000)
    assert (driver.health.buffer_overflows, driver.health.scans_lost) == (0, 0)
