"""``imuhal evaluate``: estimators x settings x recordings with ground truth -> errors."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, ClassVar

from pydantic import Field

from imuhal.cli.frame_option import frame_argument
from imuhal.cli.options import CommandOptions, Needs
from imuhal.core.atomic import check_outputs
from imuhal.core.errors import ImuhalError
from imuhal.core.samples import GyroSample, PressureSample
from imuhal.evaluate.download import BROAD_URL, default_cache, download_broad
from imuhal.evaluate.recording import BROAD_SUFFIXES, RecordingSource
from imuhal.evaluate.report import (
    aggregate,
    summary_table,
    write_csv,
    write_json,
    write_markdown,
)
from imuhal.evaluate.runner import (
    EstimatorSpec,
    TrialResult,
    evaluate_serial,
    expand_grid,
    with_rate_settings,
)
from imuhal.offline.settings_args import build_settings, parse_set_arguments
from imuhal.plugins.manager import Registry

HELP = """\
Recordings: BROAD trials (.hdf5 or .mat; a folder means every trial in it, HDF5 preferred
when a trial is there in both forms; groups come from the trials.json next to them), or
imuhal sample CSVs (a run log of `imuhal run --output LOG.csv --samples`, or the wide
CSV of `imuhal estimate`), each with a --truth TRUTH.csv (from `imuhal run --truth`).
--broad uses the BROAD cache (filled by --download-broad, which alone uses the network).

Estimators: -e NAME[:KEY=VALUE[:KEY=VALUE...]], repeatable, e.g. -e madgwick
-e madgwick:accel_gate_g=null -e vqf:offline=true (default: every installed attitude
estimator with its defaults). --grid NAME.KEY=V1,V2,... runs every combination of the values
given for NAME. --dof 9 (gyro+accel+mag) and/or 6 (the magnetometer withheld).

Errors follow BROAD (Laidig et al. 2021): the estimate's error quaternion in the earth
frame; total angle, heading (about the vertical) and inclination RMSE in degrees over the
recording's movement mask; group figures are means over their trials.
"""


class EvaluateUsageError(ImuhalError):
    pass


EVALUATE_RULES = (
    Needs(lambda o: o.workers is not None, lambda o: o.dask or o.scheduler is not None,
          "--workers sizes the local Dask cluster; add --dask (or drop --workers)"),
    Needs(lambda o: o.workers is not None, lambda o: o.workers >= 1,
          lambda o: f"--workers {o.workers}: give 1 or more workers"),
    Needs(lambda o: bool(o.cache), lambda o: o.broad or o.download_broad,
          "--cache is where --broad and --download-broad keep BROAD; add one of them (or "
          "drop --cache)"),
)


class EvaluateOptions(CommandOptions):
    """What ``imuhal evaluate`` was asked (argparse destinations, values already typed)."""

    RULES: ClassVar[tuple[Needs, ...]] = EVALUATE_RULES
    ERROR: ClassVar[type[ImuhalError]] = EvaluateUsageError

    recordings: tuple[str, ...] = ()
    truth: tuple[str, ...] = ()
    input_frame: Any = None
    """The ``--input-frame`` convention (imuhal.core.conventions.Convention) or None."""
    broad: bool = False
    download_broad: bool = False
    cache: str | None = None
    broad_url: str = BROAD_URL
    estimator: tuple[str, ...] = ()
    grid: tuple[str, ...] = ()
    dof: tuple[int, ...] = ()
    group: tuple[str, ...] = ()
    output: str | None = None
    json_path: str | None = Field(None, alias="json")
    markdown: str | None = None
    plot: str | None = None
    dask: bool = False
    scheduler: str | None = None
    workers: int | None = None
    quiet: bool = False

    @property
    def on_dask(self) -> bool:
        """The jobs run on Dask: ``--dask``, or a ``--scheduler`` to send them to."""
        return self.dask or self.scheduler is not None

    def outputs(self) -> dict[str, str | None]:
        """Every file the evaluation may write, by option."""
        return {"--output": self.output, "--json": self.json_path,
                "--markdown": self.markdown, "--plot": self.plot}

    def inputs(self) -> dict[str, str]:
        """Every file it reads, by option (the second and later numbered)."""
        return {**{"RECORDING" + (f" #{i + 1}" if i else ""): r
                   for i, r in enumerate(self.recordings)},
                **{"--truth" + (f" #{i + 1}" if i else ""): t
                   for i, t in enumerate(self.truth)}}


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "evaluate", help="errors of estimators on recordings with ground truth (BROAD, CSV)",
        description="Run estimators over recordings with ground truth and report BROAD's "
        "total, heading and inclination RMSE per trial, per group and overall.",
        epilog=HELP, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("recordings", nargs="*", metavar="RECORDING")
    p.add_argument("--truth", action="append", default=[], metavar="TRUTH.csv",
                   help="truth CSV of each sample CSV, in the same order")
    p.add_argument("--input-frame", type=frame_argument, metavar="NAME",
                   help="convention of the sample CSVs' vectors (as for `imuhal estimate`)")
    p.add_argument("--broad", action="store_true", help="evaluate the cached BROAD trials")
    p.add_argument("--download-broad", action="store_true",
                   help="download BROAD into the cache first (uses the network)")
    p.add_argument("--cache", metavar="DIR", help=f"BROAD cache (default {default_cache()})")
    p.add_argument("--broad-url", default=BROAD_URL, help="where BROAD's files are fetched")
    p.add_argument("-e", "--estimator", action="append", default=[], metavar="SPEC")
    p.add_argument("--grid", action="append", default=[], metavar="NAME.KEY=V1,V2")
    p.add_argument("--dof", action="append", type=int, choices=(6, 9), default=[],
                   help="9 and/or 6 (default: both)")
    p.add_argument("--group", action="append", default=[], metavar="NAME",
                   help="also print this group's table (default: only all trials)")
    p.add_argument("--output", "-o", metavar="RESULTS.csv", help="per-trial results (CSV)")
    p.add_argument("--json", metavar="RESULTS.json", help="per-trial and group results (JSON)")
    p.add_argument("--markdown", metavar="TABLES.md",
                   help="per-group tables in Markdown (as in docs/evaluation.md)")
    p.add_argument("--plot", metavar="FIGURE.png",
                   help="a figure of each estimator's errors per trial and their means "
                   "(.png, .pdf or .svg; needs matplotlib: pip install 'imuhal[plot]')")
    p.add_argument("--dask", action="store_true", help="run the jobs on Dask")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler to use (default: a local cluster); implies --dask")
    p.add_argument("--workers", type=int, metavar="N", help="local Dask cluster size")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_evaluate)


def parse_spec(text: str, registry: Registry) -> tuple[str, dict[str, Any]]:
    name, *items = text.split(":")
    registry.estimators.get(name)  # an unknown name is a one-line error listing the known
    return name, parse_set_arguments(items, f"-e {name}:")


def parse_grid(items: list[str], registry: Registry) -> dict[str, dict[str, list[Any]]]:
    grid: dict[str, dict[str, list[Any]]] = {}
    for item in items:
        head, sep, _ = item.partition("=")
        name, dot, key = head.partition(".")
        if not sep or not dot or not key:
            raise EvaluateUsageError(f"--grid {item!r}: write NAME.KEY=V1,V2, e.g. --grid "
                                     "madgwick.beta=0.01,0.03,0.1")
        registry.estimators.get(name)
        value = parse_set_arguments([item[len(name) + 1:]], "--grid")[key]
        grid.setdefault(name, {})[key] = value if isinstance(value, list) else [value]
    return grid


def attitude_estimators(registry: Registry) -> list[str]:
    """Installed estimators that take gyro samples and no pressure (the AHRS kind)."""
    return [n for n in registry.estimators.names()
            if GyroSample in registry.estimators.get(n).consumes
            and PressureSample not in registry.estimators.get(n).consumes]


def recording_sources(args: argparse.Namespace | EvaluateOptions) -> list[RecordingSource]:
    """The recordings to evaluate: the named ones and the BROAD cache (``--broad``), each
    sample CSV paired with its ``--truth``."""
    paths = [Path(p) for p in args.recordings]
    cache = None
    if args.broad or args.download_broad:
        cache = Path(args.cache) if args.cache else default_cache()
        paths.append(cache)
    sources: list[RecordingSource] = []
    csvs: list[Path] = []
    for p in paths:
        if p.suffix.lower() == ".csv" and not p.is_dir():
            csvs.append(p)
        else:
            sources += _broad_sources(p, broad=args.broad, cache=cache)
    if len(csvs) != len(args.truth):
        raise EvaluateUsageError(f"{len(csvs)} sample CSV(s) but {len(args.truth)} --truth "
                                 "file(s); give one --truth TRUTH.csv per sample CSV")
    frame = args.input_frame.name if args.input_frame is not None else None
    sources += [RecordingSource(str(c), t, frame) for c, t in zip(csvs, args.truth, strict=True)]
    if not sources:
        raise EvaluateUsageError("no recordings; give BROAD trials, a folder of them, "
                                 "--broad, or a sample CSV with --truth")
    return sources


def _broad_sources(p: Path, *, broad: bool, cache: Path | None) -> list[RecordingSource]:
    """A BROAD trial file, or every trial in a folder (HDF5 preferred over MAT)."""
    if p.is_file():
        return [RecordingSource(str(p))]
    if not p.is_dir():
        raise EvaluateUsageError(f"{p}: no such file or folder" + (
            "; fetch BROAD into it first with `imuhal evaluate --download-broad`"
            " (or name a BROAD folder with --cache)" if p == cache else ""))
    trials: dict[str, Path] = {}
    for f in sorted(p.iterdir()):
        if f.suffix.lower() in BROAD_SUFFIXES and (
                f.stem not in trials or f.suffix.lower() != ".mat"):
            trials[f.stem] = f
    if not trials:
        raise EvaluateUsageError(f"{p}: no BROAD trials (.hdf5/.mat) in this folder"
                                 + ("; fetch them with --download-broad" if broad else ""))
    return [RecordingSource(str(trials[k])) for k in sorted(trials)]


def _progress(quiet: bool) -> Any:
    def show(done: int, total: int, r: TrialResult) -> None:
        if not quiet:
            print(f"[{done}/{total}] {r.trial}  {r.label} ({r.dof}-DOF): total "
                  f"{r.total_deg:.2f}, heading {r.heading_deg:.2f}, inclination "
                  f"{r.inclination_deg:.2f} deg ({r.seconds:.1f} s)", file=sys.stderr)
    return show


def cmd_evaluate(args: argparse.Namespace, registry: Registry) -> int:
    opts = EvaluateOptions.from_args(args)
    # No output may replace an input (links and hard links included) or another output.
    check_outputs(opts.outputs(), opts.inputs())
    if opts.plot:
        from imuhal.offline.plotting import check_figure_path

        check_figure_path(opts.plot)  # before the evaluation, not after it
    specs = _specs(opts, registry)
    if opts.download_broad:
        download_broad(opts.cache, base_url=opts.broad_url,
                       progress=None if opts.quiet else lambda m: print(m, file=sys.stderr))
    sources = recording_sources(opts)
    progress = _progress(opts.quiet)
    if opts.on_dask:
        from imuhal.evaluate.dask_runner import evaluate_dask

        results = evaluate_dask(sources, specs, scheduler=opts.scheduler,
                                workers=opts.workers, progress=progress)
    else:
        results = evaluate_serial(sources, specs, registry, progress)
    groups = aggregate(results)
    _print_tables(groups, opts.group)
    _write_results(opts, results, groups)
    return 0


def _specs(opts: EvaluateOptions, registry: Registry) -> list[EstimatorSpec]:
    """Every estimator x settings x DOF job, each settings mistake found before the first
    job runs, not after some ran."""
    specs_in = [parse_spec(s, registry) for s in opts.estimator] or [
        (n, {}) for n in attitude_estimators(registry)]
    grid = parse_grid(list(opts.grid), registry)
    unused = sorted(set(grid) - {n for n, _ in specs_in})
    if unused:
        raise EvaluateUsageError(f"--grid {unused[0]}.*: {unused[0]} is not evaluated; add -e "
                                 f"{unused[0]} (or drop the --grid)")
    dofs = opts.dof or (9, 6)
    specs = expand_grid([EstimatorSpec(n, s, d) for d in dofs for n, s in specs_in], grid)
    for spec in specs:
        cls = registry.estimators.get(spec.name)
        build_settings(cls.Settings,
                       with_rate_settings(cls.Settings.model_fields, spec.settings, 100.0),
                       spec.name, f"-e {spec.name}: / --grid {spec.name}.")
    return specs


def _print_tables(groups: list[Any], wanted: tuple[str, ...]) -> None:
    """The table of all trials, then one per ``--group``."""
    known = list(dict.fromkeys(g.group for g in groups))
    for g in wanted:
        if g not in known:
            raise EvaluateUsageError(f"--group {g}: no trial is in that group; groups: "
                                     f"{', '.join(known)}")
    print(summary_table(groups))
    for g in wanted:
        print(f"\ngroup {g}:\n{summary_table(groups, g)}")


def _write_results(opts: EvaluateOptions, results: list[TrialResult],
                   groups: list[Any]) -> None:
    if opts.output:
        write_csv(opts.output, results)
    if opts.json_path:
        write_json(opts.json_path, results, groups)
    if opts.markdown:
        write_markdown(opts.markdown, groups)
    if opts.plot:
        from imuhal.offline.plotting import plot_trial_errors

        plot_trial_errors(results, title="imuhal evaluate: RMSE per trial").save(opts.plot)
        print(f"wrote {opts.plot}", file=sys.stderr)
