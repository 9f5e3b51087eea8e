"""What the page receives over server-sent events is what the pipeline produced."""

from __future__ import annotations

import math
import threading

from tests.support.sse import sse_messages

from imuhal.core.samples import Sample
from imuhal.emulation import EmulatedBoard, open_emulated
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.live import LiveView


def test_every_message_matches_the_pipeline_events_at_its_time(plugins, seed_board):
    """Attitude, vertical estimates, sensor values and sample counts in each SSE message
    are exactly those of the pipeline's events at the message's timestamps."""
    events: list = []
    with open_emulated(seed_board, plugins, scenario="thermal", realtime=True,
                       seed=3) as pipeline, \
            LiveView(pipeline, truth=EmulatedBoard.of(pipeline)) as live:
        def run() -> None:
            for event in pipeline.events(1.6):
                events.append(event)
                live.sink.handle(event)
            live.sink.close()

        runner = threading.Thread(target=run)
        runner.start()
        messages = []
        for msg in sse_messages(live.url + "events", timeout_s=8):
            if msg["t_s"] is not None:
                messages.append(msg)
            if msg["ended"]:
                break
        runner.join()
    by_time = {}
    for e in events:
        key = e.device if isinstance(e, Sample) else e.source
        by_time[(key, type(e).__name__, e.t_ns)] = e
    assert len(messages) >= 15  # 1.6 s at 20 Hz, whatever the start-up phase took
    checked = 0
    for msg in messages:
        for name, att in msg["attitude"].items():
            event = by_time[(name, "AttitudeEstimate", round(att["t_s"] * 1e9))]
            assert isinstance(event, AttitudeEstimate)
            roll, pitch, yaw = event.roll_pitch_yaw_deg
            assert (att["roll_deg"], att["pitch_deg"]) == (roll, pitch)
            assert att["heading_deg"] == yaw % 360.0
            checked += 1
        for name, vert in msg["vertical"].items():
            event = by_time[(name, "VerticalEstimate", round(vert["t_s"] * 1e9))]
            assert isinstance(event, VerticalEstimate)
            assert (vert["altitude_m"], vert["climb_m_s"]) == (event.altitude_m,
                                                               event.climb_m_s)
            checked += 1
        for device, channels in msg["sensors"].items():
            for channel, entry in channels.items():
                matches = [e for e in events if isinstance(e, Sample) and e.device == device
                           and e.channel.value == channel
                           and e.t_ns == round(entry["value_t_s"] * 1e9)]
                value = getattr(matches[-1], "vector", None) or [matches[-1].scalar]
                assert list(value) == (entry["value"] if isinstance(entry["value"], list)
                                       else [entry["value"]])
                checked += 1
        t_ns = round(msg["t_s"] * 1e9)
        for device, health in msg["health"].items():
            before = sum(1 for e in events if isinstance(e, Sample) and e.device == device
                         and e.t_ns < t_ns)
            upto = sum(1 for e in events if isinstance(e, Sample) and e.device == device
                       and e.t_ns <= t_ns)
            assert before <= health["samples"] <= upto
    assert checked > 100
    last = messages[-1]
    assert last["ended"]
    assert set(last["attitude"]) == {"ahrs"}
    assert list(last["vertical"]) == ["vario", "baro-only"]  # the profile's order


def test_an_emulated_run_sends_its_truth_at_the_time_of_the_latest_event(plugins, seed_board):
    with open_emulated(seed_board, plugins, scenario="thermal", seed=3) as pipeline:
        live = LiveView(pipeline, truth=EmulatedBoard.of(pipeline))
        pipeline.run(0.5, [live.sink])
        state = live.snapshotter.snapshot()
    truth = pipeline.board.scenario.truth(state["truth"]["t_s"])
    assert state["truth"]["t_s"] == state["t_s"]  # the truth of the latest event's instant
    assert state["truth"]["climb_m_s"] == truth.climb_m_s
    assert state["board"] == {"profile": "seed-paraglider-vario", "scenario": "thermal",
                              "emulated": True}


def test_health_reports_configured_and_achieved_rates_per_channel(plugins, seed_board):
    with open_emulated(seed_board, plugins, scenario="static", seed=3) as pipeline:
        live = LiveView(pipeline, truth=EmulatedBoard.of(pipeline))
        # two snapshots 1.5 s apart give the rate over that span (2 s apart, the span sat on
        # the 2 s window's edge: the last event of a run then decided whether it counted)
        for _ in range(2):
            pipeline.run(1.5, [live.sink])
            state = live.snapshotter.snapshot()
    imu = state["health"]["imu"]
    # the rates the chips' stream specs report (read back from their registers)
    assert imu["configured_hz"] == {"gyro": 250.0, "accel": 250.0, "temperature": 10.0}
    assert math.isclose(imu["achieved_hz"]["gyro"], 250.0, rel_tol=0.02)
    assert state["health"]["baro"]["configured_hz"] == {"pressure": 50.0, "temperature": 50.0}
    assert state["health"]["mag"]["configured_hz"] == {"mag": 75.0}
    assert not any(h["stale"] or h["faulty"] for h in state["health"].values()), state["health"]


def test_a_diverged_estimate_reaches_the_page_as_null_not_as_invalid_json():
    from imuhal.estimation.outputs import VerticalEstimate

    with LiveView() as live:
        live.sink.handle(VerticalEstimate(t_ns=1, source="vario", altitude_m=float("nan"),
                                          climb_m_s=float("inf")))
        live._publish()
        message = next(sse_messages(live.url + "events", timeout_s=5))
    assert message["vertical"]["vario"] == {"t_s": 1e-9, "altitude_m": None,
                                            "climb_m_s": None}
