"""Bring-up checks: each motion about the right body axis with the right sign (NED)."""

from __future__ import annotations

import pytest

from imuhal.core.frames import parse_mount
from imuhal.core.samples import GyroSample, Quantity
from imuhal.emulation import open_emulated
from imuhal.live.mounts import (
    MOTION_BY_KEY,
    MOTIONS,
    Evidence,
    MotionRecorder,
    check,
    judge,
    motion_name,
    rotation_between,
    suggest_mount,
)

NOSE_UP = MOTION_BY_KEY["nose-up"]
ROLL_RIGHT = MOTION_BY_KEY["roll-right"]
TURN_RIGHT = MOTION_BY_KEY["turn-right"]


@pytest.mark.parametrize(("rotation", "name"), [
    ((0.0, 30.0, 0.0), "nose up"), ((0.0, -30.0, 0.0), "nose down"),
    ((30.0, 0.0, 0.0), "roll right"), ((-30.0, 0.0, 0.0), "roll left"),
    ((0.0, 0.0, 90.0), "turn right"), ((0.0, 0.0, -90.0), "turn left"),
    ((2.0, 3.0, 1.0), None)])
def test_a_body_rotation_is_named_by_its_axis_and_sign_in_ned(rotation, name):
    assert motion_name(rotation) == name


def test_a_gyro_passes_a_motion_about_the_right_axis_with_the_right_sign():
    assert judge(NOSE_UP, Evidence("imu", Quantity.GYRO, (1.0, 29.0, -2.0))).ok is True
    assert judge(ROLL_RIGHT, Evidence("imu", Quantity.GYRO, (30.0, 0.0, 0.0))).ok is True
    assert judge(TURN_RIGHT, Evidence("imu", Quantity.GYRO, (0.0, 0.0, 88.0))).ok is True


def test_a_gyro_with_the_wrong_sign_or_axis_fails_naming_what_it_saw():
    flipped = judge(NOSE_UP, Evidence("imu", Quantity.GYRO, (0.0, -30.0, 0.0)))
    assert flipped.ok is False and "nose down" in flipped.message and "'imu'" in flipped.message
    swapped = judge(NOSE_UP, Evidence("imu", Quantity.GYRO, (-30.0, 0.0, 0.0)))
    assert swapped.ok is False and "roll left" in swapped.seen


def test_too_small_a_motion_is_no_verdict():
    assert judge(NOSE_UP, Evidence("imu", Quantity.GYRO, (0.0, 4.0, 0.0))).ok is None


def test_gravity_turns_the_opposite_way_to_the_body():
    # Nose up 30 deg: level specific force (0, 0, -g) becomes (g sin30, 0, -g cos30).
    rot = rotation_between((0.0, 0.0, -9.81), (4.905, 0.0, -8.496))
    assert rot[1] == pytest.approx(30.0, abs=0.1)
    assert abs(rot[0]) < 1e-9 and abs(rot[2]) < 1e-9


def test_an_accelerometer_cannot_see_a_level_turn_so_it_gives_no_verdict_on_one():
    level = (0.0, 0.0, -1.0)
    unseen = judge(TURN_RIGHT, Evidence("imu", Quantity.ACCEL, (0.0, 0.0, 0.0), level))
    assert unseen.ok is None and "gravity" in unseen.message
    # What it shows then is its own error (or the user's tilt): reported, not judged.
    tilted = judge(TURN_RIGHT, Evidence("imu", Quantity.ACCEL, (12.0, 0.0, 0.0), level))
    assert tilted.ok is None and "roll right 12 deg" in tilted.message


def test_an_accelerometer_judges_the_tilts_it_can_see():
    level = (0.0, 0.0, -1.0)
    assert judge(NOSE_UP, Evidence("imu", Quantity.ACCEL, (0.0, 29.0, 0.0), level)).ok is True
    assert judge(NOSE_UP, Evidence("imu", Quantity.ACCEL, (0.0, -29.0, 0.0), level)).ok is False


def test_a_recorder_integrates_the_gyro_between_start_and_evidence():
    rec = MotionRecorder()
    rec.handle(GyroSample(t_ns=0, device="imu", gyro_rad_s=(0.0, 9.0, 0.0)))  # not recording
    rec.start()
    for i in range(101):  # 1 s at 0.5236 rad/s (30 deg/s) about body y
        rec.handle(GyroSample(t_ns=i * 10_000_000, device="imu", gyro_rad_s=(0.0, 0.5236, 0.0)))
    (evidence,) = rec.evidence()
    assert evidence.rotation_deg[1] == pytest.approx(30.0, abs=0.05)
    assert [v.ok for v in check(NOSE_UP, [evidence])] == [True]


def _verdicts(plugins, board, **mounts):  # the wrong-mount case: tests/live/test_live_cli.py
    """Every sensor's verdict on every motion of an emulated bring-up run."""
    with open_emulated(board, plugins, scenario="bringup", seed=2,
                       physical_mounts=mounts) as pipeline:
        phases = {p.name: p for p in pipeline.board.scenario.phases()}
        out = {}
        recorder = MotionRecorder()
        events = iter(pipeline.events(16.0))
        for motion in MOTIONS:
            phase = phases[motion.key]
            for event in events:
                if event.t_ns >= phase.start_s * 1e9:
                    break
            recorder.start()
            for event in events:
                recorder.handle(event)
                if event.t_ns >= phase.end_s * 1e9:
                    break
            out[motion.key] = {(v.device, v.channel.value): v.ok
                               for v in check(motion, recorder.evidence())}
    return out


def test_the_seed_board_passes_every_bring_up_motion(plugins, seed_board):
    verdicts = _verdicts(plugins, seed_board)
    for motion, by_sensor in verdicts.items():
        assert by_sensor[("imu", "gyro")] is True, motion
        assert False not in by_sensor.values(), (motion, by_sensor)
    assert verdicts["nose-up"][("imu", "accel")] is True
    assert verdicts["turn-right"][("mag", "mag")] is True
    assert verdicts["turn-right"][("imu", "accel")] is None  # a level turn: gravity stays


@pytest.mark.parametrize(("profile_mount", "real_mount", "board"), [
    ("-Y-X-Z", "-X+Y-Z", "+X+Y+Z"), ("+X+Y+Z", "+Y-X+Z", "+X+Y+Z"),
    ("-Y-X-Z", "-Y-X-Z", "+Y-X+Z"), ("+X-Y-Z", "+Z+X+Y", "-X-Y+Z")])
def test_the_three_motions_name_the_mount_the_chip_really_has(profile_mount, real_mount,
                                                             board):
    b = parse_mount(board)
    said, real = b @ parse_mount(profile_mount), b @ parse_mount(real_mount)
    seen = {m.key: tuple(30.0 * (said @ real.T)[:, m.axis]) for m in MOTIONS}
    assert suggest_mount(said, b, seen) == real_mount


def test_no_mount_is_suggested_from_an_unclear_motion():
    b = parse_mount("+X+Y+Z")
    seen = {"nose-up": (0.0, 30.0, 0.0), "roll-right": (20.0, 20.0, 0.0),
            "turn-right": (0.0, 0.0, 90.0)}
    assert suggest_mount(b, b, seen) is None
