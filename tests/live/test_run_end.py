"""When the run ends the page is told so, with the run's summary, before the server stops:
a connected page shows "run ended" and the summary instead of a lost connection."""

from __future__ import annotations

import threading

from tests.support.sse import sse_messages

from imuhal.emulation import EmulatedBoard, open_emulated
from imuhal.live import LiveView


def test_a_connected_page_receives_the_end_and_the_summary_before_the_server_stops(
        plugins, seed_board):
    got: list[dict] = []
    with open_emulated(seed_board, plugins, scenario="thermal", realtime=True,
                       seed=3) as pipeline:
        live = LiveView(pipeline, truth=EmulatedBoard.of(pipeline)).start()
        reader = threading.Thread(
            target=lambda: got.extend(sse_messages(live.url + "events", timeout_s=15)))
        reader.start()
        summary = pipeline.run(1.0, [live.sink])  # closes the sink: the run ended
        live.close()  # the CLI's order: the server goes right after the run
        reader.join(timeout=20)
    ended = [m["ended"] for m in got]
    assert ended[-1] and ended == sorted(ended)  # once ended, ended for good
    last = got[-1]
    # the run's own summary: its span and counts per device and estimator (the wall time
    # is the view's, from the first event)
    assert last["ended"] and last["summary"][1:] == summary.describe().splitlines()[1:]
    assert last["summary"][0].startswith("ran 1.0 s in ")


def test_while_the_run_goes_there_is_no_summary(plugins, seed_board):
    with open_emulated(seed_board, plugins, scenario="thermal", seed=3) as pipeline, \
            LiveView(pipeline, truth=EmulatedBoard.of(pipeline)) as live:
        for event in pipeline.events(0.5):
            live.sink.handle(event)
        state = live.snapshotter.snapshot()
    assert state["ended"] is False and state["summary"] is None
