"""A GPS vario whose receiver is optional (``required: false``) flies on when the receiver
is silent: the pipeline looks for it in steps between the other devices' polls.

Before, a silent receiver cost the whole board: the first look (at start-up, with
retries) listened at each baud rate for 1.5 s, twice: the run began 6 s late (38 s with
10 % line noise, whose garbled bytes never repeat the same evidence), and every later look
(one a second) held the poll loop for seconds, so at 10 % line noise 3,599 of 3,800 IMU
frames were lost to host stalls in 20 s and no attitude was estimated.
"""

from __future__ import annotations

from imuhal.core.samples import PositionSample, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import ChipAbsent
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile
from imuhal.profile.model import BoardProfile

SILENT_UNTIL_S = 4.0
FLIGHT_S = 8.0


def _optional_gps(registry: Registry) -> BoardProfile:
    path = bundled_profiles()["seed-gps-vario.yaml"]
    text = path.read_text()
    assert "    driver: gnss\n" in text
    text = text.replace("    driver: gnss\n", "    driver: gnss\n    required: false\n")
    return parse_profile(text, str(path), registry)


def _attitudes(events: list[object]) -> int:
    return sum(isinstance(e, AttitudeEstimate) for e in events)


def test_a_silent_optional_receiver_costs_the_other_devices_nothing() -> None:
    registry = load_registry()
    profile = _optional_gps(registry)
    silent = ChipAbsent(device="gps", start_s=0.0, end_s=FLIGHT_S)
    with open_emulated(profile, registry, seed=1, faults=[silent]) as p:
        # the run starts after the other chips' own bring-up (resets: 115 ms), without
        # waiting for the receiver (6.1 s before)
        assert p.clock.now_ns() < 0.5e9
        events = list(p.events(FLIGHT_S))
        summary = p.summary()
    with open_emulated(profile, registry, seed=1) as p:
        talking = _attitudes(list(p.events(FLIGHT_S)))
    imu = summary.frames["imu"]
    assert imu["delivered"] == imu["produced"] >= 0.99 * FLIGHT_S * 200
    # the same attitudes as with the receiver talking, within the 1 % its epochs can move
    # (the magnetometer learner and GNSS-aided accelerometer learning see different inputs)
    assert abs(_attitudes(events) - talking) <= 0.01 * talking


def test_an_optional_receiver_that_starts_talking_joins_the_run() -> None:
    registry = load_registry()
    silent = ChipAbsent(device="gps", start_s=0.0, end_s=SILENT_UNTIL_S)
    with open_emulated(_optional_gps(registry), registry, seed=1, faults=[silent]) as p:
        events = list(p.events(FLIGHT_S))
        warnings = list(p.warnings)
    assert any(w.startswith("gps: not found at start-up") for w in warnings)
    found = [w for w in warnings if w.startswith("gps: found at t=")]
    assert len(found) == 1
    joined_s = float(found[0].removeprefix("gps: found at t=").split(" ")[0])
    # heard in the first listening window after it starts talking (1.5 s at each rate)
    assert SILENT_UNTIL_S <= joined_s < SILENT_UNTIL_S + 4.0
    fixes = [e for e in events if isinstance(e, PositionSample) and e.valid]
    assert fixes and min(e.t_ns for e in fixes) / 1e9 > joined_s


def test_a_talking_optional_receiver_is_found_without_a_warning() -> None:
    registry = load_registry()
    with open_emulated(_optional_gps(registry), registry, seed=1) as p:
        events = list(p.events(FLIGHT_S))
        warnings = list(p.warnings)
    assert not any(w.startswith("gps:") for w in warnings)
    assert any(isinstance(e, Sample) and e.device == "gps" and e.valid for e in events)
