"""`imuhal replay --mqtt` and `imuhal estimate --mqtt` against a real mosquitto broker: a
recorded run published again under its board name with the live run's values, and a run log's
new estimates published beside its samples."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

pytest.importorskip("paho.mqtt.client", reason="the mqtt extra (paho-mqtt) is not installed")

from tests.support.mosquitto import Mosquitto, Subscriber, deduplicated, mosquitto_binary

if mosquitto_binary() is None:
    pytest.skip("mosquitto is not installed (apt-get install mosquitto)", allow_module_level=True)

from imuhal.cli.main import main
from imuhal.profile.bundled import bundled_profiles

pytestmark = pytest.mark.slow

VARIO = str(bundled_profiles()["seed-paraglider-vario.yaml"])


@pytest.fixture
def broker(tmp_path: Path):
    with Mosquitto(tmp_path / "broker") as b:
        yield b


def _published(stderr: str) -> int:
    line = next(x for x in stderr.splitlines() if x.strip().startswith("mqtt: published"))
    return int(line.split("published", 1)[1].split(",", 1)[0])


def test_a_replayed_recording_publishes_the_live_runs_values_under_its_board(
        tmp_path: Path, broker: Mosquitto, capsys: pytest.CaptureFixture[str]) -> None:
    recording, log = tmp_path / "run.imurec", tmp_path / "live.csv"
    assert main(["run", VARIO, "--emulate", "thermal", "--duration", "3", "--quiet",
                 "--skip-calibration", "--record", str(recording), "--output", str(log)]) == 0
    sub = Subscriber(broker.port)
    sub.start()
    capsys.readouterr()
    try:
        assert main(["replay", str(recording), "--quiet", "--mqtt", broker.url,
                     "--sink-set", "mqtt.board=replayed-7",
                     "--sink-set", f"mqtt.queue_path={tmp_path}/queue.sqlite",
                     "--sink-set", "mqtt.streams=vario/*"]) == 0
        published = _published(capsys.readouterr().err)
        got = sub.wait_for(published)
    finally:
        sub.stop()
    with log.open(newline="") as f:
        live = [r for r in csv.DictReader(f) if r["source"] == "vario"]
    per_topic = deduplicated(got)
    assert set(per_topic) == {"imuhal/replayed-7/vario/vertical"}
    messages = per_topic["imuhal/replayed-7/vario/vertical"]
    assert published == len(live) == len(messages) > 100
    assert [m.payload["seq"] for m in messages] == list(range(len(messages)))
    for m, row in zip(messages[::20], live[::20], strict=True):
        assert m.payload["t_s"] == pytest.approx(float(row["t_s"]), abs=1e-6)
        if row["climb_m_s"]:
            assert m.payload["climb_m_s"] == pytest.approx(float(row["climb_m_s"]), abs=1e-6)
        else:  # the vario's start-up withholds its first estimates: no value, as live
            assert "climb_m_s" not in m.payload


def test_estimate_publishes_the_new_estimates_beside_the_logs_samples(
        tmp_path: Path, broker: Mosquitto, capsys: pytest.CaptureFixture[str]) -> None:
    log, out = tmp_path / "flight.csv", tmp_path / "estimates.csv"
    assert main(["run", VARIO, "--emulate", "thermal", "--duration", "3", "--quiet",
                 "--skip-calibration", "--samples", "--output", str(log)]) == 0
    sub = Subscriber(broker.port)
    sub.start()
    capsys.readouterr()
    try:
        assert main(["estimate", "baro-vario", str(log), "--output", str(out), "--mqtt",
                     broker.url, "--sink-set", f"mqtt.queue_path={tmp_path}/queue.sqlite",
                     "--sink-set", "mqtt.streams=*/vertical,baro/pressure"]) == 0
        err = capsys.readouterr().err
        got = sub.wait_for(_published(err))
    finally:
        sub.stop()
    per_topic = deduplicated(got)
    # the board is the input log's name; the estimator's own name is its source
    assert set(per_topic) == {"imuhal/flight/baro/pressure", "imuhal/flight/baro-vario/vertical"}
    with out.open(newline="") as f:
        estimates = list(csv.DictReader(f))
    sent = per_topic["imuhal/flight/baro-vario/vertical"]
    assert len(sent) == len(estimates)
    # the filter's start-up withholds its first estimates: no value in either
    assert [m.payload.get("climb_m_s") for m in sent[::25]] == pytest.approx(
        [float(r["climb_m_s"]) if r["climb_m_s"] else None for r in estimates[::25]], abs=1e-6)


def test_streaming_a_wide_csv_is_one_error_naming_the_run_log_it_needs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    wide = tmp_path / "wide.csv"
    wide.write_text("t_s,pressure_pa\n0.0,95000\n0.1,95001\n")
    assert main(["estimate", "baro-vario", str(wide), "--output", str(tmp_path / "o.csv"),
                 "--mqtt", "mqtt://127.0.0.1:1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--mqtt: needs a run log as INPUT" in err[0]
