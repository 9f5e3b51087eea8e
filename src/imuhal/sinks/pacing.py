"""Per-message rate limits for output sinks, in the run's time (event time stamps, ns), so a
replay at any speed and a live run send the same messages."""

from __future__ import annotations

# Half a microsecond of slack: a 10 Hz limit must pass events 100 ms apart even when their
# time stamps were rounded to the nanosecond.
SLACK_NS = 500


class RateLimiter:
    """One message of each name per point of a grid 1 / rate apart: ``ready`` says whether one
    may go at ``t_ns``, ``mark`` records that it went (a sink that may still fail to encode it
    checks first and marks after), ``due`` does both. A rate of 0 or less means no limit.

    The grid, not "1 / rate after the last message", is what keeps the rate asked for: events
    stamped on a chip's own clock come a hair under their nominal period apart (a 200 Hz
    IMU's 5 ms is 4.999 ms on a chip 0.02 % fast), so four of them span just under the 20 ms
    of a 50 Hz limit and a limit measured from the last message waited for a fifth: 40 Hz.
    On the grid each message goes at the first event at or after its point; a message more
    than a whole period late (a gap in the events) starts the grid again from itself."""

    def __init__(self) -> None:
        self._due_ns: dict[str, float] = {}

    def ready(self, name: str, t_ns: int, rate_hz: float) -> bool:
        due = self._due_ns.get(name)
        return rate_hz <= 0 or due is None or t_ns >= due - SLACK_NS

    def mark(self, name: str, t_ns: int, rate_hz: float) -> None:
        if rate_hz <= 0:
            return
        period_ns = 1e9 / rate_hz
        due = self._due_ns.get(name)
        start = due if due is not None and t_ns < due + period_ns else float(t_ns)
        self._due_ns[name] = start + period_ns

    def due(self, name: str, t_ns: int, rate_hz: float) -> bool:
        if not self.ready(name, t_ns, rate_hz):
            return False
        self.mark(name, t_ns, rate_hz)
        return True
