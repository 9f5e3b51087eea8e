"""Every input format the CLI reads, fuzzed (issue 26 item 5): recordings (replay), sample
CSVs (estimate, evaluate), truth CSVs (evaluate, run --replay-truth), board profiles
(profile check and run) and the GNSS receiver's NMEA/UBX stream. A case passes when the
command exits 0, or 2 with one ``imuhal: error:`` line; exit 70, a traceback or a hang
fails. Seeded (derandomized) and a few dozen cases per format; the 2,000-case run is
tests/benchmarks/fuzz_inputs.py.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from tests.support.fuzzing import (
    Hang,
    damaged_recordings,
    gnss_streams,
    hostile_csv,
    hostile_profiles,
    recording_chunks,
    recording_of,
    run_cli,
    time_limit,
    ubx_frame,
    write,
)

from imuhal_chips.gnss.decode import DecodeError, decode_nmea, decode_ubx
from imuhal_chips.gnss.framing import StreamSplitter

PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "gy91.yaml"
FUZZ = settings(max_examples=25, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow, HealthCheck.data_too_large])


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short GY-91 run's sample log, truth and bus recording."""
    d = tmp_path_factory.mktemp("fuzz")
    outcome = run_cli(["run", str(PROFILE), "--emulate", "thermal", "--duration", "1.2",
                       "--quiet", "--output", str(d / "log.csv"), "--samples",
                       "--truth", str(d / "truth.csv"), "--record", str(d / "rec.imr")])
    assert outcome.exit_code == 0, outcome.stderr
    return d


def _check(outcome_of: str, outcome: object) -> None:
    assert outcome.clean, f"{outcome_of}: {outcome}"


@FUZZ
@given(data=st.data())
def test_a_damaged_recording_is_replayed_or_refused_in_one_line(
        made: Path, tmp_path: Path, data: st.DataObject) -> None:
    """Cuts (including within the first second), flipped bits, records garbled under a
    correct CRC, crafted headers."""
    case = write(tmp_path / "case.imr",
                 data.draw(damaged_recordings((made / "rec.imr").read_bytes())))
    _check("replay", run_cli(["replay", str(case), "--quiet",
                              "--output", str(tmp_path / "out.csv")]))


@FUZZ
@given(data=st.data())
def test_a_hostile_sample_csv_is_estimated_or_refused_in_one_line(
        tmp_path: Path, data: st.DataObject) -> None:
    """Times of 1e300 or inf, cells over the csv module's 131,072-character limit, bytes
    that are not UTF-8, columns missing or repeated."""
    case = write(tmp_path / "case.csv", data.draw(hostile_csv()))
    for estimator in ("madgwick", "vario-kf3"):
        _check(f"estimate {estimator}", run_cli(["estimate", estimator, str(case),
                                                 "--output", str(tmp_path / "o.csv")]))


@FUZZ
@given(data=st.data())
def test_hostile_sample_and_truth_csvs_are_evaluated_or_refused_in_one_line(
        made: Path, tmp_path: Path, data: st.DataObject) -> None:
    samples = write(tmp_path / "s.csv", data.draw(hostile_csv()))
    truth_columns = (made / "truth.csv").read_text().splitlines()[0].split(",")
    truth = write(tmp_path / "t.csv", data.draw(hostile_csv(truth_columns)))
    for log, truth_file in ((samples, made / "truth.csv"), (made / "log.csv", truth)):
        _check("evaluate", run_cli(["evaluate", str(log), "--truth", str(truth_file),
                                    "-e", "madgwick", "-q"]))


@FUZZ
@given(data=st.data())
def test_a_hostile_truth_is_replayed_or_refused_in_one_line(
        made: Path, tmp_path: Path, data: st.DataObject) -> None:
    truth_columns = (made / "truth.csv").read_text().splitlines()[0].split(",")
    truth = write(tmp_path / "t.csv", data.draw(hostile_csv(truth_columns)))
    _check("run --replay-truth", run_cli(
        ["run", "--emulate", "replay", "--replay-truth", str(truth), "--quiet",
         "--duration", "0.3", "--output", str(tmp_path / "o.csv")]))


@FUZZ
@given(data=st.data())
def test_a_profile_that_profile_check_accepts_runs_and_one_it_refuses_is_one_line(
        tmp_path: Path, data: st.DataObject) -> None:
    """Profile check runs every check run runs: ``ok`` means the emulated run starts."""
    case = write(tmp_path / "board.yaml", data.draw(hostile_profiles(PROFILE.read_text())))
    checked = run_cli(["profile", "check", str(case)])
    assert checked.exit_code in (0, 2) and "internal error" not in checked.stderr, checked
    ran = run_cli(["run", str(case), "--emulate", "thermal", "--duration", "0.2", "--quiet",
                   "--output", str(tmp_path / "o.csv")])
    _check("run", ran)
    if checked.exit_code == 0:
        assert ran.exit_code == 0, f"profile check said ok, run said {ran.stderr}"


@settings(max_examples=300, derandomize=True, deadline=None, database=None)
@given(reads=gnss_streams())
def test_a_hostile_gnss_stream_decodes_or_is_refused_as_a_decode_error(
        reads: list[bytes]) -> None:
    """NMEA sentences and UBX frames with correct checksums and hostile fields, corrupted
    ones and noise: the driver's splitter and decoders raise nothing but DecodeError (which
    the driver counts), and what they decode is finite."""
    splitter = StreamSplitter()
    for chunk in reads:
        for kind, item in splitter.feed(chunk):
            try:
                fragment = decode_nmea(item) if kind == "nmea" else decode_ubx(item)
            except DecodeError:
                continue
            numbers = [v for v in vars(fragment).values() if isinstance(v, float)]
            numbers += list(fragment.velocity_ned_m_s or ())
            assert all(math.isfinite(v) for v in numbers), fragment


# -- the cases issue 26 item 5 found, each one line with exit 2 --------------------------

def _garbled_recording(good: bytes) -> bytes:
    """A records chunk with a correct CRC whose bus record announces a 5-byte name and
    ends (the reader ran off the chunk: IndexError)."""
    header = recording_chunks(good)[0]
    return recording_of(good[:10], [header, b"\x03\x01\x00\x05"])


def _profile_with(old: str, new: str) -> str:
    text = PROFILE.read_text()
    assert old in text
    return text.replace(old, new, 1)


KNOWN_PROFILES = {
    "a negative seed": (_profile_with("  seed: 1", "  seed: -1"), "emulation.seed"),
    "a binary bus": (_profile_with("    bus: i2c1", "    bus: !!binary AAAA"), "binary"),
    "nested 500 deep": ("schema_version: 1\nname: x\nbuses: " + "[" * 500 + "]" * 500,
                        "nested more than"),
    "a complex key": ("schema_version: 1\nname: x\n? key: 4096\n: 3\n", "a key must be"),
    "unknown scenario params": (_profile_with("  scenario: thermal",
                                              "  scenario: thermal\n  scenario_params: {x: 1}"),
                                "scenario_params.x"),
}


@pytest.mark.parametrize("case", sorted(KNOWN_PROFILES))
def test_a_known_bad_profile_fails_profile_check_and_run_in_one_line(
        case: str, tmp_path: Path) -> None:
    text, names = KNOWN_PROFILES[case]
    board = write(tmp_path / "board.yaml", text)
    checked = run_cli(["profile", "check", str(board)])
    assert checked.exit_code == 2 and names in checked.stdout, checked
    ran = run_cli(["run", str(board), "--emulate", "thermal", "--duration", "0.2", "--quiet",
                   "--output", str(tmp_path / "o.csv")])
    assert ran.clean and ran.exit_code == 2 and names in ran.stderr, ran


def test_a_recording_with_garbled_records_under_a_correct_crc_is_one_line(
        made: Path, tmp_path: Path) -> None:
    case = write(tmp_path / "g.imr", _garbled_recording((made / "rec.imr").read_bytes()))
    outcome = run_cli(["replay", str(case), "--quiet", "--output", str(tmp_path / "o.csv")])
    assert outcome.clean and outcome.exit_code == 2, outcome
    assert "garbled records" in outcome.stderr


def test_a_recording_cut_in_its_first_second_says_so_instead_of_blaming_the_profile(
        made: Path, tmp_path: Path) -> None:
    good = (made / "rec.imr").read_bytes()
    header = recording_chunks(good)[0]
    case = write(tmp_path / "cut.imr", recording_of(good[:10], [header]))
    outcome = run_cli(["replay", str(case), "--quiet", "--output", str(tmp_path / "o.csv")])
    assert outcome.clean and outcome.exit_code == 2, outcome
    assert "holds no bus records" in outcome.stderr and "profile" not in outcome.stderr


def test_a_truth_cell_over_the_csv_field_limit_is_one_line(made: Path, tmp_path: Path) -> None:
    truth = (made / "truth.csv").read_text().splitlines()
    header = next(i for i, line in enumerate(truth) if not line.startswith("#"))
    truth[header + 1] = "9" * 140_000 + truth[header + 1][1:]
    case = write(tmp_path / "t.csv", "\n".join(truth) + "\n")
    outcome = run_cli(["evaluate", str(made / "log.csv"), "--truth", str(case),
                       "-e", "madgwick", "-q"])
    assert outcome.clean and outcome.exit_code == 2, outcome


def test_a_nav_pvt_with_a_good_checksum_and_an_impossible_date_is_a_decode_error() -> None:
    payload = bytearray(92)
    payload[6] = 13  # month 13
    payload[7] = 1
    with pytest.raises(DecodeError):
        decode_ubx(ubx_frame(0x01, 0x07, bytes(payload)))


def test_a_ubx_frame_whose_body_does_not_fit_its_message_is_a_decode_error() -> None:
    """Found by the 2,000-case run: a class 0x0A frame with a good checksum and a 2-byte
    body made pyubx2 index past it (IndexError: exit 70 in a run)."""
    with pytest.raises(DecodeError):
        decode_ubx(b"\xb5b\n1\x02\x00\x00\x01>:")


def test_the_hang_guard_stops_a_spinning_case_by_its_cpu_time() -> None:
    with pytest.raises(Hang, match="CPU"), time_limit(0.2, wall_seconds=30.0):
        while True:
            pass


def test_the_hang_guard_stops_a_blocked_case_by_the_wall_clock() -> None:
    started = time.monotonic()
    with pytest.raises(Hang), time_limit(30.0, wall_seconds=0.3):
        time.sleep(30.0)
    assert time.monotonic() - started < 10.0
