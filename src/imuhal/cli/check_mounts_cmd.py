"""``imuhal check-mounts``: are the profile's mounts right? (the live page's bring-up
checks, headless).

The user tilts the nose up, rolls right and turns right on cue; every gyro, accelerometer
and magnetometer must see each motion about the right body axis with the right sign
(imuhal.live.mounts). Emulated (``--emulate bringup``, the default without PROFILE) the
scenario performs the motions in its phases of the same names, so the check runs unattended;
``--physical-mount DEVICE=MOUNT`` places a chip differently from what the profile says.
Exit status: 0 every check passed, 1 a mount is wrong or a motion was not seen.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imuhal.cli import args as types
from imuhal.core.errors import ImuhalError
from imuhal.core.frames import MountError, parse_mount
from imuhal.core.samples import Quantity
from imuhal.live.mounts import MOTIONS, Motion, MotionRecorder, Verdict, check, suggest_mount
from imuhal.plugins.manager import Registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.profile.topology import chip_to_body_rotations

if TYPE_CHECKING:
    from imuhal.pipeline import Pipeline

EXIT_WRONG = 1
WINDOW_S = 3.0
"""How long each motion is recorded on hardware, by default."""
MAX_WINDOW_S = 600.0
"""Longest --window accepted: a motion takes seconds; beyond ten minutes it is a typo."""
MARKS = {True: "ok  ", False: "FAIL", None: "--  "}


def add_parser(sub: Any) -> None:
    cmd = sub.add_parser(
        "check-mounts", help="check the profile's mounts with three motions (bring-up)",
        description="Ask for three motions (tilt nose up, roll right, turn right) and tell, "
        "for every gyro, accelerometer and magnetometer, whether the profile's mount turns "
        "its axes the right way. With no PROFILE: the bundled seed board, emulated flying "
        "the 'bringup' scenario (which performs the motions).")
    cmd.add_argument("profile", nargs="?", help="board profile YAML (default: bundled seed "
                     "board, emulated)")
    cmd.add_argument("--emulate", metavar="SCENARIO",
                     help="emulate the board flying SCENARIO, whose phases 'nose-up', "
                     "'roll-right' and 'turn-right' are the motions (e.g. bringup)")
    cmd.add_argument("--physical-mount", action="append", default=[], metavar="DEVICE=MOUNT",
                     help="emulated: DEVICE's chip really sits so (e.g. imu=-X+Y-Z), "
                     "whatever the profile says; repeatable")
    cmd.add_argument("--seed", type=types.seed, help="seed of the simulated world (0 or more)")
    cmd.add_argument("--window", type=float, metavar="SECONDS",
                     help="hardware: how long each motion is recorded (default 3 s)")
    cmd.set_defaults(func=cmd_check_mounts)


def _physical_mounts(items: Iterable[str]) -> dict[str, str]:
    mounts = {}
    for item in items:
        device, sep, mount = item.partition("=")
        if not sep or not device or not mount:
            raise ImuhalError(f"--physical-mount {item!r}: write DEVICE=MOUNT, e.g. "
                              f"imu=-X+Y-Z")
        try:
            parse_mount(mount)
        except MountError as exc:
            raise ImuhalError(f"--physical-mount {item!r}: {exc}") from None
        mounts[device] = mount
    return mounts


def cmd_check_mounts(args: argparse.Namespace, registry: Registry) -> int:
    path = Path(args.profile) if args.profile else default_profile_path()
    profile = load_profile(path, registry)
    emulate = args.emulate if args.emulate or args.profile else "bringup"
    mounts = _physical_mounts(args.physical_mount)
    if mounts and emulate is None:
        raise ImuhalError("--physical-mount places emulated chips: add --emulate bringup")
    if args.window is not None and emulate is not None:
        raise ImuhalError("--window times the motions on hardware; an emulated scenario times "
                          "its own phases - drop --window")
    window = WINDOW_S if args.window is None else args.window
    if not window > 0 or window > MAX_WINDOW_S:
        raise ImuhalError(f"--window {window:g}: give a number of seconds from 0 to "
                          f"{MAX_WINDOW_S:g}, e.g. 3")
    if emulate is not None:
        registry.scenarios.get(emulate)  # an unknown name fails here, before the board opens
    where = f"emulated, scenario '{emulate}'" if emulate else "real hardware"
    print(f"checking the mounts of {profile.name} ({where}) from {path}", file=sys.stderr)
    if emulate is not None:
        verdicts = _emulated(profile, registry, emulate, args.seed, mounts)
    else:
        verdicts = _hardware(profile, registry, window)
    return _report(verdicts, profile)


def _emulated(profile: Any, registry: Registry, scenario: str, seed: int | None,
              mounts: dict[str, str]) -> dict[str, list[Verdict]]:
    from imuhal.emulation import open_emulated

    with open_emulated(profile, registry, scenario=scenario, seed=seed,
                       physical_mounts=mounts) as pipeline:
        phases = {p.name: p for p in pipeline.board.scenario.phases()}  # type: ignore[attr-defined]
        missing = [m.key for m in MOTIONS if m.key not in phases]
        if missing:
            raise ImuhalError(f"scenario {scenario!r} has no phase {', '.join(missing)}: it "
                              f"does not perform the bring-up motions; use --emulate bringup")
        windows = [(m, phases[m.key].start_s, phases[m.key].end_s) for m in MOTIONS]
        recorder = MotionRecorder()
        verdicts: dict[str, list[Verdict]] = {}
        pending = list(windows)
        for event in pipeline.events(max(end for _, _, end in windows) + 0.1):
            t_s = event.t_ns / 1e9
            motion, start, end = pending[0]
            if t_s >= end:
                verdicts[motion.key] = _announce(motion, check(motion, recorder.evidence()))
                pending.pop(0)
                if not pending:
                    break
                motion, start, end = pending[0]
            if not recorder.recording and start <= t_s < end:
                print(f"\n{motion.label}: the scenario will {motion.prompt}")
                recorder.start()
            recorder.handle(event)
        return verdicts


def _hardware(profile: Any, registry: Registry, window_s: float) -> dict[str, list[Verdict]]:
    from imuhal.pipeline import Pipeline

    with Pipeline.open(profile, registry) as pipeline:
        for w in pipeline.warnings:
            print(f"warning: {w}", file=sys.stderr)
        try:
            return guided_check(pipeline, window_s=window_s)
        except EOFError:
            raise ImuhalError("check-mounts on hardware prompts for each motion: run it in "
                              "a terminal (standard input ended)") from None


def guided_check(pipeline: Pipeline, *, window_s: float,
                 ask: Callable[[str], str] = input) -> dict[str, list[Verdict]]:
    """Prompt for each motion (``ask`` shows a prompt and waits for Enter) and record
    ``window_s`` wall seconds of it while the pipeline runs on its own thread, at its own
    pace; every sensor's verdict per motion."""
    recorder = MotionRecorder()
    lock = threading.Lock()
    stop = threading.Event()
    failure: list[BaseException] = []

    def run() -> None:
        try:
            for event in pipeline.events():
                if stop.is_set():
                    return
                with lock:
                    recorder.handle(event)
        except BaseException as exc:  # reported by the main thread
            failure.append(exc)

    thread = threading.Thread(target=run, name="imuhal-check-mounts", daemon=True)
    thread.start()
    verdicts: dict[str, list[Verdict]] = {}
    try:
        ask("Put the board level and still, then press Enter ")
        for motion in MOTIONS:
            ask(f"\n{motion.label}: press Enter, then {motion.prompt} "
                f"(within {window_s:g} s) ")
            with lock:
                recorder.start()
            time.sleep(window_s)
            if failure:
                raise failure[0]
            with lock:
                evidence = recorder.evidence()
            verdicts[motion.key] = _announce(motion, check(motion, evidence))
            if motion is not MOTIONS[-1]:
                ask("Put the board back level and still, then press Enter ")
    finally:
        stop.set()
        thread.join(timeout=2.0)
    return verdicts


def _announce(motion: Motion, verdicts: list[Verdict]) -> list[Verdict]:
    if not verdicts:
        print(f"  {MARKS[None]} no gyro, accelerometer or magnetometer sample was seen",
              file=sys.stderr)
    for v in verdicts:
        print(f"  {MARKS[v.ok]} {v.message}")
    return verdicts


def _report(verdicts: dict[str, list[Verdict]], profile: Any) -> int:
    wrong = [v for vs in verdicts.values() for v in vs if v.ok is False]
    unseen = [key for key, vs in verdicts.items() if not any(v.ok for v in vs)]
    if wrong:
        devices = sorted({v.device for v in wrong})
        print(f"\nmounts WRONG: {len(wrong)} checks failed; fix the mount of "
              f"{', '.join(devices)} in the profile (docs/live-view.md, bring-up)")
        for device in devices:
            _suggest(device, verdicts, profile)
        return EXIT_WRONG
    if unseen:
        print(f"\nnot seen: {', '.join(unseen)}; repeat and move further (about 30 "
              f"degrees, 90 for the turn)")
        return EXIT_WRONG
    print("\nmounts right: every sensor saw every motion the right way (or could not see it)")
    return 0


def _suggest(device: str, verdicts: dict[str, list[Verdict]], profile: Any) -> None:
    """Print the mount that explains what ``device``'s gyro saw, when it has one."""
    seen = {key: v.rotation_deg for key, vs in verdicts.items() for v in vs
            if v.device == device and v.channel is Quantity.GYRO}
    mount = suggest_mount(chip_to_body_rotations(profile)[device],
                          parse_mount(profile.board_to_body), seen)
    if mount is not None:
        print(f"  {device}: its gyro moved as a chip mounted \"{mount}\" would (the profile "
              f"says {profile.devices[device].mount!r}): set `mount: \"{mount}\"`")
