"""What estimators produce. Units and frames are in the names."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from imuhal.core.frames import euler_deg_from_quat
from imuhal.core.samples import Vec3, slot_setter


@dataclass(frozen=True, slots=True, kw_only=True)
class Estimate:
    t_ns: int
    source: str
    """The name of the estimator instance (its key in the profile)."""
    diagnostics: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, slots=True, kw_only=True)
class AttitudeEstimate(Estimate):
    """Orientation as a unit quaternion (w, x, y, z) rotating body -> NED."""

    q_body_to_ned: tuple[float, float, float, float]
    linear_accel_ned_m_s2: Vec3 | None = None
    """Gravity-compensated acceleration in NED (m/s^2), when the estimator had an accel sample."""

    @property
    def roll_pitch_yaw_deg(self) -> tuple[float, float, float]:
        """Seed conventions: roll right +, pitch up +, yaw [-180, 180] clockwise from north."""
        return euler_deg_from_quat(self.q_body_to_ned)

    @classmethod
    def build(cls, t_ns: int, source: str, q_body_to_ned: tuple[float, float, float, float],
              linear_accel_ned_m_s2: Vec3 | None, diagnostics: dict[str, Any]
              ) -> AttitudeEstimate:
        """The same estimate as the keyword constructor, built faster (an AHRS makes one
        per gyro sample): the fields are set through their slots, where the generated
        ``__init__`` of a frozen class goes through ``object.__setattr__`` per field."""
        e = _new(cls)
        _set_t_ns(e, t_ns)
        _set_source(e, source)
        _set_diagnostics(e, diagnostics)
        _set_q(e, q_body_to_ned)
        _set_linear_accel(e, linear_accel_ned_m_s2)
        return e


@dataclass(frozen=True, slots=True, kw_only=True)
class VerticalEstimate(Estimate):
    """Altitude above the pressure reference (m, up +) and climb rate (m/s, up +)."""

    altitude_m: float
    climb_m_s: float
    accel_bias_m_s2: float | None = None


# Slot setters for the ``build`` fast path (a frozen class forbids plain assignment).
_new = object.__new__
_set_t_ns = slot_setter(Estimate, "t_ns")
_set_source = slot_setter(Estimate, "source")
_set_diagnostics = slot_setter(Estimate, "diagnostics")
_set_q = slot_setter(AttitudeEstimate, "q_body_to_ned")
_set_linear_accel = slot_setter(AttitudeEstimate, "linear_accel_ned_m_s2")
