"""Emulated runs in one process are independent: an embedding program that runs pipelines one
after another gets, from each, what the same run gives in a fresh process (no module,
class or kernel state carried from one run into the next).

A fresh process is the reference (a subprocess), and two other boards and scenarios fly
between the in-process runs, so state that one run leaves behind and the next one reads
shows as a different event stream.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

from imuhal.emulation import open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile

ROOT = Path(__file__).resolve().parents[2]
SEED = 1
DURATION_S = 20.0
"""Long enough for the GNSS fix, the wind fit's first circle input and the vario to settle."""


def event_digest(board: str, scenario: str, duration_s: float) -> str:
    """SHA-256 over the repr of every event of a bundled board's emulated run (each float
    exactly), in order."""
    registry = load_registry()
    profile = load_profile(default_profile_path().parent / f"{board}.yaml", registry)
    digest = hashlib.sha256()
    with open_emulated(profile, registry, scenario=scenario, seed=SEED) as pipeline:
        for event in pipeline.events(duration_s):
            digest.update(repr(event).encode())
    return digest.hexdigest()


def _fresh_process_digest(board: str, scenario: str, duration_s: float) -> str:
    code = (f"import runpy; digest = runpy.run_path({__file__!r})['event_digest']; "
            f"print(digest({board!r}, {scenario!r}, {duration_s!r}))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, timeout=300, cwd=ROOT)
    return done.stdout.strip().splitlines()[-1]


def test_a_run_after_other_runs_in_the_process_equals_the_same_run_in_a_fresh_process(
) -> None:
    first = event_digest("seed-gps-vario", "thermal", DURATION_S)
    event_digest("seed-paraglider-vario", "rc-flight", 10.0)
    event_digest("seed-gps-vario", "static", 5.0)
    again = event_digest("seed-gps-vario", "thermal", DURATION_S)
    assert again == first
    assert _fresh_process_digest("seed-gps-vario", "thermal", DURATION_S) == first
