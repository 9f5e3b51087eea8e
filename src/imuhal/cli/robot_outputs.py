"""The robot and ground-station outputs: ``--mcap`` (ROS 2 messages in MCAP; ``run``,
``replay`` and ``estimate``) and ``--mavlink`` (``run``), through the sinks the ``mcap`` and
``mavlink`` plugins register, configured from the board profile (docs/outputs.md)."""

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
    """The ``mcap`` sink writing ``path``, with the profile's ``outputs.mcap`` section and
    the board's name as frame id unless the section names one."""
    ros = profile.outputs.mcap
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


def add_mavlink_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mavlink", metavar="udpout:HOST:PORT",
                        help="also send MAVLink 2 (HEARTBEAT, HIGHRES_IMU, SCALED_PRESSURE, "
                        "ATTITUDE_QUATERNION, GLOBAL_POSITION_INT) to a ground station, e.g. "
                        "udpout:127.0.0.1:14550; needs pip install 'imuhal[mavlink]' "
                        "(docs/outputs.md)")
    parser.add_argument("--mavlink-imu-hz", type=float, metavar="HZ",
                        help="with --mavlink: HIGHRES_IMU rate (default: the profile's "
                        "outputs.mavlink.highres_imu_hz, 50)")


def mavlink_sink(registry: Registry, args: Any, profile: Any) -> Any:
    """The ``mavlink`` sink sending to ``args.mavlink`` with the profile's
    ``outputs.mavlink`` section (its HIGHRES_IMU rate replaced by ``--mavlink-imu-hz``);
    ``args`` has the ``mavlink`` and ``mavlink_imu_hz`` options (an argparse namespace or a
    command's options model)."""
    from imuhal.core.errors import ImuhalError

    settings = profile.outputs.mavlink
    if args.mavlink_imu_hz is not None:
        if not args.mavlink:
            raise ImuhalError("--mavlink-imu-hz sets the rate of a --mavlink output; add "
                              "--mavlink udpout:HOST:PORT")
        if not args.mavlink_imu_hz >= 0:
            raise ImuhalError(f"--mavlink-imu-hz {args.mavlink_imu_hz:g}: give a rate of 0 "
                              "(every gyro sample) or more, e.g. 50")
        settings = settings.model_copy(update={"highres_imu_hz": args.mavlink_imu_hz})
    if not args.mavlink:
        return None
    return registry.sinks.get("mavlink")({"output": args.mavlink, "mavlink": settings})


def report_mavlink(sink: Any, spec: str) -> str:
    """The closing line about a MAVLink output: what was sent, and what the network refused."""
    parts = ", ".join(f"{n} {name}" for name, n in sorted(sink.counts.items()))
    line = f"mavlink: sent {parts or 'nothing'} to {spec}"
    if sink.send_errors:
        line += f" ({sink.send_errors} datagrams refused by the network)"
    if sink.skipped_fixes:
        line += f" ({sink.skipped_fixes} GNSS fixes without a mean-sea-level height not sent)"
    return line
