"""Why a calibration procedure refused, and what to do about it."""

from __future__ import annotations

from imuhal.core.errors import ImuhalError


class CalibrationError(ImuhalError):
    """A procedure could not produce a trustworthy calibration.

    ``reason`` says what was wrong with the data, ``advice`` what the user should do; the
    message is both. ``figures`` carries the numbers behind the decision (coverage, residual).
    """

    def __init__(self, reason: str, advice: str, figures: dict[str, float] | None = None) -> None:
        self.reason = reason
        self.advice = advice
        self.figures = dict(figures or {})
        super().__init__(f"{reason}. {advice[:1].upper()}{advice[1:]}")


class CalibrationWriteError(ImuhalError):
    """The profile could not be rewritten; the file on disk is unchanged."""
