"""Buffered frames stamped from the chip's data-ready edges (imuhal.drivers.edge_stamps):
frames and edges pair in order, whatever the number of edges per read, a FIFO reset's edges
are never paired, frames wait briefly for late edges, a silent line is bridged on the
learned period, and stamps never go back."""

from __future__ import annotations

from itertools import pairwise

import pytest

from imuhal.drivers.edge_stamps import EdgeStamps

P = 5_000_000  # 200 Hz


def _edges(first: int, n: int, period: int = P) -> list[int]:
    return [first + i * period for i in range(n)]


def test_each_frame_gets_its_own_edge_however_many_edges_go_to_one_read() -> None:
    stamps = EdgeStamps(P)
    out: list[int] = []
    edges = _edges(1_000, 12)
    for chunk in (edges[:1], edges[1:3], edges[3:10], edges[10:]):  # 1, 2, 7, 2 a read
        stamps.add(chunk)
        out += stamps.match(len(chunk))
    assert out == edges


def test_edges_of_frames_a_reset_cleared_are_never_paired() -> None:
    stamps = EdgeStamps(P)
    stamps.add(_edges(0, 3))
    stamps.cleared(12_000_000)  # the reset was asked for at 12 ms
    stamps.add([10_000_000, 14_000_000])  # the first came before the reset
    assert stamps.match(1) == [14_000_000]


def test_an_edge_between_a_resets_request_and_its_effect_is_dropped_as_surplus() -> None:
    stamps = EdgeStamps(P)
    stamps.cleared(0)
    stamps.add([1_000, 5_001_000])  # the first edge's frame went with the reset
    assert stamps.match(1) == [5_001_000]
    assert stamps.surplus_edges == 1


def test_frames_newer_than_the_last_edge_wait_for_theirs() -> None:
    stamps = EdgeStamps(P)
    stamps.add(_edges(0, 2))
    assert stamps.match(3) == _edges(0, 2)  # the third frame came after the edges were taken
    stamps.add(_edges(2 * P, 1))
    assert stamps.match(1) == [2 * P]


def test_a_silent_line_is_bridged_on_the_learned_period_and_edges_coming_back_back_date(
        ) -> None:
    period = 5_050_000  # the chip runs 1 % slow
    stamps = EdgeStamps(P, wait_frames=4)
    stamps.add(_edges(0, 20, period))
    out = stamps.match(20)
    stamps.silent()
    out += stamps.extrapolate(6)  # six frames without edges
    assert out[20:] == [out[19] + (i + 1) * period for i in range(6)]
    # the line returns: three frames older than its first edge, back-dated from it
    back = 40 * period + 300_000  # the silence lasted longer than the bridge
    stamps.add([back + period, back + 2 * period])
    out += stamps.match(5)
    assert out[-2:] == [back + period, back + 2 * period]
    assert out[-5:-2] == [back + period - (3 - i) * period for i in range(3)]
    assert all(b > a for a, b in pairwise(out))


def test_stamps_never_go_back_even_when_an_edge_does() -> None:
    stamps = EdgeStamps(P)
    stamps.add([10_000_000, 9_000_000])
    first, second = stamps.match(2)
    assert second > first


def test_frames_handed_out_before_their_edges_do_not_take_the_next_frames_edges() -> None:
    stamps = EdgeStamps(P)
    stamps.add(_edges(0, 4))
    stamps.match(4)
    assert stamps.extrapolate(2) == [4 * P, 5 * P]  # the run ended with two frames held
    stamps.add(_edges(4 * P, 3))  # their edges, then the next frame's
    assert stamps.match(1) == [6 * P]


def test_nothing_to_extrapolate_from_is_an_error() -> None:
    with pytest.raises(ValueError, match="match an edge first"):
        EdgeStamps(P).extrapolate(1)
