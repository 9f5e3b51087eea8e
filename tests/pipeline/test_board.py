"""The pipeline sees a board only through the Board protocol (buses, clock, a hook before
each poll): it runs on any board, and only an emulated one knows a simulation."""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest
from tests.support.testchip import TC3Emulator

from imuhal.bus.base import Bus, BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import ImuhalError
from imuhal.core.samples import AccelSample
from imuhal.emulation import EmulatedBoard, open_emulated
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import parse_profile
from imuhal.sim.emulated_bus import EmulatedBus

PROFILE = """\
schema_version: 1
name: board-test
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}
devices:
  acc: {driver: tc3, bus: i2c1, address: 0x19, settings: {odr_hz: 50}}
"""


@dataclass
class BenchBoard:
    """A board of its own: one bus with a TC3 at 0x19 that nobody moves, and a record of
    every before-poll call."""

    clock: SimulatedClock = field(default_factory=SimulatedClock)
    polls: list[tuple[int, str]] = field(default_factory=list)

    def __post_init__(self) -> None:
        bus = EmulatedBus("bench", BusKind.I2C)
        bus.attach(0x19, TC3Emulator(clock=self.clock))
        self.buses: dict[str, Bus] = {"i2c1": bus}

    def before_poll(self, t_ns: int, device: str) -> int:
        assert self.clock.now_ns() == t_ns  # the pipeline moved the clock there first
        self.polls.append((t_ns, device))
        return t_ns  # poll on time


def test_the_pipeline_runs_on_any_board_and_calls_its_hook_before_every_poll(
        registry: Registry) -> None:
    board = BenchBoard()
    pipeline = Pipeline(parse_profile(PROFILE, "board.yaml", registry), registry, board)
    accel = [e for e in pipeline.events(0.1) if isinstance(e, AccelSample)]
    assert board.polls == [(i * 20_000_000, "acc") for i in range(5)]
    # One sample per poll; the bench board never hands the chip any physics.
    assert [s.t_ns for s in accel] == [t for t, _ in board.polls]
    assert all(s.accel_m_s2 == (0.0, 0.0, 0.0) for s in accel)


def test_the_emulated_board_of_a_pipeline_on_another_board_is_an_error(
        registry: Registry) -> None:
    pipeline = Pipeline(parse_profile(PROFILE, "board.yaml", registry), registry, BenchBoard())
    with pytest.raises(ImuhalError, match="not an emulated board"):
        EmulatedBoard.of(pipeline)


def test_open_emulated_gives_typed_access_to_its_board(registry: Registry) -> None:
    profile = parse_profile(PROFILE, "board.yaml", registry)
    with open_emulated(profile, registry, scenario="static") as pipeline:
        board = EmulatedBoard.of(pipeline)
        assert isinstance(board.emulators["acc"], TC3Emulator)
        assert board.scenario.name == "static"
