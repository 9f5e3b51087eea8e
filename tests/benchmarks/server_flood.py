"""1,000 connections to the NMEA TCP port and to the live view against a running board
(issue 26 item 4; plain script, not collected by pytest).

Run:  .venv/bin/python tests/benchmarks/server_flood.py [--duration 10] [--connections 1000]

The seed GPS vario board (emulated, ``--realtime`` pacing, seed 1) runs ``--duration`` s
twice, feeding an NMEA TCP server and a live view: once undisturbed, once while a thread
opens ``--connections`` idle sockets to each server (and holds them). Reported per run:
wall time against the simulated time (pacing), the process's resident memory at the end,
its most open descriptors and threads, and what each server refused. The targets: pacing
and memory within 5 % of the undisturbed run, descriptors within the process limit. The
script raises its soft descriptor limit to the hard one, as a long-running service would.
"""

from __future__ import annotations

import argparse
import os
import resource
import socket
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from imuhal.emulation import open_emulated
from imuhal.live import LiveView
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sinks.flight.sink import FlightSink
from imuhal.sinks.flight.transports import TcpTransport


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def descriptors() -> int:
    return len(os.listdir("/proc/self/fd"))


def flood(ports: list[int], n: int, held: list[socket.socket], stop: threading.Event) -> None:
    """``n`` connections to each port, opened without waiting (non-blocking connects, as
    a flood would), then held idle."""
    for i in range(n):
        for port in ports:
            if stop.is_set():
                return
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.setblocking(False)
            s.connect_ex(("127.0.0.1", port))
            held.append(s)
        if i % 100 == 0:
            time.sleep(0.01)


def one_run(duration_s: float, connections: int) -> dict[str, float]:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    tcp = TcpTransport(0)
    held: list[socket.socket] = []
    stop = threading.Event()
    most = {"fds": 0.0, "threads": 0.0}

    def watch() -> None:
        while not stop.is_set():
            most["fds"] = max(most["fds"], descriptors() - len(held))
            most["threads"] = max(most["threads"], threading.active_count())
            time.sleep(0.05)

    with open_emulated(profile, registry, seed=1, realtime=True) as pipeline, \
            LiveView.for_pipeline(pipeline) as live:
        port = live._server.server_address[1]  # type: ignore[union-attr]
        threads = [threading.Thread(target=watch, daemon=True)]
        if connections:
            threads.append(threading.Thread(target=flood, args=([tcp.port, port], connections,
                                                                  held, stop), daemon=True))
        for t in threads:
            t.start()
        t0 = time.perf_counter()
        pipeline.run(duration_s, [FlightSink(transport=tcp), live.sink])
        wall = time.perf_counter() - t0
        stop.set()
        for t in threads:
            t.join(timeout=5.0)
        result = {"wall_s": wall, "rss_mb": rss_mb(), "most_fds": most["fds"],
                  "most_threads": most["threads"], "nmea_refused": tcp.refused_clients,
                  "live_refused": live.refused_connections,
                  "held": len(held)}
    for s in held:
        s.close()
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--connections", type=int, default=1000)
    args = parser.parse_args()
    _soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    limit = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    quiet = one_run(args.duration, 0)
    flooded = one_run(args.duration, args.connections)
    print(f"descriptor limit {limit}; {args.duration:g} s simulated, realtime, seed 1")
    print("| run | wall s | RSS MB | most descriptors (server side) | most threads | "
          "NMEA refused | live view refused | sockets the flood holds |")
    print("|---|---|---|---|---|---|---|---|")
    for name, r in (("undisturbed", quiet), (f"{args.connections} to each", flooded)):
        print(f"| {name} | {r['wall_s']:.2f} | {r['rss_mb']:.1f} | {r['most_fds']:.0f} | "
              f"{r['most_threads']:.0f} | {r['nmea_refused']:.0f} | {r['live_refused']:.0f} | "
              f"{r['held']:.0f} |")
    pacing = flooded["wall_s"] / quiet["wall_s"] - 1.0
    memory = flooded["rss_mb"] / quiet["rss_mb"] - 1.0
    print(f"pacing {pacing:+.1%}, memory {memory:+.1%} (targets within 5 %)")
    return 0 if abs(pacing) <= 0.05 and abs(memory) <= 0.05 else 1


if __name__ == "__main__":
    sys.exit(main())
