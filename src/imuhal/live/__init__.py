"""The live view: a read-only web dashboard for a running pipeline (docs/live-view.md).

``imuhal run --web [HOST:]PORT`` on the command line; from Python::

    from imuhal.live import LiveView

    with open_emulated(profile, registry, realtime=True) as pipeline, \\
            LiveView(pipeline, truth=EmulatedBoard.of(pipeline), port=8080) as live:
        print("open", live.url)
        pipeline.run(60, [live.sink])

The pipeline never imports this package: the live view is a sink (:class:`LiveSink`, which
only stores the latest state) plus a server on its own threads. The bring-up checks
(imuhal.live.mounts) are shared with ``imuhal check-mounts``.
"""

from imuhal.live.mounts import MOTIONS, Evidence, MotionRecorder, Verdict, check, judge
from imuhal.live.server import BindAddress, LiveView, parse_bind
from imuhal.live.sink import LiveSink

__all__ = ["MOTIONS", "BindAddress", "Evidence", "LiveSink", "LiveView", "MotionRecorder",
           "Verdict", "check", "judge", "parse_bind"]
