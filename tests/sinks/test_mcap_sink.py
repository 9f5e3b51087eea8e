"""The MCAP sink's file safety: readable while it is written, committed on close, and never
replacing a good file with a failed run's output (imuhal.core.atomic rules)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from imuhal.core.errors import ImuhalError
from imuhal.core.samples import Frame, GyroSample, PressureSample

pytest.importorskip("mcap_ros2", reason="the ros extra (mcap, mcap-ros2-support) is missing")
rosbags_highlevel = pytest.importorskip("rosbags.highlevel", reason="rosbags is not installed")
from imuhal.sinks.ros.mcap_sink import McapSink  # noqa: E402


def _stamps(path: Path, tmp_path: Path) -> list[int]:
    copy = tmp_path / "copy.mcap"  # readers pick the format by the .mcap suffix
    shutil.copyfile(path, copy)
    with rosbags_highlevel.AnyReader([copy]) as reader:
        return [t for _c, t, _raw in reader.messages()]


def _pressure(t_s: float) -> PressureSample:
    return PressureSample(t_ns=round(t_s * 1e9), device="baro", pressure_pa=95000.0)


def test_the_partial_file_is_readable_up_to_the_last_closed_chunk(tmp_path: Path) -> None:
    sink = McapSink({"path": str(tmp_path / "out.mcap"), "chunk_s": 1.0})
    for i in range(26):  # 0.0 .. 2.5 s at 10 Hz
        sink.handle(_pressure(i / 10))
    partial = tmp_path / "out.mcap.partial"
    seen = _stamps(partial, tmp_path)
    # a chunk is closed once it spans chunk_s (here after the messages at 1.0 s and 2.1 s):
    # what a kill now loses is less than chunk_s
    assert seen == [round(i / 10 * 1e9) for i in range(22)]
    sink.close()
    assert not partial.exists()
    assert len(_stamps(tmp_path / "out.mcap", tmp_path)) == 26


def test_a_failed_run_keeps_the_previous_file_and_its_messages_beside_it(
        tmp_path: Path) -> None:
    out = tmp_path / "out.mcap"
    out.write_bytes(b"the previous good file")
    sink = McapSink({"path": str(out)})
    sink.handle(GyroSample(t_ns=1, device="imu", frame=Frame.BODY_NED,
                           gyro_rad_s=(0.0, 0.0, 0.1)))
    partial = sink.abort()
    assert out.read_bytes() == b"the previous good file"
    assert partial == tmp_path / "out.mcap.partial"
    assert _stamps(partial, tmp_path) == [1]  # completed, with the half-pair written


def test_a_device_is_refused_in_one_line() -> None:
    with pytest.raises(ImuhalError, match="needs a regular file"):
        McapSink({"path": "/dev/null"})
