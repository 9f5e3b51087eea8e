"""``imuhal replay``'s options as a validated model (``REPLAY_RULES``: which flags need which
others), with the plugin sinks' ``--mqtt``, ``--sink`` and ``--sink-set`` from
``SinkOptions``."""

from __future__ import annotations

from typing import ClassVar

from imuhal.cli.options import Needs
from imuhal.cli.sink_options import SinkOptions

REPLAY_RULES = (
    Needs(lambda o: o.samples, lambda o: bool(o.output),
          "--samples writes the samples into the --output log; add --output FILE.csv"),
)


class ReplayOptions(SinkOptions):
    """What ``imuhal replay`` was asked (argparse destinations)."""

    RULES: ClassVar[tuple[Needs, ...]] = REPLAY_RULES

    recording: str
    profile: str | None = None
    output: str | None = None
    samples: bool = False
    mcap: str | None = None
    realtime: bool = False
    quiet: bool = False

    def outputs(self) -> dict[str, str | None]:
        """Every file the replay may write, by option (checked before anything opens)."""
        return {"--output": self.output, "--mcap": self.mcap}
