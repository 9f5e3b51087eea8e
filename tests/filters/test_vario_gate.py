"""The innovation gate both variometers share (imuhal_filters.vario.gate)."""

from __future__ import annotations

import json

from imuhal_filters.vario.gate import InnovationGate


def _counts() -> dict[str, int]:
    return {"gated": 0, "reacquired": 0}


def test_an_innovation_within_sigma_standard_deviations_is_fused() -> None:
    gate, counts = InnovationGate(5.0, 0.0, 0.3), _counts()
    # variances in cm^2 (100 units per metre): sigma = sqrt(300 + 100) cm = 0.2 m
    assert gate.accept(0, 0.99, 300.0, 100.0, 100.0, lambda: None, counts)
    assert not gate.accept(1, 1.01, 300.0, 100.0, 100.0, lambda: None, counts)
    assert counts == {"gated": 1, "reacquired": 0}


def test_the_gate_never_closes_within_its_minimum() -> None:
    gate, counts = InnovationGate(5.0, 1.0, 0.3), _counts()
    assert gate.accept(0, 0.9, 0.0, 1e-4, 1.0, lambda: None, counts)


def test_altitudes_rejected_for_the_reacquire_time_are_a_new_level_taken_by_the_filter(
        ) -> None:
    gate, counts = InnovationGate(5.0, 0.0, 0.3), _counts()
    taken: list[int] = []
    flags = [gate.accept(t_ms * 1_000_000, 10.0, 0.01, 0.01, 1.0,
                         lambda t=t_ms: taken.append(t), counts)
             for t_ms in range(0, 400, 100)]
    assert flags == [False, False, False, True]
    assert taken == [300] and counts == {"gated": 3, "reacquired": 1}
    assert gate.rejected_since_ns is None


def test_a_fused_altitude_restarts_the_reacquire_timer() -> None:
    gate, counts = InnovationGate(5.0, 0.0, 0.3), _counts()
    gate.accept(0, 10.0, 0.01, 0.01, 1.0, lambda: None, counts)
    gate.accept(200_000_000, 0.0, 0.01, 0.01, 1.0, lambda: None, counts)
    assert not gate.accept(400_000_000, 10.0, 0.01, 0.01, 1.0, lambda: None, counts)
    assert counts["reacquired"] == 0


def test_without_a_sigma_there_is_no_gate() -> None:
    gate, counts = InnovationGate(None, 0.0, 0.3), _counts()
    assert gate.accept(0, 1e6, 0.0, 0.0, 1.0, lambda: None, counts)
    assert counts == {"gated": 0, "reacquired": 0}


def test_a_gate_that_refused_most_altitudes_of_the_last_second_is_unsettled() -> None:
    gate, counts = InnovationGate(5.0, 0.0, 10.0), _counts()
    for i in range(10):  # 0.0 .. 0.9 s: fused
        gate.accept(i * 100_000_000, 0.0, 0.01, 0.01, 1.0, lambda: None, counts)
    assert not gate.unsettled
    for i in range(10, 16):  # 1.0 .. 1.5 s: refused; the window holds 0.6 .. 1.5 s
        gate.accept(i * 100_000_000, 10.0, 0.01, 0.01, 1.0, lambda: None, counts)
    assert gate.unsettled
    gate.forget()
    assert not gate.unsettled


def test_one_refused_altitude_among_many_leaves_the_gate_settled() -> None:
    gate, counts = InnovationGate(5.0, 0.0, 0.3), _counts()
    for i in range(50):
        gate.accept(i * 20_000_000, 10.0 if i == 25 else 0.0, 0.01, 0.01, 1.0,
                    lambda: None, counts)
        assert not gate.unsettled
    assert counts["gated"] == 1


def test_the_gate_state_round_trips_through_json() -> None:
    gate, counts = InnovationGate(5.0, 0.0, 10.0), _counts()
    for i in range(4):
        gate.accept(i * 100_000_000, 10.0 * (i % 2), 0.01, 0.01, 1.0, lambda: None, counts)
    copy = InnovationGate(5.0, 0.0, 10.0)
    copy.load_dict(json.loads(json.dumps(gate.as_dict())))
    assert copy.as_dict() == gate.as_dict() and copy.unsettled == gate.unsettled
