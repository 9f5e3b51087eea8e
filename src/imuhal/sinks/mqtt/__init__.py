"""MQTT telemetry with store-and-forward (``imuhal run --mqtt URL``; docs/outputs.md)."""

from imuhal.sinks.mqtt.sink import COUNTERS, MqttSettings, MqttSink

__all__ = ["COUNTERS", "MqttSettings", "MqttSink"]
