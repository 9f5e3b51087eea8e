"""The robot and ground-station outputs of ``run``, ``replay`` and ``estimate``: ``--mcap``
(ROS 2 messages in MCAP) through the sink the ``mcap`` plugin registers, configured from the
board profile (docs/outputs.md)."""

from __future__ import annotations

import argparse
from typing import Any

from imuhal import __version__
from imuhal.plugins.manager import Registry


def add_mcap_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mcap", metavar="FILE.mcap",
                        help="also write ROS 2 messages (sensor_msgs Imu, MagneticField, "
                        "FluidPressure, Temperature, NavSatFix; ENU/FLU) to an MCAP file; "
                        "needs pip install 'imuhal[ros]' (docs/outputs.md)")


def mcap_sink(registry: Registry, path: str, profile: Any) -> Any:
    """The ``mcap`` sink writing ``path``, with the profile's ``ros:`` section and the
    board's name as frame id unless the section names one."""
    ros = profile.ros
    if ros.frame_id is None:
        ros = ros.model_copy(update={"frame_id": profile.name})
    return registry.sinks.get("mcap")({
        "path": path, "ros": ros,
        "metadata": {"board": profile.name, "imuhal_version": __version__,
                     "frames": "REP-103: ENU earth, FLU body; REP-145 topics"}})


def report_mcap(sink: Any, path: str) -> str:
    """The closing line about an MCAP output: messages written, samples left out and why."""
    line = f"wrote {sink.messages} ROS 2 messages to {path}"
    if sink.records.skipped:
        parts = ", ".join(f"{n} {why}" for why, n in sorted(sink.records.skipped.items()))
        line += f" (samples not written: {parts}; a ROS message has no validity flag)"
    return line
