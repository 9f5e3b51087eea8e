"""How an estimator takes its limits and periods from the streams it is fed.

The pipeline hands ``Estimator.bind`` the stream specs (imuhal.core.streams) of the devices
an estimator takes input from; ``imuhal estimate`` hands it specs measured from the log's
time stamps. One rule for every estimator with a rate or a full-scale setting:

- a setting the user did not give follows the stream (the gyro's period, its full scale
  with ``CALIBRATION_MARGIN``);
- a setting given by hand that contradicts the stream is an error naming the setting and
  the fix (:class:`StreamContradiction`): a period or rate off the stream's by more than
  ``RATE_TOLERANCE``, a full scale below the stream's (it would drop correct readings).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from pydantic import BaseModel

from imuhal.core.errors import ImuhalError
from imuhal.core.quantities import Quantity
from imuhal.core.streams import StreamSpec

RATE_TOLERANCE = 0.05
"""A fixed period or rate setting may differ from its stream's by this fraction (5 %): a
chip's clock is good to a few percent; more is another rate."""

CALIBRATION_MARGIN = 1.1
"""An estimator's full-scale limit is the stream's full scale times this: calibration gains
and the mount rotation may carry a correct reading a little beyond the chip's range (the
pipeline itself flags raw readings beyond the range before calibration)."""


class StreamContradiction(ImuhalError):
    """A setting given by hand contradicts the stream it applies to. ``key`` is the
    setting's name; the message says what the stream says and the fix. The pipeline reports
    it as a profile error located at ``estimators.NAME.settings.KEY``; ``imuhal estimate``
    as an error of ``--set KEY``."""

    def __init__(self, key: str, problem: str) -> None:
        self.key = key
        self.problem = problem
        super().__init__(f"{key}: {problem}")


def stream_of(streams: Iterable[StreamSpec], quantity: Quantity) -> StreamSpec | None:
    """The stream carrying ``quantity`` an estimator steps on: the fastest one when several
    devices deliver it (the one that sets the step rate)."""
    found = [s for s in streams if s.quantity == quantity]
    return max(found, key=lambda s: s.rate_hz) if found else None


def given(settings: BaseModel) -> frozenset[str]:
    """The settings the user gave (a preset's values count as given by its name)."""
    return frozenset(settings.model_fields_set)


def bound_period(key: str, value: float, hand_set: bool, spec: StreamSpec | None
                 ) -> float | None:
    """The period (s) setting ``key`` should have for ``spec``: None to keep ``value``;
    raises StreamContradiction when a hand-set ``value`` is off by more than 5 %."""
    if spec is None:
        return None
    return _follow(key, value, hand_set, spec, spec.period_s,
                   f"{value:g} s", f"{spec.rate_hz:g} Hz: {spec.period_s:g} s")


def bound_rate(key: str, value: float, hand_set: bool, spec: StreamSpec | None
               ) -> float | None:
    """As :func:`bound_period`, for a rate setting in Hz."""
    if spec is None:
        return None
    return _follow(key, value, hand_set, spec, spec.rate_hz, f"{value:g} Hz",
                   f"{spec.rate_hz:g} Hz")


def _follow(key: str, value: float, hand_set: bool, spec: StreamSpec, want: float,
            shown: str, stream: str) -> float | None:
    """``want`` unless ``value`` already is it or was given by hand (then checked)."""
    if not hand_set:
        return want if value != want else None
    if abs(value - want) > RATE_TOLERANCE * want:
        raise StreamContradiction(key, (
            f"{shown} contradicts the {spec.quantity} stream of {spec.device!r} ({stream}); "
            f"remove {key} (it follows the stream) or change the stream's rate"))
    return None


def bound_limit(key: str, value: float, hand_set: bool, spec: StreamSpec | None
                ) -> float | None:
    """The full-scale limit setting ``key`` should have for ``spec``: the stream's full scale
    with ``CALIBRATION_MARGIN`` unless set by hand; a hand-set limit below the stream's full
    scale would drop correct readings: StreamContradiction."""
    if spec is None or spec.full_scale is None:
        return None
    if hand_set:
        if value < spec.full_scale:
            raise StreamContradiction(key, (
                f"{value:g} {spec.unit} is below the full scale of the {spec.quantity} stream "
                f"of {spec.device!r} (+-{spec.full_scale:.4g} {spec.unit} at its configured "
                f"range): correct readings would be dropped; remove {key} (it follows the "
                "stream) or raise it"))
        return None
    limit = CALIBRATION_MARGIN * spec.full_scale
    return limit if value != limit else None


def updated(settings: BaseModel, changes: Mapping[str, Any]) -> Any:
    """``settings`` with ``changes`` (None values dropped), or the same object unchanged."""
    real = {k: v for k, v in changes.items() if v is not None}
    return settings.model_copy(update=real) if real else settings
