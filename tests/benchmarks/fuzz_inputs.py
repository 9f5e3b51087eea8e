"""Every input format the CLI reads, fuzzed at length (issue 26 item 5; plain script, not
collected by pytest). The suite runs the same strategies a few dozen cases per format
(tests/cli/test_fuzz_inputs.py); this runs ``--cases`` (default 2,000) per format and
reports the exit codes, the cases that were not clean (exit 70, a traceback, more than one
error line, a hang past tests.support.fuzzing.CASE_TIME_LIMIT_S) and the wall time.

Run:  nice .venv/bin/python tests/benchmarks/fuzz_inputs.py [--cases 2000] [--only csv]

Formats: recordings (``replay``), sample CSVs (``estimate madgwick``), sample and truth
CSVs (``evaluate``), truth CSVs (``run --replay-truth``), profiles (``profile check`` and
``run --emulate``; a profile check says ok must run), NMEA/UBX streams (the GNSS driver's
splitter and decoders: nothing but DecodeError). Seeded: hypothesis derandomized.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.support.fuzzing import (
    Outcome,
    damaged_recordings,
    gnss_streams,
    hostile_csv,
    hostile_profiles,
    run_cli,
    write,
)

from imuhal_chips.gnss.decode import DecodeError, decode_nmea, decode_ubx
from imuhal_chips.gnss.framing import StreamSplitter

PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "gy91.yaml"


class Tally:
    def __init__(self) -> None:
        self.codes: Counter[int] = Counter()
        self.unclean: list[str] = []

    def add(self, what: str, outcome: Outcome) -> None:
        self.codes[outcome.exit_code] += 1
        if not outcome.clean:
            self.unclean.append(f"{what}: exit {outcome.exit_code}: "
                                f"{outcome.stderr.strip().splitlines()[-1:]}")


def fuzz(cases: int, strategy: st.SearchStrategy, case: Callable[[object], None]) -> None:
    settings(max_examples=cases, derandomize=True, deadline=None, database=None,
             phases=[Phase.generate],
             suppress_health_check=list(HealthCheck))(given(strategy)(case))()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=2000)
    parser.add_argument("--only", default="")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="imuhal-fuzz-"))
    made = run_cli(["run", str(PROFILE), "--emulate", "thermal", "--duration", "1.2", "--quiet",
                    "--output", str(work / "log.csv"), "--samples", "--truth",
                    str(work / "truth.csv"), "--record", str(work / "rec.imr")])
    assert made.exit_code == 0, made
    truth_columns = (work / "truth.csv").read_text().splitlines()[0].split(",")
    good_recording = (work / "rec.imr").read_bytes()
    tallies: dict[str, Tally] = {}

    def recordings(data: bytes) -> None:
        case = write(work / "case.imr", data)
        tallies["recordings (replay)"].add(
            "replay", run_cli(["replay", str(case), "--quiet", "--output",
                               str(work / "o.csv")]))

    def estimate_csv(data: bytes) -> None:
        case = write(work / "case.csv", data)
        tallies["sample CSV (estimate)"].add(
            "estimate", run_cli(["estimate", "madgwick", str(case), "--output",
                                 str(work / "o.csv")]))

    def evaluate_csv(pair: tuple[bytes, bytes]) -> None:
        samples = write(work / "s.csv", pair[0])
        truth = write(work / "t.csv", pair[1])
        for log, truth_file in ((samples, work / "truth.csv"), (work / "log.csv", truth)):
            tallies["sample and truth CSV (evaluate)"].add(
                "evaluate", run_cli(["evaluate", str(log), "--truth", str(truth_file),
                                     "-e", "madgwick", "-q"]))

    def replay_truth(data: bytes) -> None:
        truth = write(work / "t.csv", data)
        tallies["truth CSV (run --replay-truth)"].add(
            "run --replay-truth", run_cli(["run", "--emulate", "replay", "--replay-truth",
                                           str(truth), "--quiet", "--duration", "0.3",
                                           "--output", str(work / "o.csv")]))

    def profiles(text: str) -> None:
        board = write(work / "board.yaml", text)
        checked = run_cli(["profile", "check", str(board)])
        ran = run_cli(["run", str(board), "--emulate", "thermal", "--duration", "0.2",
                       "--quiet", "--output", str(work / "o.csv")])
        tally = tallies["profiles (check, run)"]
        tally.add("run", ran)
        if checked.exit_code not in (0, 2) or "internal error" in checked.stderr:
            tally.unclean.append(f"profile check: exit {checked.exit_code}")
        elif checked.exit_code == 0 and ran.exit_code != 0:
            tally.unclean.append(f"check ok, run: {ran.stderr.strip().splitlines()[-1:]}")

    def gnss(reads: list[bytes]) -> None:
        splitter = StreamSplitter()
        outcome = Outcome(0, "")
        try:
            for chunk in reads:
                for kind, item in splitter.feed(chunk):
                    with contextlib.suppress(DecodeError):
                        decode_nmea(item) if kind == "nmea" else decode_ubx(item)
        except Exception as exc:
            outcome = Outcome(70, f"internal error: {type(exc).__name__}: {exc}")
        tallies["NMEA/UBX streams (GNSS decoder)"].add("gnss", outcome)

    formats: list[tuple[str, st.SearchStrategy, Callable[[object], None]]] = [
        ("recordings (replay)", damaged_recordings(good_recording), recordings),
        ("sample CSV (estimate)", hostile_csv(), estimate_csv),
        ("sample and truth CSV (evaluate)",
         st.tuples(hostile_csv(), hostile_csv(truth_columns)), evaluate_csv),
        ("truth CSV (run --replay-truth)", hostile_csv(truth_columns), replay_truth),
        ("profiles (check, run)", hostile_profiles(PROFILE.read_text()), profiles),
        ("NMEA/UBX streams (GNSS decoder)", gnss_streams(), gnss),
    ]
    print("| format | cases | exit 0 | exit 2 | not clean (exit 70, traceback, hang) | wall s |")
    print("|---|---|---|---|---|---|")
    failed = 0
    for name, strategy, case in formats:
        if args.only and args.only not in name:
            continue
        tallies[name] = Tally()
        t0 = time.perf_counter()
        fuzz(args.cases, strategy, case)  # type: ignore[arg-type]
        tally = tallies[name]
        wall = time.perf_counter() - t0
        print(f"| {name} | {sum(tally.codes.values())} | {tally.codes[0]} | {tally.codes[2]} | "
              f"{len(tally.unclean)} | {wall:.0f} |", flush=True)
        for line in sorted(set(tally.unclean))[:10]:
            print(f"    {line}", file=sys.stderr)
        failed += len(tally.unclean)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
