"""``imuhal calibrate gyro|accel|mag PROFILE``: measure a calibration and store it in the
profile; ``imuhal calibrate --show PROFILE``: print what is stored."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from pydantic import ValidationError

from imuhal.calibrate.session import (
    describe_position,
    guided_order,
    open_raw_pipeline,
    pick_device,
    run_procedure,
)
from imuhal.calibrate.store import write_device_calibration
from imuhal.calibration.accel import (
    AccelSixPosition,
    AccelSixSettings,
    parse_position,
    position_name,
)
from imuhal.calibration.gyro import GyroOffsetProcedure, GyroOffsetSettings
from imuhal.calibration.mag import MagCalibrationProcedure, MagSettings
from imuhal.calibration.model import DeviceCalibration, GyroStartupSettings, now
from imuhal.calibration.progress import Progress, ProgressKind
from imuhal.cli import args as types
from imuhal.core.atomic import check_outputs, check_writable, resolve_target
from imuhal.core.errors import ImuhalError
from imuhal.core.frames import parse_mount
from imuhal.core.samples import Quantity, VectorSample
from imuhal.offline.settings_args import build_settings, parse_set_arguments
from imuhal.plugins.manager import Registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sim.errors import SensorErrorSpec, error_spec_of, noise_only

DEG = math.pi / 180.0
MG = 9.80665e-3
TIMEOUTS_S = {"gyro": 60.0, "accel": 300.0, "mag": 180.0}
MAX_FIELD_UT = 1000.0
"""Largest --field accepted: the Earth's field is 25-65 uT; beyond this it is a typo."""
CHANNELS = {"gyro": Quantity.GYRO, "accel": Quantity.ACCEL, "mag": Quantity.MAG}


def add_parser(sub: Any) -> None:
    cal = sub.add_parser(
        "calibrate", help="calibrate a board's gyro, accelerometer or magnetometer",
        description="Run a calibration procedure on the board in PROFILE (real, or emulated "
        "with --emulate calibration: the simulator performs the motions), print the result "
        "and its quality, and store it in the profile (atomically; the old file is kept as "
        "PROFILE.bak and the replaced record under calibration.previous), or in a copy with "
        "--output. A bundled profile of the installed package is never edited: copy it first "
        "or give --output.",
    )
    cal.add_argument("procedure", nargs="?",
                     help="gyro: offsets at rest; accel: six positions; mag: figure of 8; or "
                     "a procedure a plugin registered (`imuhal plugins`), e.g. vector-zero")
    cal.add_argument("profile", nargs="?", help="board profile YAML")
    cal.add_argument("--show", metavar="PROFILE", help="print the calibration stored in PROFILE")
    cal.add_argument("--device", metavar="NAME", help="device to calibrate (default: the only "
                     "one with the channel)")
    cal.add_argument("--emulate", metavar="SCENARIO", help="emulated board flying SCENARIO "
                     "(use 'calibration'); its chips get their datasheet error models")
    cal.add_argument("--ideal", action="store_true",
                     help="with --emulate: chips without errors (their noise kept)")
    cal.add_argument("--seed", type=types.seed,
                     help="seed of the simulated world and sensor errors (0 or more)")
    cal.add_argument("--timeout", type=types.seconds, metavar="SECONDS",
                     help="give up after this long (default: gyro 60, accel 300, mag 180; "
                     "emulated: the scenario's length)")
    cal.add_argument("--samples", type=types.int_at_least(1, "a number of readings", "250"),
                     metavar="N",
                     help="readings averaged (gyro default 100, accel per position 250)")
    cal.add_argument("--misalignment", action="store_true",
                     help="accel: also fit the full 3x3 misalignment by least squares")
    cal.add_argument("--method", choices=["ellipsoid", "minmax"],
                     help="mag: ellipsoid fit (hard + full soft iron) or the seed's min/max")
    cal.add_argument("--field", type=types.positive_float("a field strength in uT", "48",
                                                          MAX_FIELD_UT),
                     metavar="UT",
                     help="mag: local field strength in uT (default: fitted)")
    cal.add_argument("--at-startup", action="store_true",
                     help="gyro: also re-measure the offsets at every start-up")
    cal.add_argument("--output", "-o", metavar="FILE.yaml",
                     help="write the calibrated profile here instead of updating PROFILE "
                     "(needed for a bundled profile)")
    cal.add_argument("--quantity", metavar="NAME",
                     help="registered procedures: the vector quantity to calibrate")
    cal.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="registered procedures: a setting of the procedure")
    cal.add_argument("--dry-run", action="store_true", help="print the result, write nothing")
    cal.set_defaults(func=cmd_calibrate, _parser=cal)


def cmd_calibrate(args: argparse.Namespace, registry: Registry) -> int:
    if args.show:
        if args.procedure is not None or args.output or args.dry_run:
            args._parser.error("--show prints a stored calibration and writes nothing; give "
                               "either --show PROFILE or a procedure and a PROFILE")
        return show(Path(args.show), registry, sys.stdout)
    if args.procedure is None or args.profile is None:
        args._parser.error("give a procedure and a PROFILE (or --show PROFILE)")
    _refuse_unused_options(args)
    path = Path(args.profile)
    registered = args.procedure not in CHANNELS
    if registered and args.procedure not in registry.calibrations.entries:
        raise ImuhalError(
            f"no calibration procedure named {args.procedure!r}; choose gyro, accel, mag or "
            f"one a plugin registered: {', '.join(registry.calibrations.names()) or 'none'}")
    target = None if args.dry_run else _writable_target(path, args.output)
    profile = load_profile(path, registry)
    key = _registered_quantity(args, registry) if registered else args.procedure
    channel = registry.quantities.get(key).channel if registered else CHANNELS[key]
    device = pick_device(profile, registry, channel, args.device)
    cfg = profile.devices[device]
    chip_to_body = parse_mount(profile.board_to_body) @ parse_mount(cfg.mount)
    err = sys.stderr
    reporter = _Reporter(err)
    timeout = args.timeout
    if timeout is None:
        timeout = (registry.scenarios.get(args.emulate).default_duration_s if args.emulate
                   else _registered(args, registry).default_timeout_s if registered
                   else TIMEOUTS_S[args.procedure])
    proc = (_registered_procedure(args, registry, key, device, reporter) if registered
            else _procedure(args, device, chip_to_body, reporter, None))  # settings checked early
    where = f"emulated, scenario '{args.emulate}'" if args.emulate else "real hardware"
    what = f"{key} ({args.procedure})" if registered else args.procedure
    print(f"calibrating {what} of {device} ({cfg.driver}) in {profile.name} ({where})",
          file=err)
    with open_raw_pipeline(profile, registry, emulate=args.emulate, seed=args.seed,
                           realtime=False, error_specs=_ideal_specs(profile, registry)
                           if args.ideal else None) as pipeline:
        for w in pipeline.warnings:
            print(f"warning: {w}", file=err)
        order = _scenario_order(pipeline, chip_to_body)
        if args.procedure == "accel" and order is not None:
            proc = _procedure(args, device, chip_to_body, reporter, order)
        binding = pipeline.calibration_binding(device)
        try:
            result = run_procedure(proc, pipeline, timeout)
        finally:
            reporter.end_line()
    stored = cfg.calibration or DeviceCalibration()
    date = now()
    if registered:
        record = result.model_copy(update={"date": date})
    elif args.procedure == "gyro":
        record = result.record(stored.gyro, date=date)
    else:
        record = result.record(date=date)
    record = record.model_copy(update={"binding": binding})
    new = stored.replaced(key, record)
    if args.at_startup:
        new = new.model_copy(update={"gyro_at_startup": GyroStartupSettings()})
    print(f"{device} {key} calibration ({record.procedure}):")
    print(_describe_record(key, record.model_dump(), indent="  "))
    if args.dry_run:
        print("dry run: profile not written", file=err)
        return 0
    assert target is not None
    bak, warnings = write_device_calibration(path, device, new, registry, output=target)
    for w in warnings:
        print(f"warning: {w}", file=err)
    print(f"wrote devices.{device}.calibration.{key} to {target}"
          + (f" (previous file kept as {bak})" if bak else ""), file=err)
    return 0


OPTION_FOR = {
    "--misalignment": ("misalignment", ("accel",)),
    "--method": ("method", ("mag",)),
    "--field": ("field", ("mag",)),
    "--at-startup": ("at_startup", ("gyro",)),
    "--samples": ("samples", ("gyro", "accel")),
}
"""Options that only some built-in procedures read: option -> (attribute, procedures)."""


def _refuse_unused_options(args: argparse.Namespace) -> None:
    """An option the chosen procedure would silently ignore is a mistake worth a line."""
    builtin = args.procedure in CHANNELS
    for option, (attr, procedures) in OPTION_FOR.items():
        if getattr(args, attr) not in (None, False) and (not builtin or
                                                         args.procedure not in procedures):
            raise ImuhalError(f"{option} applies to `imuhal calibrate {' or '.join(procedures)}`"
                              f", not to {args.procedure}; drop {option}")
    if builtin and (args.quantity is not None or args.set):
        option = "--quantity" if args.quantity is not None else "--set"
        raise ImuhalError(f"{option} sets a procedure a plugin registered; `imuhal calibrate "
                          f"{args.procedure}` has none - drop {option}")
    for option, given in (("--ideal", args.ideal), ("--seed", args.seed is not None)):
        if given and not args.emulate:
            raise ImuhalError(f"{option} applies to an emulated board; add --emulate "
                              "calibration (or drop it)")
    if args.dry_run and args.output:
        raise ImuhalError("--dry-run writes nothing; drop --output (or --dry-run)")


def _writable_target(profile: Path, output: str | None) -> Path:
    """Where the calibrated profile goes, checked before any measurement: ``--output``, or
    the profile itself unless it is one of the installed package's bundled profiles."""
    if output is not None:
        check_outputs({"--output": output}, {"PROFILE": profile})
        return Path(output)
    real = resolve_target(profile)
    bundled = {resolve_target(p) for p in bundled_profiles().values()}
    if real in bundled:
        raise ImuhalError(
            f"{profile}: is a profile bundled with imuhal ({real}); calibration is never "
            f"written into it. Copy it first (cp {profile} my-board.yaml) and calibrate the "
            "copy, or add --output my-board.yaml")
    check_writable(profile, "PROFILE")
    return profile


def _procedure(args: argparse.Namespace, device: str, chip_to_body: np.ndarray,
               reporter: _Reporter, scenario_order: tuple[str, ...] | None) -> Any:
    """The procedure the arguments ask for; settings mistakes are one-line errors."""
    try:
        if args.procedure == "gyro":
            gs = GyroOffsetSettings(**({"samples": args.samples} if args.samples else {}))
            return GyroOffsetProcedure(gs, device=device, progress=reporter)
        if args.procedure == "accel":
            acc = AccelSixSettings(positions=scenario_order or guided_order(chip_to_body),
                                   misalignment=args.misalignment,
                                   **({"samples": args.samples} if args.samples else {}))
            return AccelSixPosition(acc, device=device, progress=reporter,
                                    describe=lambda p: describe_position(p, chip_to_body))
        return MagCalibrationProcedure(MagSettings(method=args.method or "ellipsoid",
                                                   field_ut=args.field),
                                       device=device, progress=reporter)
    except ValidationError as exc:
        first = exc.errors(include_url=False)[0]
        option = {"samples": "--samples", "field_ut": "--field"}.get(
            str(first["loc"][0]) if first["loc"] else "", "settings")
        raise ImuhalError(f"{option}: {first['msg']} (found {first.get('input')!r})") from None


def _registered(args: argparse.Namespace, registry: Registry) -> Any:
    return registry.calibrations.get(args.procedure)


def _registered_procedure(args: argparse.Namespace, registry: Registry, quantity: str,
                          device: str, reporter: _Reporter) -> Any:
    """A procedure a plugin registered, with its ``--set`` settings."""
    cls = _registered(args, registry)
    settings = build_settings(cls.Settings, parse_set_arguments(args.set),
                              f"procedure {args.procedure!r}")
    return cls(settings, quantity=quantity, device=device, progress=reporter)


def _registered_quantity(args: argparse.Namespace, registry: Registry) -> str:
    """The quantity a registered procedure calibrates: its own, or ``--quantity``."""
    cls = _registered(args, registry)
    name = cls.quantity or args.quantity
    if name is None:
        raise ImuhalError(f"procedure {args.procedure!r} works on any vector quantity: name "
                          "one with --quantity NAME (see `imuhal plugins`)")
    if args.quantity is not None and cls.quantity is not None and args.quantity != name:
        raise ImuhalError(f"procedure {args.procedure!r} calibrates {name!r} only; drop "
                          f"--quantity {args.quantity}")
    if name in CHANNELS:
        raise ImuhalError(f"{name} has its own procedure: run `imuhal calibrate {name}`")
    if not issubclass(registry.quantities.get(name), VectorSample):
        raise ImuhalError(f"{name} is not a vector in the chip's frame; calibration applies "
                          "to those only")
    return name


def _scenario_order(pipeline: Any, chip_to_body: np.ndarray) -> tuple[str, ...] | None:
    """Emulated: the sensor positions in the order the scenario holds them (its phases are
    named after the body axis pointing down), so each prompt names the position the
    simulated hand is about to hold. None on hardware or when the scenario has no six."""
    scenario = getattr(getattr(pipeline, "board", None), "scenario", None)
    if scenario is None:
        return None
    order: list[str] = []
    body_to_chip = np.asarray(chip_to_body, dtype=float).T
    for phase in scenario.phases():
        try:
            axis, sign = parse_position(phase.name)
        except ValueError:
            continue
        down_chip = body_to_chip @ (sign * np.eye(3)[axis])
        i = int(np.argmax(np.abs(down_chip)))
        if abs(down_chip[i]) < 0.99:
            return None  # mounted at an angle: no sensor axis points straight down
        name = position_name((i, 1 if down_chip[i] > 0 else -1))
        if name not in order:
            order.append(name)
    return tuple(order) if len(order) == 6 else None


class _Reporter:
    """Prints procedure progress: instructions and retries on their own lines, progress as one
    updating line on a terminal (every quarter otherwise)."""

    def __init__(self, out: TextIO) -> None:
        self.out = out
        self.tty = out.isatty()
        self._open = False
        self._last_quarter: tuple[str, int] | None = None

    def __call__(self, p: Progress) -> None:
        if p.kind is ProgressKind.PROGRESS:
            frac = p.fraction or 0.0
            if self.tty:
                bar = "#" * int(20 * frac)
                print(f"\r  [{bar:<20}] {p.message}", end="", file=self.out, flush=True)
                self._open = True
                return
            quarter = (p.step, int(4 * frac))
            if quarter == self._last_quarter:
                return
            self._last_quarter = quarter
        self.end_line()
        prefix = {ProgressKind.INSTRUCTION: ">> ", ProgressKind.RETRY: "!! "}.get(p.kind, "   ")
        print(f"{prefix}{p.message}", file=self.out, flush=True)

    def end_line(self) -> None:
        if self._open:
            print(file=self.out)
            self._open = False


# --------------------------------------------------------------------------- --show
def show(path: Path, registry: Registry, out: TextIO) -> int:
    profile = load_profile(path, registry)
    any_cal = False
    for name, dev in profile.devices.items():
        cal = dev.calibration
        if cal is None:
            continue
        any_cal = True
        print(f"{name} ({dev.driver} on {dev.bus} at 0x{dev.address:02X}):", file=out)
        records = cal.records()
        for channel in sorted(records, key=lambda c: (c not in ("gyro", "accel", "mag"), c)):
            rec = records[channel]
            when = rec.date.isoformat() if rec.date else "undated"
            print(f"  {channel}: {rec.procedure}, {when}", file=out)
            print(_describe_record(channel, rec.model_dump(), indent="    "), file=out)
            b = rec.binding
            print("    bound to: " + (f"{b.driver} at {b.bus}/0x{b.address:02X} ({b.identity}, "
                                       f"calibration version {b.calibration_version})"
                                       if b else "any chip (no binding)"), file=out)
        if cal.gyro_at_startup is not None:
            state = "on" if cal.gyro_at_startup.enabled else "off"
            print(f"  gyro offsets at start-up: {state} ({cal.gyro_at_startup.samples} "
                  "samples)", file=out)
        if cal.previous is not None:
            kept = list(cal.previous.records())
            print(f"  previous records kept: {', '.join(kept)}", file=out)
    if not any_cal:
        print(f"{path}: no calibration stored; run `imuhal calibrate gyro|accel|mag {path}`",
              file=out)
    return 0


def _vec(v: Any, unit_scale: float = 1.0, fmt: str = "+.4f") -> str:
    return "(" + ", ".join(format(float(x) / unit_scale, fmt) for x in v) + ")"


def _describe_record(channel: str, rec: dict[str, Any], indent: str) -> str:
    lines = []
    if channel == "gyro":
        lines.append(f"offset: {_vec(rec['offset_rad_s'], DEG)} deg/s")
        lines.append(f"scale: {_vec(rec['scale'], fmt='.5f')}")
    elif channel == "accel":
        lines.append(f"offset: {_vec(rec['offset_m_s2'], MG, '+.2f')} mg")
        lines.append(f"scale: {_vec(rec['scale'], fmt='.5f')}")
        m = np.asarray(rec["misalignment"])
        if not np.allclose(m, np.eye(3)):
            lines += [f"misalignment: {_vec(row, fmt='+.5f')}" for row in m]
    elif channel == "mag":
        lines.append(f"hard iron: {_vec(rec['hard_iron_ut'], fmt='+.2f')} uT")
        lines += [f"soft iron: {_vec(row, fmt='+.4f')}" for row in rec["soft_iron"]]
    else:  # any other vector quantity (VectorCalibration), in its own unit
        lines.append(f"offset: {_vec(rec['offset'], fmt='+.5g')}")
        m = np.asarray(rec["matrix"])
        if not np.allclose(m, np.eye(3)):
            lines += [f"matrix: {_vec(row, fmt='+.5f')}" for row in m]
    if rec.get("quality"):
        lines.append("quality: " + ", ".join(f"{k} {v:.4g}" for k, v in rec["quality"].items()))
    return "\n".join(indent + line for line in lines)


def _ideal_specs(profile: Any, registry: Registry) -> dict[str, SensorErrorSpec]:
    """``--ideal``: every chip without errors but with its datasheet noise (a noiseless chip
    at rest repeats one raw frame, which its driver flags FROZEN)."""
    specs = {}
    for name, device in profile.devices.items():
        reg = registry.emulators.entries.get(device.driver)
        spec = noise_only(error_spec_of(reg.obj)) if reg is not None else None
        if spec is not None:
            specs[name] = spec
    return specs
