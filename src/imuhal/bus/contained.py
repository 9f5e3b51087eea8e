"""A bus wrapper that keeps a bus plugin's own exceptions inside the bus layer.

A third-party bus plugin (or the kernel, through smbus2/spidev) may raise ``OSError`` or
anything else for a failed transfer. The pipeline contains ``BusError`` to the device that
met it; ``ContainedBus`` turns any other exception raised by a transfer into a ``BusError``
naming the original, so one flaky bus plugin cannot end the whole run.
"""

from __future__ import annotations

from imuhal.bus.base import Bus, Link
from imuhal.core.errors import BusError, ImuhalError, RunEnded


class ContainedBus(Bus):
    """Forwards every transaction to ``inner``; foreign exceptions become ``BusError``."""

    def __init__(self, inner: Bus) -> None:
        super().__init__(inner.name)
        self.kind = inner.kind
        self.inner = inner
        self.lock = inner.lock  # one lock: the wrapper must not let transactions interleave

    def transfer(self, target: int, write: bytes = b"", read_len: int = 0) -> bytes:
        try:
            return self.inner.transfer(target, write, read_len)
        except (ImuhalError, RunEnded):
            raise
        except Exception as exc:
            raise self._contained(exc, target) from exc

    def receive(self, target: int, max_len: int) -> bytes:
        try:
            return self.inner.receive(target, max_len)
        except (ImuhalError, RunEnded):
            raise
        except Exception as exc:
            raise self._contained(exc, target) from exc

    def _contained(self, exc: Exception, target: int) -> BusError:
        return BusError(f"{type(exc).__name__} from the bus plugin: {exc}", bus=self.name,
                        target=target)

    def __getattr__(self, name: str) -> object:
        # Optional capabilities of the wrapped bus (a UART's set_baudrate) stay reachable;
        # only called for names this wrapper does not define itself.
        return getattr(self.inner, name)

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        return self.transfer(target, write, read_len)  # pragma: no cover - transfer overrides

    def link(self, target: int) -> Link:
        return Link(self, target)

    def close(self) -> None:
        self.inner.close()
