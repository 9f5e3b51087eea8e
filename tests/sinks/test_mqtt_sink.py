"""The MQTT sink without a broker: the broker URL and its credentials, the topic and payload
of an event, which events a decimated stream publishes, and the user's mistakes."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from imuhal.cli.main import main
from imuhal.core.errors import ImuhalError, ProfileError
from imuhal.core.samples import AccelSample, Frame, PressureSample
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile
from imuhal.sinks.builtin import event_row
from imuhal.sinks.mqtt.broker import PASSWORD_ENV, USERNAME_ENV, parse_broker_url
from imuhal.sinks.mqtt.payload import StreamSelector, encode, stream_of, topic_level
from imuhal.sinks.mqtt.sink import MqttSettings, default_client_id

GPS_VARIO = bundled_profiles()["seed-gps-vario.yaml"]


def test_a_plain_url_defaults_to_port_1883_and_mqtts_to_tls_on_8883() -> None:
    plain = parse_broker_url("mqtt://broker.local", {})
    assert (plain.host, plain.port, plain.tls, plain.username) == ("broker.local", 1883,
                                                                   False, None)
    tls = parse_broker_url("mqtts://broker.local", {})
    assert (tls.port, tls.tls) == (8883, True)
    assert parse_broker_url("mqtt://[::1]:1884", {}).display() == "mqtt://[::1]:1884"


def test_credentials_come_from_the_url_or_else_the_environment_and_are_never_shown() -> None:
    env = {USERNAME_ENV: "fleet", PASSWORD_ENV: "env-secret"}
    in_url = parse_broker_url("mqtts://pilot:p%40ss@broker:8884", env)
    assert (in_url.username, in_url.password) == ("pilot", "p@ss")
    from_env = parse_broker_url("mqtts://broker", env)
    assert (from_env.username, from_env.password) == ("fleet", "env-secret")
    for broker in (in_url, from_env):
        shown = broker.display() + repr(broker)
        assert "p@ss" not in shown and "secret" not in shown and "pilot" not in shown
    assert "secret" not in repr(MqttSettings(url="mqtt://a:secret@b"))


@pytest.mark.parametrize(("url", "message"), [
    ("http://broker", "must start with mqtt:// or mqtts://"),
    ("broker:1883", "must start with mqtt://"),
    ("mqtt://:1883", "names no host"),
    ("mqtt://broker:99999", "port is not a number"),
    ("mqtt://broker/topic", "has a path"),
])
def test_a_wrong_url_is_one_error_that_never_repeats_it(url: str, message: str) -> None:
    with pytest.raises(ImuhalError, match=message) as info:
        parse_broker_url(url.replace("//", "//u:hunter2@") if "//" in url else url, {})
    assert "hunter2" not in str(info.value)


def test_a_password_without_a_user_name_in_the_environment_is_refused() -> None:
    with pytest.raises(ImuhalError, match=f"{PASSWORD_ENV} is set but {USERNAME_ENV}"):
        parse_broker_url("mqtt://broker", {PASSWORD_ENV: "x"})


def test_the_payload_is_the_csv_row_with_run_seq_and_unix_time_as_json_numbers() -> None:
    accel = AccelSample(t_ns=1_500_000_000, device="imu", frame=Frame.BODY_NED,
                        accel_m_s2=(0.25, float("nan"), -9.81))
    assert stream_of(accel) == "imu/accel"
    payload = json.loads(encode(event_row(accel), run=1700000000000, seq=41,
                                unix_s=1700000001.25))
    assert payload == {"run": 1700000000000, "seq": 41, "unix_s": 1700000001.25, "t_s": 1.5,
                       "flags": 0, "ax_m_s2": 0.25, "ay_m_s2": None, "az_m_s2": -9.81}
    level = AttitudeEstimate(t_ns=0, source="ahrs", q_body_to_ned=(1.0, 0.0, 0.0, 0.0))
    assert stream_of(level) == "ahrs/attitude"
    enu = json.loads(encode(event_row(level, "enu"), run=1, seq=0, unix_s=0.0))
    # the run's output frame names the columns: body FLU -> ENU, a level board facing north
    assert math.isclose(enu["yaw_deg_enu"], 90.0) and "qw" not in enu
    assert stream_of(VerticalEstimate(t_ns=0, source="vario", altitude_m=1.0,
                                      climb_m_s=0.0)) == "vario/vertical"


def test_a_name_with_topic_wildcards_or_separators_becomes_one_topic_level() -> None:
    assert topic_level("my board/#1+") == "my_board__1_"
    assert stream_of(PressureSample(t_ns=0, device="baro/2", pressure_pa=1e5)) == \
        "baro_2/pressure"
    assert default_client_id("glider 7") .startswith("imuhal-glider_7-")
    assert default_client_id("glider 7") == default_client_id("glider 7")


def test_decimation_publishes_every_nth_event_of_a_stream_from_the_first() -> None:
    selector = StreamSelector(("*",), {"imu/*": 4, "*/accel": 2})
    taken = [selector.take("imu/accel") for _ in range(9)]
    assert taken == [True, False, False, False, True, False, False, False, True]  # first match
    assert [selector.take("mag/accel") for _ in range(3)] == [True, False, True]
    assert all(selector.take("ahrs/attitude") for _ in range(3))


def test_streams_not_chosen_are_not_published() -> None:
    selector = StreamSelector(("ahrs/*", "*/pressure"), {})
    assert selector.take("ahrs/attitude") and selector.take("baro/pressure")
    assert not selector.take("imu/accel")


def test_decimation_and_streams_read_from_the_command_line_form() -> None:
    s = MqttSettings.model_validate({"decimate": ["imu/*:10", "mag/*:5"], "streams": "ahrs/*"})
    assert s.decimate == {"imu/*": 10, "mag/*": 5} and s.streams == ("ahrs/*",)
    with pytest.raises(ValueError, match="write PATTERN:N"):
        MqttSettings.model_validate({"decimate": "imu/*"})
    with pytest.raises(ValueError, match="N must be 1 or more"):
        MqttSettings.model_validate({"decimate": {"imu/*": 0}})


def test_a_wrong_broker_url_on_the_command_line_is_one_line_and_exit_2(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(GPS_VARIO), "--emulate", "thermal", "--duration", "1", "--quiet",
                 "--mqtt", "http://user:hunter2@broker"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("imuhal: error: --mqtt: the broker URL must")
    assert "hunter2" not in err[0]


def test_a_wrong_mqtt_setting_on_the_command_line_names_it(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(GPS_VARIO), "--emulate", "thermal", "--duration", "1", "--quiet",
                 "--mqtt", "mqtt://localhost", "--sink-set", "mqtt.queue_max_mesages=5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("imuhal: error: --sink-set mqtt.queue_max_mesages: sink 'mqtt' "
                              "has no such setting")


def test_the_profile_outputs_section_is_checked_by_the_sink_s_own_settings() -> None:
    text = Path(GPS_VARIO).read_text(encoding="utf-8")
    registry = load_registry()
    good = parse_profile(text + "outputs:\n  mqtt:\n    board: glider-7\n"
                         "    decimate: {'imu/*': 10}\n", "p.yaml", registry)
    assert good.outputs.plugin_sections() == {"mqtt": {"board": "glider-7",
                                                  "decimate": {"imu/*": 10}}}
    lines = len(text.splitlines())
    with pytest.raises(ProfileError) as info:
        parse_profile(text + "outputs:\n  mqtt:\n    queue_max_messages: 0\n  kafka: {}\n",
                      "p.yaml", registry)
    problems = "\n".join(info.value.problems)
    assert f"p.yaml:{lines + 3}:" in problems and "outputs.mqtt.queue_max_messages" in problems
    assert "outputs.kafka: no sink named 'kafka' is installed" in problems


def test_the_mqtt_sink_is_a_plugin_registered_through_the_entry_points() -> None:
    registration = load_registry().sinks.entries["mqtt"]
    assert registration.plugin == "sinks" and registration.package == "imuhal"
