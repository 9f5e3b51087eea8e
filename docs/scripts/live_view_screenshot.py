"""The screenshot in docs/live-view.md: the live view of the default emulated board.

Usage::

    .venv/bin/python docs/scripts/live_view_screenshot.py [--output docs/images/live-view.png]

Runs the bundled seed board emulated (the ``thermal`` scenario, seed 1: what ``imuhal run
--web 8080`` shows), paced at ``SPEED`` times the wall clock so the page's history fills in
a few seconds, opens the page in headless Chromium (/usr/bin/chromium, driven over the
DevTools pipe by tests/support/headless.py) and captures it at ``T_SHOT_S`` simulated
seconds, in the first thermal.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from tests.support.headless import Chromium  # noqa: E402

from imuhal.emulation import open_emulated  # noqa: E402
from imuhal.live import LiveView  # noqa: E402
from imuhal.plugins.manager import load_registry  # noqa: E402
from imuhal.profile.bundled import default_profile_path  # noqa: E402
from imuhal.profile.loader import load_profile  # noqa: E402

SPEED = 6.0
T_SHOT_S = 34.0
WIDTH, HEIGHT = 1180, 1060


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=ROOT / "docs/images/live-view.png")
    args = parser.parse_args()
    registry = load_registry()
    profile = load_profile(default_profile_path(), registry)
    go = threading.Event()
    with open_emulated(profile, registry) as pipeline, \
            LiveView.for_pipeline(pipeline) as live, \
            Chromium(width=WIDTH, height=HEIGHT) as browser:
        def run() -> None:
            go.wait(30)
            wall0 = time.monotonic()
            for event in pipeline.events(T_SHOT_S + 1.0):
                live.sink.handle(event)
                ahead = event.t_ns / 1e9 / SPEED - (time.monotonic() - wall0)
                if ahead > 0:
                    time.sleep(ahead)

        runner = threading.Thread(target=run, daemon=True)
        runner.start()
        browser.navigate(live.url)
        browser.wait_for("window.imuhalState && window.imuhalState.messages > 0")
        go.set()
        browser.wait_for(f"imuhalState.t_s >= {T_SHOT_S}", timeout=T_SHOT_S / SPEED + 30)
        png = browser.screenshot()
        runner.join(timeout=30)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.output.with_suffix(".tmp")
    tmp.write_bytes(png)
    tmp.replace(args.output)
    print(f"wrote {args.output} ({len(png) // 1024} KiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
