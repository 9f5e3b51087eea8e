"""Bringing a device up: probe and configure, telling a glitch from a wrong chip.

One transient bus error during start-up must not stop a board (with 1 % of transfers
failing, a bare probe-and-configure of the seed board failed in 26 of 40 start-ups). So a
failed attempt is repeated after a growing pause. A chip that answers with the same wrong
identity twice in a row is another chip (or none), not a glitch: that is reported at once.
"""

from __future__ import annotations

from imuhal.core.clock import Clock
from imuhal.core.errors import DeviceNotFoundError, ImuhalError
from imuhal.drivers.base import DeviceIdentity, Driver

ATTEMPTS = 6
"""Probe-and-configure attempts at start-up before the device is reported."""
BACKOFF_S = (0.001, 0.002, 0.005, 0.01, 0.02)
"""Pause before each further attempt (38 ms in all at worst)."""


def bring_up(driver: Driver, clock: Clock, *, attempts: int = ATTEMPTS) -> DeviceIdentity:
    """Probe and configure ``driver``'s chip; sets and returns ``driver.identity``.

    Retries after any imuhal error (a bus error, a configuration that did not read back,
    an identity read through a glitch); raises the last error when every attempt failed, or
    as soon as the same wrong identity is found twice in a row.
    """
    last_found: str | None = None
    error: ImuhalError | None = None
    for attempt in range(attempts):
        if attempt:
            clock.sleep(BACKOFF_S[min(attempt - 1, len(BACKOFF_S) - 1)])
        try:
            identity = driver.probe()
            driver.identity = identity
            driver.configure()
            return identity
        except DeviceNotFoundError as exc:
            if exc.found == last_found:
                raise  # the same evidence twice: a wrong or missing chip, not a glitch
            last_found, error = exc.found, exc
        except ImuhalError as exc:
            last_found, error = None, exc
    assert error is not None
    raise error
