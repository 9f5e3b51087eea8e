"""Device health on the page: stale and faulty devices are marked, healthy ones are not."""

from __future__ import annotations

from imuhal.core.samples import GyroSample, PressureSample, SampleFlag
from imuhal.live.sink import LiveSink
from imuhal.live.snapshot import Snapshotter


def _feed(sink: LiveSink, t0_s: float, t1_s: float, *, baro: bool = True,
          baro_flags: SampleFlag = SampleFlag.OK) -> None:
    """A 100 Hz gyro and a 50 Hz barometer from ``t0_s`` to ``t1_s``."""
    for i in range(round(t0_s * 100), round(t1_s * 100)):
        t_ns = i * 10_000_000
        sink.handle(GyroSample(t_ns=t_ns, device="imu", gyro_rad_s=(0.0, 0.0, 0.0)))
        if baro and i % 2 == 0:
            sink.handle(PressureSample(t_ns=t_ns, device="baro", pressure_pa=90000.0,
                                       flags=baro_flags))


def test_a_device_that_stops_producing_turns_stale_while_the_others_stay_healthy():
    sink = LiveSink()
    snap = Snapshotter(sink)
    _feed(sink, 0.0, 1.0)
    assert not snap.snapshot()["health"]["baro"]["stale"]
    _feed(sink, 1.0, 2.0, baro=False)
    health = snap.snapshot()["health"]
    assert health["baro"]["stale"] and "no sample for 1.0 s" in health["baro"]["problems"][0]
    assert not health["imu"]["stale"] and not health["imu"]["faulty"]


def test_a_device_whose_samples_are_flagged_is_faulty_with_its_flags_counted_by_kind():
    sink = LiveSink()
    snap = Snapshotter(sink)
    _feed(sink, 0.0, 1.0)
    snap.snapshot()
    _feed(sink, 1.0, 2.0, baro_flags=SampleFlag.STALE | SampleFlag.CRC_ERROR)
    baro = snap.snapshot()["health"]["baro"]
    assert baro["faulty"] and not baro["stale"]
    assert baro["flagged"] == {"STALE": 50, "CRC_ERROR": 50}
    assert baro["achieved_hz"]["pressure"] == 50.0


def test_flagged_samples_never_reach_the_displayed_values():
    sink = LiveSink()
    sink.handle(PressureSample(t_ns=0, device="baro", pressure_pa=90000.0))
    sink.handle(PressureSample(t_ns=1, device="baro", pressure_pa=float("nan"),
                               flags=SampleFlag.NAN))
    entry = Snapshotter(sink).snapshot()["sensors"]["baro"]["pressure"]
    assert entry["value"] == 90000.0 and entry["valid"] is False
