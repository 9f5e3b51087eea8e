"""The exception hierarchy. Every message says what went wrong and what to do about it."""

from __future__ import annotations


class ImuhalError(Exception):
    """Base of every error imuhal raises on purpose."""


class BusError(ImuhalError):
    """A transfer failed: NACK, I/O error, timeout. Carries the bus and target."""

    def __init__(self, message: str, *, bus: str = "", target: int | None = None) -> None:
        where = f"{bus}" + (f" @0x{target:02X}" if target is not None else "")
        super().__init__(f"{where}: {message}" if where else message)
        self.bus = bus
        self.target = target


class RunEnded(Exception):
    """Raised by a bus to end the whole run instead of failing one device: a replayed
    recording that has run out or diverged. Deliberately not an ImuhalError (the pipeline
    contains those to their device and recovers it), and never wrapped by ContainedBus."""


class NackError(BusError):
    """No device acknowledged the address (I2C) or answered on the chip select (SPI)."""


class DeviceNotFoundError(ImuhalError):
    """The chip at a bus address is absent or is not the chip the profile names."""

    def __init__(
        self,
        *,
        driver: str,
        bus: str,
        address: int,
        expected: str,
        found: str,
        hint: str = "",
    ) -> None:
        self.driver = driver
        self.bus = bus
        self.address = address
        self.expected = expected
        self.found = found
        self.hint = hint
        text = (
            f"{driver}: no matching chip on {bus} at address/cs 0x{address:02X}: "
            f"expected {expected}, found {found}"
        )
        if hint:
            text += f". Hint: {hint}"
        super().__init__(text)


class ConfigurationError(ImuhalError):
    """A register write did not read back as written, or a setting cannot be applied."""


class ProfileError(ImuhalError):
    """A board profile is invalid. ``problems`` lists every problem found, each located."""

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source = source
        self.problems = problems
        if len(problems) == 1:  # one problem, one line (it usually starts with its file:line)
            only = problems[0]
            super().__init__(only if only.startswith(source) else f"{source}: {only}")
            return
        lines = "\n".join(f"  - {p}" for p in problems)
        count = len(problems)
        super().__init__(
            f"{source}: {count} problem{'s' if count != 1 else ''} in board profile:\n{lines}"
        )


class OutputError(ImuhalError):
    """A file cannot be written where the user asked, or writing it would destroy an input."""


class PluginError(ImuhalError):
    """A plugin failed to load, registered something twice, or a name is not installed."""


class ImuhalDeprecationWarning(DeprecationWarning):
    """An input uses an old name that still works (a renamed driver setting): the
    message names the old and the new key. The CLI shows each such message once, on one
    line (Python hides DeprecationWarning outside ``__main__``)."""
