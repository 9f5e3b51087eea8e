"""Per-message rate limits for output sinks, in the run's time (event time stamps, ns), so a
replay at any speed and a live run send the same messages."""

from __future__ import annotations

# Half a microsecond of slack: a 10 Hz limit must pass events 100 ms apart even when their
# time stamps were rounded to the nanosecond.
SLACK_NS = 500


class RateLimiter:
    """At most one message of each name per 1 / rate: ``ready`` says whether one may go at
    ``t_ns``, ``mark`` records that it went (a sink that may still fail to encode it checks
    first and marks after), ``due`` does both. A rate of 0 or less means no limit."""

    def __init__(self) -> None:
        self._last_ns: dict[str, int] = {}

    def ready(self, name: str, t_ns: int, rate_hz: float) -> bool:
        last = self._last_ns.get(name)
        return rate_hz <= 0 or last is None or t_ns - last >= 1e9 / rate_hz - SLACK_NS

    def mark(self, name: str, t_ns: int) -> None:
        self._last_ns[name] = t_ns

    def due(self, name: str, t_ns: int, rate_hz: float) -> bool:
        if not self.ready(name, t_ns, rate_hz):
            return False
        self.mark(name, t_ns)
        return True
