"""``imuhal run``'s options as a validated model: which flags need which others is a table
(``RUN_RULES``), not a chain of ifs in the command."""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

from imuhal.cli.options import Needs
from imuhal.cli.sink_options import SinkOptions


def _emulated(o: RunOptions) -> bool:
    return o.emulated


RUN_RULES = (
    Needs(lambda o: o.samples, lambda o: bool(o.output),
          "--samples writes the samples into the --output log; add --output FILE.csv"),
    Needs(lambda o: o.igc_pilot is not None or o.igc_glider is not None, lambda o: bool(o.igc),
          "--igc-pilot and --igc-glider name who flies in the IGC log; add --igc FILE.IGC "
          "(or a folder)"),
    Needs(lambda o: o.audio_damping is not None or o.audio_sink_alarm is not None,
          lambda o: o.audio or bool(o.audio_wav),
          "--audio-damping and --audio-sink-alarm shape the vario tones; add --audio or "
          "--audio-wav FILE.wav"),
    Needs(lambda o: o.nmea_sentences is not None, lambda o: bool(o.nmea),
          "--nmea-sentences chooses the sentences of an --nmea output; add --nmea OUTPUT "
          "(e.g. --nmea pty)"),
    Needs(lambda o: o.seed is not None, _emulated,
          "--seed seeds the simulated world of an emulated run; add --emulate SCENARIO (or "
          "drop --seed): real hardware has no seed"),
    Needs(lambda o: o.skip_calibration, _emulated,
          "--skip-calibration is for emulated runs (real hardware is never calibrated by "
          "`imuhal run`); drop it, or add --emulate SCENARIO"),
    Needs(lambda o: bool(o.truth), _emulated,
          "--truth needs an emulated run (--emulate SCENARIO): real hardware has no ground "
          "truth"),
)


class RunOptions(SinkOptions):
    """What ``imuhal run`` was asked (argparse destinations, values already typed; the
    plugin sinks' ``--mqtt``, ``--sink`` and ``--sink-set`` in ``SinkOptions``)."""

    RULES: ClassVar[tuple[Needs, ...]] = RUN_RULES

    profile: str | None = None
    emulate: str | None = None
    duration: float | None = None
    """Seconds to run; None: the scenario's length, or until Ctrl-C on hardware."""
    realtime: bool = False
    output: str | None = None
    output_frame: Any = None
    """The ``--output-frame`` convention (imuhal.core.conventions.Convention) or None."""
    samples: bool = False
    truth: str | None = None
    trace: str | None = None
    nmea: tuple[str, ...] = ()
    nmea_sentences: str | None = None
    audio: bool = False
    audio_wav: str | None = None
    audio_damping: float | None = None
    """Seconds."""
    audio_sink_alarm: float | None = None
    """m/s (negative: sinking)."""
    igc: str | None = None
    igc_pilot: str | None = None
    igc_glider: str | None = None
    mcap: str | None = None
    mavlink: str | None = None
    mavlink_imu_hz: float | None = None
    seed: int | None = None
    replay_truth: str | None = None
    record: str | None = None
    skip_calibration: bool = False
    save_learned: str | None = None
    quiet: bool = False
    web: str | None = None

    @property
    def emulated(self) -> bool:
        """An emulated run: ``--emulate``, or no PROFILE (the bundled board flies its
        default scenario); a PROFILE without ``--emulate`` runs on real buses."""
        return self.emulate is not None or self.profile is None

    @property
    def igc_file(self) -> str | None:
        """``--igc`` when it names a file (a folder gets the FAI name at the end of the run,
        so it is no output to check beforehand)."""
        return self.igc if self.igc and not Path(self.igc).is_dir() else None

    def outputs(self) -> dict[str, str | None]:
        """Every file the run may write, by option (checked before anything opens)."""
        return {"--output": self.output, "--truth": self.truth, "--trace": self.trace,
                "--audio-wav": self.audio_wav, "--record": self.record,
                "--igc": self.igc_file, "--mcap": self.mcap,
                "--save-learned": self.save_learned}
