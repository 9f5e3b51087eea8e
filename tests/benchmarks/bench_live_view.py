"""What the live view costs the pipeline (plain script; not collected by pytest).

Run:  .venv/bin/python tests/benchmarks/bench_live_view.py [--seconds 10] [--repeat 2]

The seed paraglider board (profiles/seed-paraglider-vario.yaml), emulated flying ``thermal``,
is run with and without the dashboard; "with" means ``LiveView`` serving at 30 Hz to one
browser-like client that reads every message (and discards it) and one client that
connected and stopped reading (it stays connected for the whole run: its send times out
after 60 s). Each case is measured after the first simulated second (class ``Rate``), the
runs interleaved (without, with, without, ...)
and the best of ``--repeat`` kept, so a neighbour's load hits both alike.

* ``real time``: paced against the wall clock (``--realtime``, what a board does): the
  issue's target is that the two rates differ by less than 5 %.
* ``free-running``: as fast as the machine goes, measured in samples per CPU second of the
  whole process; the ratio is the dashboard's whole CPU cost (sink, publisher, two client
  threads) relative to the pipeline's.

Exit 1 when the real-time rates differ by 5 % or more.
"""

from __future__ import annotations

import argparse
import socket
import sys
import threading
import time
from pathlib import Path
from urllib.parse import urlsplit

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from imuhal.core.samples import Sample
from imuhal.emulation import open_emulated
from imuhal.live import LiveView
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile


class Rate:
    """A sink counting samples per wall second from ``SKIP_S`` of simulated time on (past
    the start-up phase, and past any head start the simulated clock took while the view
    was starting: a paced clock catches up on it)."""

    SKIP_S = 1.0

    def __init__(self, clock=time.perf_counter) -> None:
        self.clock = clock
        self.start: tuple[float, int] | None = None
        self.samples = 0
        self.end = 0.0

    def handle(self, event: object) -> None:
        if not isinstance(event, Sample):
            return
        self.samples += 1
        if self.start is None and event.t_ns >= self.SKIP_S * 1e9:
            self.start = (self.clock(), self.samples)
        self.end = self.clock()

    def close(self) -> None:
        pass

    def per_s(self) -> float:
        assert self.start is not None
        return (self.samples - self.start[1]) / (self.end - self.start[0])


def run_once(seconds: float, *, realtime: bool, live: bool) -> float:
    registry = load_registry()
    profile = load_profile(default_profile_path(), registry)
    with open_emulated(profile, registry, scenario="thermal", seed=5,
                       realtime=realtime) as pipeline:
        # Paced runs: wall time (the pace kept). Free-running: CPU time of the whole process,
        # the dashboard's threads included, which a neighbour's load disturbs far less.
        rate = Rate(time.perf_counter if realtime else time.process_time)
        if not live:
            pipeline.run(seconds, [rate])
            return rate.per_s()
        with LiveView.for_pipeline(pipeline, rate_hz=30.0, client_timeout_s=60.0) as view:
            parts = urlsplit(view.url)
            stalled = socket.create_connection((parts.hostname, parts.port))
            stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            stalled.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            received = [0]
            reading = socket.create_connection((parts.hostname, parts.port))
            reading.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")

            def read() -> None:
                # A fast browser, out of this process in real life: it reads and discards
                # (parsing JSON here would bill the viewer's work to the board).
                while chunk := reading.recv(1 << 16):
                    received[0] += chunk.count(b"\ndata: ")

            reader = threading.Thread(target=read, daemon=True)
            reader.start()
            time.sleep(0.3)
            pipeline.run(seconds, [rate, view.sink])
            connected = view.clients
            stalled.close()
            reading.close()
        if connected != 2 or received[0] < 5:
            raise SystemExit(f"the clients did not stay connected ({connected}) or the "
                             f"reader got only {received[0]} messages")
        return rate.per_s()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0,
                        help="simulated seconds per run (default 10)")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    results = {}
    for realtime in (True, False):
        best = {False: 0.0, True: 0.0}
        for _ in range(args.repeat):
            for live in (False, True):
                best[live] = max(best[live], run_once(args.seconds, realtime=realtime,
                                                      live=live))
        name = "real time" if realtime else "free-running"
        ratio = best[True] / best[False]
        results[name] = ratio
        unit = "samples/s" if realtime else "samples/CPU s"
        print(f"{name:13s} without {best[False]:9.1f} {unit}   with dashboard + stalled "
              f"client {best[True]:9.1f} {unit}   ratio {ratio:.3f} "
              f"({(ratio - 1) * 100:+.1f} %)")
    ok = abs(results["real time"] - 1.0) < 0.05
    print("real-time pace kept within 5 %" if ok else "real-time pace NOT kept within 5 %")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
