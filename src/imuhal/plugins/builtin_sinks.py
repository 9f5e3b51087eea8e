"""Registers the built-in sinks (flight apps, ROS 2 MCAP, MAVLink, MQTT, Foxglove) through the same
hook any plugin uses."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal.sinks.flight.audio import AudioSink
from imuhal.sinks.flight.igc import IgcSink
from imuhal.sinks.flight.sink import FlightSink
from imuhal.sinks.foxglove_live import FoxgloveSink
from imuhal.sinks.mavlink.sink import MavlinkSink
from imuhal.sinks.mqtt import MqttSink
from imuhal.sinks.ros.mcap_sink import McapSink


@hookimpl
def imuhal_register_sinks(register: Registrar) -> None:
    register(FlightSink)
    register(AudioSink)
    register(IgcSink)
    register(McapSink)
    register(MavlinkSink)
    register(MqttSink)  # paho-mqtt (the mqtt extra) is imported only when one is opened
    register(FoxgloveSink)  # foxglove-sdk (the foxglove extra): likewise
