"""The host_stall fault (issue 25 item 6): the pipeline process pauses before a poll, on a
schedule or at random, through the documented fault interface."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _run(registry: Registry, stall: HostStall, seconds: float = 3.0) -> tuple[int, dict]:
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    with open_emulated(profile, registry, seed=5, faults=[stall], calibrated=False) as p:
        list(p.events(seconds))
        stalls = p.board.faults.log.injected.get("imu", {}).get("host_stall", 0)
        return stalls, p.summary().frames


def test_a_scheduled_stall_pauses_the_host_every_period_and_its_frames_are_lost_to_it(
        registry: Registry) -> None:
    stall = HostStall(device="imu", start_s=0.5, end_s=2.5, every_s=0.5, stall_s=0.05)
    stalls, frames = _run(registry, stall)
    assert stalls == 4  # at 0.5, 1.0, 1.5 and 2.0 s
    # 50 ms at 200 Hz: the 10 frames measured during each stall are overwritten but the
    # newest, and the poll due at the stall's start never read its own
    assert frames["imu"]["lost_host_stall"] == 4 * 10
    assert frames["imu"]["delivered"] + 40 == frames["imu"]["produced"]
    # the magnetometer (100 Hz) waited as well
    assert frames["mag"]["lost_host_stall"] > 0


def test_random_stalls_come_at_about_their_rate(registry: Registry) -> None:
    stall = HostStall(device="imu", rate_hz=5.0, stall_s=0.002)
    stalls, _ = _run(registry, stall, seconds=6.0)
    assert 15 <= stalls <= 45  # Poisson, mean 30 over 6 s


def test_a_stall_needs_one_timing() -> None:
    with pytest.raises(ValidationError, match="exactly one of every_s"):
        HostStall(device="imu", stall_s=0.1)
    with pytest.raises(ValidationError, match="exactly one of every_s"):
        HostStall(device="imu", stall_s=0.1, every_s=1.0, rate_hz=1.0)
