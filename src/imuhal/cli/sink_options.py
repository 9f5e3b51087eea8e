"""The plugin-sink options of ``run``, ``replay`` and ``estimate``: ``--mqtt URL``, ``--sink
NAME`` and ``--sink-set NAME.KEY=VALUE`` (``SinkOptions``, the options model the commands'
own models extend), each sink configured from the profile's ``outputs.NAME`` section under
the command line's settings (docs/outputs.md)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from typing import Any

from imuhal.cli.options import CommandOptions
from imuhal.core.errors import ImuhalError
from imuhal.offline.settings_args import build_settings, parse_set_arguments
from imuhal.plugins.manager import Registry

RUN_DEFAULTS = ("board", "frame")
"""Settings a plugin sink gets from the command when neither the profile's ``outputs`` nor
``--sink-set`` give them: the board's name and the output frame."""


def add_sink_arguments(parser: argparse.ArgumentParser) -> None:
    """``--mqtt``, ``--sink`` and ``--sink-set`` (``SinkOptions``' fields)."""
    parser.add_argument("--mqtt", metavar="URL",
                        help="publish every event to an MQTT broker (mqtt://HOST[:PORT], "
                        "mqtts:// for TLS; credentials in the URL or IMUHAL_MQTT_USERNAME/"
                        "_PASSWORD), queued on disk while it is unreachable; settings in the "
                        "profile's outputs.mqtt or --sink-set mqtt.KEY=VALUE "
                        "(docs/outputs.md)")
    parser.add_argument("--sink", action="append", default=[], metavar="NAME",
                        help="also send every event to the sink a plugin registered as NAME "
                        "(see `imuhal plugins`); repeatable")
    parser.add_argument("--sink-set", action="append", default=[], metavar="NAME.KEY=VALUE",
                        help="a setting of sink NAME (YAML scalar; commas make a list)")


class SinkOptions(CommandOptions):
    """What a command was asked of the plugin sinks (argparse destinations)."""

    mqtt: str | None = None
    sink: tuple[str, ...] = ()
    sink_set: tuple[str, ...] = ()

    def sink_names(self) -> list[str]:
        """The plugin sinks to open: ``--sink`` ones, and ``mqtt`` for ``--mqtt``."""
        mqtt = ["mqtt"] if self.mqtt is not None and "mqtt" not in self.sink else []
        return [*self.sink, *mqtt]

    def sink_given(self) -> dict[str, dict[str, Any]]:
        """Sink settings the command's own flags give (``--mqtt URL``)."""
        return {"mqtt": {"url": self.mqtt}} if self.mqtt is not None else {}

    def sink_option(self) -> str | None:
        """The first plugin-sink option given, as the user wrote it (for a message), or
        None when there is none."""
        if self.mqtt is not None:
            return "--mqtt"
        return f"--sink {self.sink[0]}" if self.sink else None

    def plugin_sinks(self, registry: Registry, *, board: str,
                     outputs: Mapping[str, Mapping[str, Any]], frame: Any) -> list[Any]:
        """The sinks named, each built (and so checked) with its settings: the command's
        own (``--mqtt URL``) over ``--sink-set NAME.KEY=VALUE`` over the profile's
        ``outputs.NAME`` (``outputs``), over ``board`` and ``frame`` (``RUN_DEFAULTS``)."""
        names = self.sink_names()
        per_sink: dict[str, list[str]] = {name: [] for name in names}
        for item in self.sink_set:
            name, dot, rest = item.partition(".")
            if not dot or name not in per_sink:
                raise ImuhalError(f"--sink-set {item!r}: write NAME.KEY=VALUE for a sink "
                                  f"named by --sink (named: {', '.join(names) or 'none'})")
            per_sink[name].append(rest)
        given = self.sink_given()
        run_values = {"board": board, "frame": getattr(frame, "name", frame)}
        out = []
        for name, items in per_sink.items():
            cls = registry.sinks.get(name)
            values = {**outputs.get(name, {}),
                      **parse_set_arguments(items, f"--sink-set {name}."),
                      **given.get(name, {})}
            for key in RUN_DEFAULTS:
                if key in cls.Settings.model_fields and key not in values:
                    values[key] = run_values[key]
            out.append(cls(build_settings(cls.Settings, values, f"sink {name!r}",
                                          flag=f"--sink-set {name}.")))
        return out


def describe_sinks(sinks: Sequence[Any]) -> None:
    """One line per plugin sink that says where its output goes."""
    for sink in sinks:
        describe = getattr(sink, "describe", None)
        if describe is not None:
            print(f"{sink.name}: {describe()}", file=sys.stderr)


def report_sinks(sinks: Sequence[Any]) -> None:
    """The closing counts of the plugin sinks that keep some, as a run's summary words them
    (for a command without a run summary: ``estimate``); after they were closed."""
    for name, counts in sink_counts(sinks).items():
        print(f"{name}: " + ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in counts.items()),
              file=sys.stderr)


def sink_counts(sinks: Sequence[Any]) -> dict[str, dict[str, int]]:
    """The closing counts of the plugin sinks that keep some (``run_counts()``), by name,
    for a run summary (``RunSummary.sinks``); taken after they were closed."""
    return {s.name: s.run_counts() for s in sinks if hasattr(s, "run_counts")}
