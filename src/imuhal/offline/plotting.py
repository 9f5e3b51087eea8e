"""Figures of a run log (and its truth): the one plotting module every command reuses.

``read_log`` reads the log ``imuhal run --output LOG.csv [--samples]`` writes (long format,
docs/output-csv.md) or the wide output of ``imuhal estimate``; ``plot_log`` draws it with
matplotlib's object API on the Agg canvas (no pyplot, no display needed):

* attitude: roll, pitch, yaw of each attitude source (deg), truth dashed;
* altitude (m) and climb rate (m/s) of each vertical source, truth dashed; the truth altitude
  drawn is its *pressure altitude* (ISA, 101325 Pa reference), which is what a barometric
  estimate measures, so the two share a reference;
* errors (estimate minus truth at the estimate's time, truth interpolated): attitude
  (yaw wrapped to [-180, 180)), altitude, climb;
* angle lines (attitude, truth, attitude error) break where the angle wraps at +/-180 deg
  (a NaN point between the two samples), not a vertical stroke across the panel;
* raw sensors: accelerometer, gyro, magnetometer, pressure per device (body frame NED);
* device health: flagged samples per device and flag, cumulative, and each device's sample
  rate per second (a bus that fails shows as a dip; bus errors flag no sample of their own).

``plot_trial_errors`` draws what ``imuhal evaluate --plot`` shows: each estimator's RMSE per
trial as grouped bars, and its mean over the trials, one panel per DOF and error.

Scripts and benchmarks draw their figures through this module too (tests/test_plotting.py
checks that nothing else imports matplotlib).

matplotlib is an optional extra: ``pip install 'imuhal[plot]'``.
"""

from __future__ import annotations

import csv
import math
import os
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from imuhal.core.atmosphere import altitude_m_from_pressure
from imuhal.core.atomic import AtomicFile
from imuhal.core.errors import ImuhalError
from imuhal.core.samples import SampleFlag
from imuhal.estimation.framed import frame_suffix
from imuhal.offline.run_log import log_frame
from imuhal.sim.truth_csv import read_truth_csv
from imuhal.sinks import Event, event_row

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

FloatArray = np.ndarray

ATTITUDE = ("roll_deg", "pitch_deg", "yaw_deg")
VERTICAL = ("altitude_m", "climb_m_s")
SENSORS = {
    "accel": (("ax_m_s2", "ay_m_s2", "az_m_s2"), "specific force, m/s²"),
    "gyro": (("gx_rad_s", "gy_rad_s", "gz_rad_s"), "angular rate, rad/s"),
    "mag": (("mx_ut", "my_ut", "mz_ut"), "magnetic field, µT"),
    "pressure": (("pressure_pa",), "pressure, Pa"),
}
FIGURE_FORMATS = ("png", "pdf", "svg")


class PlotError(ImuhalError):
    """A log or truth file cannot be plotted, or matplotlib is missing."""


@dataclass
class Series:
    """One source's rows of one kind: times (s) and columns (float arrays, NaN if empty)."""

    t_s: FloatArray
    columns: dict[str, FloatArray]
    flags: FloatArray


@dataclass
class LogData:
    path: Path
    series: dict[tuple[str, str], Series] = field(default_factory=dict)
    """(source, kind) -> series: ("ahrs", "attitude"), ("imu", "gyro"), ..."""
    frame: str = "ned"
    """The convention of the body vectors and attitude (the log's ``output_frame``)."""

    def of_kind(self, kind: str) -> dict[str, Series]:
        return {src: s for (src, k), s in self.series.items() if k == kind}


def read_log(path: str | os.PathLike[str]) -> LogData:
    """A run log (long format) or an ``imuhal estimate`` output (wide, one source)."""
    p = Path(path)
    try:
        with p.open(newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError) as exc:
        raise PlotError(f"{p}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    if not rows:
        raise PlotError(f"{p}: no data rows; give a log of `imuhal run --output LOG.csv`")
    return _log_from_rows(p, rows)


def log_from_events(events: Iterable[Event], label: str = "run") -> LogData:
    """The log of events still in memory (a pipeline's, a script's), as the CSV would hold
    them, so scripts and other commands plot without writing a file first."""
    rows = [{k: v for k, v in event_row(e).items()} for e in events]
    if not rows:
        raise PlotError(f"{label}: no events to plot")
    return _log_from_rows(Path(label), rows)


def _log_from_rows(p: Path, rows: list[dict[str, str]]) -> LogData:
    frame = log_frame(p, list(rows[0]), None)
    sfx = frame_suffix(frame)
    if sfx:  # a log written in another frame: plot its columns under the plain names
        rows = [{(k[: -len(sfx)] if k.endswith(sfx) else k): v for k, v in r.items()}
                for r in rows]
    data = LogData(p, frame=frame.name)
    for key, group in _grouped(p, rows).items():
        names = sorted({n for r in group for n in r} - {"t_s", "source", "kind", "flags"})
        cols = {n: np.array([_num(r.get(n)) for r in group]) for n in names}
        cols = {n: v for n, v in cols.items() if not np.all(np.isnan(v))}
        flags = np.array([_num(r.get("flags")) if r.get("flags") else 0.0 for r in group])
        data.series[key] = Series(np.array([float(r["t_s"]) for r in group]), cols, flags)
    return data


def _grouped(p: Path, rows: list[dict[str, str]]) -> dict[tuple[str, str],
                                                           list[dict[str, str]]]:
    """The rows by (source, kind): a run log's own columns, or the one estimator of an
    ``imuhal estimate`` output (named after the file)."""
    header = set(rows[0])
    if "t_s" not in header:
        raise PlotError(f"{p}: no t_s column; this is not an imuhal log")
    grouped: dict[tuple[str, str], list[dict[str, str]]] = defaultdict(list)
    if {"source", "kind"} <= header:
        for row in rows:
            grouped[(row["source"], row["kind"])].append(row)
        return grouped
    kind = "attitude" if "qw" in header else "vertical" if "altitude_m" in header else ""
    if not kind:
        raise PlotError(f"{p}: neither a run log (source, kind columns) nor estimate "
                        "output (qw or altitude_m columns)")
    grouped[(p.stem, kind)] = rows
    return grouped


def _num(text: str | None) -> float:
    if text is None or not text.strip():
        return math.nan
    try:
        return float(text)
    except ValueError:
        return math.nan


@dataclass
class Truth:
    t_s: FloatArray
    columns: dict[str, FloatArray]


def read_truth(path: str | os.PathLike[str]) -> Truth:
    """A truth CSV (docs/simulation.md) with its pressure altitude as ``pressure_altitude_m``."""
    try:
        cols, _ = read_truth_csv(path)
    except (OSError, ValueError) as exc:  # UnicodeDecodeError is a ValueError
        raise PlotError(f"{path}: cannot read the truth file: {exc}; give a file written by "
                        "`imuhal run --truth FILE.csv`") from None
    if "t_s" not in cols or len(cols["t_s"]) < 2:
        raise PlotError(f"{path}: a truth file needs t_s and at least two rows "
                        "(write one with `imuhal run --truth FILE.csv`)")
    missing = [c for c in (*ATTITUDE, "climb_m_s") if c not in cols]
    if missing:
        raise PlotError(f"{path}: not a truth file: missing column(s) {', '.join(missing)}; "
                        "give a file written by `imuhal run --truth FILE.csv`")
    cols = dict(cols)
    if "pressure_pa" in cols:
        cols["pressure_altitude_m"] = np.array(
            [altitude_m_from_pressure(float(p)) for p in cols["pressure_pa"]])
    return Truth(cols["t_s"], cols)


def _truth_at(truth: Truth, column: str, t_s: FloatArray) -> FloatArray:
    """Truth interpolated at ``t_s`` (NaN outside the truth's span)."""
    values = truth.columns[column]
    if column == "yaw_deg":  # interpolate the unwrapped angle, then wrap again
        values = np.rad2deg(np.unwrap(np.deg2rad(values)))
    out = np.interp(t_s, truth.t_s, values, left=np.nan, right=np.nan)
    return _wrap_deg(out) if column == "yaw_deg" else out


def _wrap_deg(x: FloatArray) -> FloatArray:
    return (x + 180.0) % 360.0 - 180.0


def break_at_wraps(t_s: FloatArray, angle_deg: FloatArray) -> tuple[FloatArray, FloatArray]:
    """An angle series (deg) with a NaN point inserted wherever two consecutive values differ
    by more than 180 deg, so a line crossing +/-180 breaks there instead of being drawn as
    a vertical stroke across the panel; the points themselves are unchanged."""
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(angle_deg, dtype=float)
    wraps = np.flatnonzero(np.abs(np.diff(y)) > 180.0) + 1
    if not len(wraps):
        return t, y
    gap_t = 0.5 * (t[wraps - 1] + t[wraps])
    return np.insert(t, wraps, gap_t), np.insert(y, wraps, np.nan)


def errors(series: Series, truth: Truth, column: str) -> FloatArray:
    """Estimate minus truth at the estimate's times (angles wrapped to [-180, 180))."""
    truth_column = "pressure_altitude_m" if column == "altitude_m" else column
    diff = series.columns[column] - _truth_at(truth, truth_column, series.t_s)
    return _wrap_deg(diff) if column.endswith("_deg") else diff


@dataclass
class LogFigure:
    """A figure and its panels by name (``attitude``, ``altitude``, ``gyro``, ...; for
    :func:`plot_trial_errors` ``9-DOF total``, ...)."""

    figure: Figure
    axes: dict[str, Axes]

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write atomically; the format is the file's extension (png, pdf, svg)."""
        target = check_figure_path(path)
        fmt = target.suffix.lower().lstrip(".")
        out = AtomicFile(target, binary=True)
        try:
            self.figure.savefig(out.file, format=fmt, dpi=100)  # type: ignore[arg-type]  # AtomicFile.file is open until commit or abort, both below
        except BaseException:
            out.abort()
            raise
        return out.commit()


def _figure_class() -> Any:
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise PlotError("plotting needs matplotlib: pip install 'imuhal[plot]'") from None
    return Figure


def check_figure_path(path: str | os.PathLike[str]) -> Path:
    """``path`` if a figure can be written there (known format, matplotlib installed):
    commands check before long work, not after it."""
    target = Path(path)
    fmt = target.suffix.lower().lstrip(".")
    if fmt not in FIGURE_FORMATS:
        raise PlotError(f"{target}: unknown figure format {fmt!r}; name the file "
                        f".{', .'.join(FIGURE_FORMATS)}")
    _figure_class()
    return target


def plot_log(log: LogData, truth: Truth | None = None, *, title: str = "") -> LogFigure:
    """Every panel the log has data for, truth overlaid and errors shown when given."""
    if truth is not None and log.frame != "ned":
        raise PlotError(f"{log.path}: the log is in frame '{log.frame}' but truth files are "
                        "ned; compare with truth a log written in ned (the default)")
    attitude, vertical = log.of_kind("attitude"), log.of_kind("vertical")
    samples = {key: s for key, s in log.series.items() if key[1] not in ("attitude", "vertical")}
    panels = _panels(log, truth, samples)
    if not panels:
        raise PlotError(f"{log.path}: nothing to plot")
    figure = _figure_class()(figsize=(11, 2.3 * len(panels)), layout="constrained")
    grid = figure.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    axes = dict(zip(panels, grid, strict=True))
    frame_note = "" if log.frame == "ned" else f" (body vectors and attitude in {log.frame})"
    figure.suptitle((title or str(log.path)) + frame_note)
    if attitude:
        _attitude(axes, attitude, truth)
    if vertical:
        _vertical(axes, vertical, truth)
    _sensors(axes, log)
    if samples:
        _health(axes["flags"], axes["sample rate"], samples)
    for ax in axes.values():
        if ax.get_lines():
            ax.legend(loc="upper right", fontsize="x-small", ncols=3)
        ax.grid(True, alpha=0.3)
    grid[-1].set_xlabel("time, s")
    return LogFigure(figure, axes)


def _panels(log: LogData, truth: Truth | None,
            samples: dict[tuple[str, str], Series]) -> list[str]:
    """The panels, top to bottom: estimates (and their errors against ``truth``), each
    sensor kind the log has, then the samples' flags and rates."""
    panels: list[str] = []
    if log.of_kind("attitude"):
        panels += ["attitude", "attitude error"] if truth is not None else ["attitude"]
    if log.of_kind("vertical"):
        panels += ["altitude", "climb"] + (["vertical error"] if truth is not None else [])
    panels += [kind for kind in SENSORS if log.of_kind(kind)]
    if samples:
        panels += ["flags", "sample rate"]
    return panels


def _sensors(axes: dict[str, Axes], log: LogData) -> None:
    """Each sensor kind's columns, every source of that kind on one panel."""
    for kind, (columns, label) in SENSORS.items():
        if kind not in axes:
            continue
        ax = axes[kind]
        for src, s in log.of_kind(kind).items():
            for c in columns:
                if c in s.columns:
                    ax.plot(s.t_s, s.columns[c], lw=0.6, label=f"{src} {c}")
        ax.set_ylabel(label)


def _attitude(axes: dict[str, Axes], attitude: dict[str, Series], truth: Truth | None) -> None:
    ax = axes["attitude"]
    for src, s in attitude.items():
        for c in ATTITUDE:
            ax.plot(*break_at_wraps(s.t_s, s.columns[c]), lw=0.8, label=f"{src} {c}")
    ax.set_ylabel("attitude, deg")
    if truth is None:
        return
    for c in ATTITUDE:
        ax.plot(*break_at_wraps(truth.t_s, truth.columns[c]), "--", lw=0.8, color="k",
                label=f"truth {c}")
    err = axes["attitude error"]
    for src, s in attitude.items():
        for c in ATTITUDE:
            err.plot(*break_at_wraps(s.t_s, errors(s, truth, c)), lw=0.8,
                     label=f"{src} {c} error")
    err.set_ylabel("estimate - truth, deg")


def _vertical(axes: dict[str, Axes], vertical: dict[str, Series], truth: Truth | None) -> None:
    alt, climb = axes["altitude"], axes["climb"]
    for src, s in vertical.items():
        alt.plot(s.t_s, s.columns["altitude_m"], lw=0.8, label=f"{src} altitude_m")
        climb.plot(s.t_s, s.columns["climb_m_s"], lw=0.8, label=f"{src} climb_m_s")
    alt.set_ylabel("altitude, m")
    climb.set_ylabel("climb rate, m/s")
    if truth is None:
        return
    if "pressure_altitude_m" in truth.columns:
        alt.plot(truth.t_s, truth.columns["pressure_altitude_m"], "--", color="k", lw=0.8,
                 label="truth pressure altitude")
    climb.plot(truth.t_s, truth.columns["climb_m_s"], "--", color="k", lw=0.8,
               label="truth climb_m_s")
    err = axes["vertical error"]
    for src, s in vertical.items():
        if "pressure_altitude_m" in truth.columns:
            err.plot(s.t_s, errors(s, truth, "altitude_m"), lw=0.8,
                     label=f"{src} altitude_m error")
        err.plot(s.t_s, errors(s, truth, "climb_m_s"), lw=0.8, label=f"{src} climb_m_s error")
    err.set_ylabel("estimate - truth, m | m/s")


def _health(flags_ax: Axes, rate_ax: Axes, samples: dict[tuple[str, str], Series]) -> None:
    by_device: dict[str, list[Series]] = defaultdict(list)
    for (src, _), s in samples.items():
        by_device[src].append(s)
    for device, group in sorted(by_device.items()):
        t = np.concatenate([s.t_s for s in group])
        flags = np.concatenate([s.flags for s in group]).astype(int)
        order = np.argsort(t, kind="stable")
        t, flags = t[order], flags[order]
        for flag in SampleFlag:
            if not flag:
                continue
            hit = (flags & int(flag)) != 0
            if hit.any():
                flags_ax.step(t, np.cumsum(hit), where="post", label=f"{device} {flag.name}")
        seconds = np.floor(t).astype(int)
        counts = np.bincount(seconds - seconds[0])[:-1]  # the last second is cut short
        rate_ax.step(seconds[0] + np.arange(len(counts)), counts, where="post",
                     label=f"{device} samples/s")
    flags_ax.set_ylabel("flagged samples (cumulative)")
    if not flags_ax.get_lines():
        flags_ax.text(0.5, 0.5, "no flagged samples", transform=flags_ax.transAxes,
                      ha="center", va="center")
    rate_ax.set_ylabel("samples per second")


# -- evaluation errors ---------------------------------------------------------------------

class TrialErrors(Protocol):
    """One trial's errors for one estimator setting (imuhal.evaluate's TrialResult)."""

    @property
    def trial(self) -> str: ...
    @property
    def label(self) -> str: ...
    @property
    def dof(self) -> int: ...
    @property
    def total_deg(self) -> float: ...
    @property
    def heading_deg(self) -> float: ...
    @property
    def inclination_deg(self) -> float: ...


TRIAL_PANELS = {9: ("total_deg", "heading_deg", "inclination_deg"), 6: ("inclination_deg",)}
"""Errors drawn per DOF: a 6-DOF estimate has no heading reference, so only its inclination."""
MEAN = "mean"
"""The last bar group: each estimator's mean over the trials (as the tables give it)."""


def plot_trial_errors(results: Sequence[TrialErrors], *, title: str = "") -> LogFigure:
    """Each estimator setting's RMSE (deg) per trial as grouped bars, and its mean over the
    trials, in one panel per DOF and error (``9-DOF total``, ``9-DOF heading``,
    ``9-DOF inclination``, ``6-DOF inclination``). A bar missing is a job not run."""
    if not results:
        raise PlotError("no results to plot")
    panels = [(dof, metric) for dof in (9, 6) if any(r.dof == dof for r in results)
              for metric in TRIAL_PANELS[dof]]
    trials = list(dict.fromkeys(r.trial for r in results))
    categories = [*trials, MEAN]
    width_in = min(30.0, max(8.0, 0.6 * len(categories)))  # BROAD's 30 trials: 18.6 in
    figure = _figure_class()(figsize=(width_in, 3.0 * len(panels)), layout="constrained")
    grid = figure.subplots(len(panels), 1, squeeze=False)[:, 0]
    axes = {f"{dof}-DOF {metric.removesuffix('_deg')}": ax
            for (dof, metric), ax in zip(panels, grid, strict=True)}
    figure.suptitle(title or "RMSE per trial")
    x = np.arange(len(categories), dtype=float)
    for (dof, metric), (name, ax) in zip(panels, axes.items(), strict=True):
        rows = [r for r in results if r.dof == dof]
        labels = list(dict.fromkeys(r.label for r in rows))
        width = 0.8 / len(labels)
        for i, label in enumerate(labels):
            by_trial = {r.trial: float(getattr(r, metric)) for r in rows if r.label == label}
            heights = np.array([by_trial.get(t, math.nan) for t in trials]
                               + [float(np.mean(list(by_trial.values())))])
            ax.bar(x - 0.4 + width * (i + 0.5), heights, width, label=label)
        ax.set_xticks(x, categories, rotation=60, ha="right", fontsize="x-small")
        ax.set_ylabel(f"{name} RMSE, deg")
        ax.legend(loc="upper left", fontsize="x-small", ncols=min(4, len(labels)))
        ax.grid(True, axis="y", alpha=0.3)
    return LogFigure(figure, axes)


def plot_vario_audio(curve: Any, *, dampings_s: Sequence[float] = (0.0, 0.5, 1.5, 4.0),
                     alarm_m_s: float = -5.0) -> LogFigure:
    """The vario tones of ``curve`` (a :class:`~imuhal.sinks.flight.audio.VarioAudioSettings`)
    in three panels: ``pitch`` (Hz against climb m/s: beeps, sink tone, dead band, the sink
    alarm's pitches drawn below ``alarm_m_s``), ``cadence`` (beep period and on-time, s) and
    ``damping`` (the climb the tones follow after a step 0 -> 2 m/s, per time constant)."""
    s = curve
    figure = _figure_class()(figsize=(13, 4), layout="constrained")
    ax_pitch, ax_beep, ax_damp = figure.subplots(1, 3)
    climb = np.linspace(s.climb_threshold_m_s, s.max_climb_m_s + 1, 300)
    ax_pitch.plot(climb, [s.climb_hz(c) for c in climb], label="beeps")
    sink = np.linspace(-s.max_climb_m_s - 1, s.sink_threshold_m_s, 200)
    ax_pitch.plot(sink, [s.sink_tone_hz(c) for c in sink], label="continuous sink tone")
    ax_pitch.axvspan(s.sink_threshold_m_s, s.climb_threshold_m_s, color="0.9",
                     label="silent dead band")
    for hz in s.sink_alarm_hz:
        ax_pitch.plot([-s.max_climb_m_s - 1, alarm_m_s], [hz, hz], "r:", lw=1)
    ax_pitch.text(-s.max_climb_m_s - 0.5, max(s.sink_alarm_hz) + 60,
                  f"sink alarm warble\n(sink_alarm_m_s: {alarm_m_s:g})", color="r",
                  fontsize=8)
    ax_pitch.set(xlabel="climb rate (m/s)", ylabel="pitch (Hz)", title="pitch")
    ax_pitch.legend(fontsize=8, loc="upper left")
    c = np.linspace(s.climb_threshold_m_s, s.max_climb_m_s, 400)
    ax_beep.step(c, [s.beep(x)[0] for x in c], where="post", label="period")
    ax_beep.step(c, [s.beep(x)[1] for x in c], where="post", label="on-time")
    ax_beep.set(xlabel="climb rate (m/s)", ylabel="s",
                title=f"beep cadence ({s.tick_s * 1000:g} ms ticks)")
    ax_beep.legend(fontsize=8)
    t = np.arange(0, 8, 0.02)
    for tau in dampings_s:
        # the first-order step response the audio sink applies, 2 m/s step
        ax_damp.plot(t, 2.0 * (1 - np.exp(-t / tau)) if tau > 0 else np.full_like(t, 2.0),
                     label=f"damping_s {tau:g}")
    ax_damp.axhline(s.climb_threshold_m_s, color="0.5", ls="--", lw=1)
    ax_damp.text(5.0, s.climb_threshold_m_s + 0.05, "first beep", fontsize=8)
    ax_damp.set(xlabel="s after a step 0 -> 2 m/s", ylabel="climb the tones follow (m/s)",
                title="damping")
    ax_damp.legend(fontsize=8)
    return LogFigure(figure, {"pitch": ax_pitch, "cadence": ax_beep, "damping": ax_damp})
