"""Integrity of a GNSS epoch beyond its checksum: what the receiver says, held against
itself and against its previous epochs.

UBX frames carry an 8-bit Fletcher checksum and NMEA sentences an 8-bit XOR: two flipped
bits can cancel in either (UBX: bit 7 in two bytes an even number of bytes apart; NMEA: the
same bit in any two characters). The driver's in-frame checks (gSpeed against velN and
velE) and its velocity step limit catch such pairs in the velocity; this module catches
them in the position and in the epoch's time, with bounds taken from the receiver's own
accuracy estimates and from physics:

- **position against velocity** (:class:`EpochWatch`): the new position must lie where the
  last valid one, advanced by the mean of the two epochs' reported velocities over the time
  between them, puts it. Allowed: ``GATE_SIGMAS`` standard deviations of the two epochs'
  stated position errors (hAcc, vAcc) and of the velocity's stated error (sAcc) over the
  interval, plus what an acceleration of ``max_acceleration_m_s2`` can move the vehicle off
  the trapezoid between the two velocities (a dt^2 / 4). This is ArduPilot's early glitch
  rule (position projected from the last one with its velocity, a radius and an
  acceleration term) with the radius taken from the receiver's own accuracies, as PX4's and
  ArduPilot's filters gate a GNSS position on its innovation against hAcc. Vertically the
  radius is what the height *error* can change by between the two epochs
  (:func:`height_error_change_m`: a receiver's error wanders slowly, HEIGHT_ERROR_TAU_S)
  and the manoeuvre term uses both velD (:func:`vertical_manoeuvre_m`): the height must
  follow the integrated velD, and a flip of both heights (which keeps the geoid
  separation) cannot hide in two epochs' vAcc.
- **height against MSL height**: NAV-PVT states the height above the ellipsoid and above
  mean sea level; their difference is the geoid separation, which lies between -107 and
  +86 m on Earth and changes with the position by no more than the geoid's slope
  (``GEOID_SLOPE``) times the distance moved. A flip in one of the two heights shows here
  to the millimetre; the same flip in both is left to the vertical position check.
- **UTC against GPS time**: NAV-PVT states its epoch as GPS time of week (iTOW) and as UTC
  (hour, minute, second, nano); their difference is the leap-second count, constant but for
  a leap second. A time stamp shifted by a flip would put a valid fix at the wrong time (and
  a later one moves the driver's time mapping for every epoch after it). The UTC date stays
  the last epoch's or the day after (a flipped year put a fix 128 years back).

A refused epoch is no new reference. When the reference itself is wrong (the first epoch
after start-up was hit, or the receiver really jumped while epochs were lost), ``CONFIRM``
refused epochs in a row that agree with one another under the same rules become the new
reference (imuhal.drivers.validity.NewLevel): a wrong reference costs at most
``CONFIRM - 1`` honest epochs, flagged, never a wrong one passed. The first epoch has
nothing to be held against but the geoid's range, so it is no reference until ``CONFIRM``
epochs in a row follow one another: the first ``CONFIRM - 1`` fixes of a run are refused
(``UNCONFIRMED``), and a hit in one of them never becomes valid (one that was the reference
had refused the honest epochs after it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from imuhal.drivers.validity import NewLevel

EARTH_A_M = 6378137.0
"""WGS-84 semi-major axis."""
EARTH_E2 = 6.69437999014e-3
"""WGS-84 first eccentricity squared."""
GATE_SIGMAS = 5.0
"""Standard deviations the position check allows (PX4's EKF2 gates GNSS position at 5).
Horizontal, a 2-D Gaussian exceeds 5 times its rms with probability exp(-25), 1.4e-11;
vertical, 5 sigma is 5.7e-7 an epoch. Both figures assume the two epochs' errors
independent; a receiver's are strongly correlated from one epoch to the next (its own
filter), so the real chance is far smaller."""
GEOID_RANGE_M = (-110.0, 90.0)
"""The geoid separation anywhere on Earth (EGM96: -106.2 to +85.4 m) with a margin."""
GEOID_SLOPE = 1e-3
"""How much the geoid separation changes per metre moved, at most (the deflection of the
vertical stays below 1 arcmin, 3e-4, but in the steepest mountains; a receiver's coarser
geoid model is smoother still)."""
GEOID_RESOLUTION_M = 0.002
"""Two heights of 1 mm resolution each."""
HEIGHT_ERROR_TAU_S = 10.0
"""The shortest correlation time taken for a receiver's height error. The error comes from
the satellites' geometry, the ionosphere, the troposphere and multipath, which change over
tens of seconds to minutes (the emulated receiver's error is a Gauss-Markov process of 30 s;
GNSS error models in the navigation literature take 30 s to several minutes), and the
navigation filter smooths what is left. Shorter than any of those, the bound is the loose
side: 10 s makes the change between epochs 0.2 s apart 0.2 vAcc (0.8 m at 4 m), where a
30 s error changes by 0.12 vAcc. A receiver whose height jumps (the satellite set changed)
loses two epochs to the new level's confirmation (CONFIRM)."""
POSITION_RESOLUTION_M = 0.03
"""Two positions of NAV-PVT's 1e-7 deg each in latitude and longitude (1.1 cm a step)."""
LEAP_TOLERANCE_S = 0.002
"""How far GPS time less UTC may stray from the last valid epoch's: iTOW is in whole ms and
the UTC fields state the same epoch to the ns (a u-blox keeps its epochs on the ms grid;
their sub-ms residual shows in nano). Wider, a flip in nano's third byte (8.4 ms) passed and
moved the driver's time mapping, so every later epoch's stamp, by as much."""
CONFIRM = 3
"""Refused epochs in a row that agree with one another become the new reference; the first
fix, too, is valid only once this many epochs in a row agree (0.4 s at 5 Hz, 2 s at 1 Hz)."""
UNCONFIRMED = "first fix unconfirmed"
"""The rule that refuses the epochs before the first reference is confirmed."""
DAY_S = 86_400.0


@dataclass(frozen=True)
class Epoch:
    """What one epoch says, as the checks need it (SI units; None: not stated).

    ``velocity_ned_m_s`` is the epoch's own velocity, NED; ``vertical_velocity_measured``
    says whether its down component is a measurement (NAV-PVT's velD) or was made from
    heights (NMEA), which the vertical position check cannot use. Accuracies are the
    receiver's: horizontal position (hAcc, 2-D rms), vertical (vAcc), speed per axis (sAcc).
    """

    t_ns: int
    latitude_deg: float
    longitude_deg: float
    height_msl_m: float
    velocity_ned_m_s: tuple[float, float, float] | None
    horizontal_accuracy_m: float
    vertical_accuracy_m: float | None
    speed_accuracy_m_s: float
    vertical_velocity_measured: bool = True
    height_ellipsoid_m: float | None = None
    gps_minus_utc_s: float | None = None
    """GPS time of week less UTC time of day, modulo a day (NAV-PVT only)."""
    utc_day: int | None = None
    """The UTC date as a day number (proleptic Gregorian ordinal)."""

    @property
    def geoid_separation_m(self) -> float | None:
        if self.height_ellipsoid_m is None:
            return None
        return self.height_ellipsoid_m - self.height_msl_m


@dataclass(frozen=True)
class Verdict:
    """The checks' answer for one epoch: ``ok``, or which rule refused it (``reason``);
    ``ratios``: each rule's residual over its bound (above 1 refuses)."""

    ok: bool
    reason: str = ""
    ratios: tuple[tuple[str, float], ...] = ()


def local_offset_m(a: Epoch, b: Epoch) -> tuple[float, float, float]:
    """``b`` less ``a`` in metres north, east, down, on the WGS-84 ellipsoid's local radii
    at ``a`` (exact to well below a millimetre over the few hundred metres between epochs;
    a longitude difference is taken across the antimeridian the short way)."""
    lat = math.radians(a.latitude_deg)
    s = math.sin(lat)
    w = math.sqrt(1.0 - EARTH_E2 * s * s)
    h = a.height_msl_m
    r_meridian = EARTH_A_M * (1.0 - EARTH_E2) / w**3 + h
    r_normal = EARTH_A_M / w + h
    dlon = (b.longitude_deg - a.longitude_deg + 180.0) % 360.0 - 180.0
    north = math.radians(b.latitude_deg - a.latitude_deg) * r_meridian
    east = math.radians(dlon) * r_normal * math.cos(lat)
    return north, east, -(b.height_msl_m - a.height_msl_m)


class EpochWatch:
    """Holds each epoch against the last valid one (module docstring).

    ``observe`` is called with every epoch the driver would otherwise deliver valid; it
    answers whether the epoch may be, and keeps the reference and the run of refused epochs.
    ``refused`` counts the epochs refused, per rule.
    """

    def __init__(self, max_acceleration_m_s2: float) -> None:
        if max_acceleration_m_s2 <= 0:
            raise ValueError(f"max_acceleration_m_s2 must be > 0, got {max_acceleration_m_s2}")
        self.max_acceleration_m_s2 = max_acceleration_m_s2
        self._reference: Epoch | None = None
        self._new_level: NewLevel[Epoch] = NewLevel(CONFIRM, self._agree)
        self.refused: dict[str, int] = {}
        self.worst_ratio: dict[str, float] = {}
        """Per rule: the largest residual over its bound among epochs it passed (how close
        honest epochs come to the bound)."""

    def observe(self, epoch: Epoch) -> Verdict:
        alone = self._alone(epoch)
        if not alone.ok:
            return self._refuse(epoch, alone, chain=False)
        if self._reference is None:
            # Nothing to hold the first fix against: a hit in it would be passed and would
            # then refuse the honest epochs after it. It is valid once CONFIRM epochs in a
            # row follow one another under every rule, as a new level after a wrong
            # reference is.
            if self._new_level.refused(epoch):
                self._accept(epoch, ())
                return Verdict(True, f"first fix confirmed by {CONFIRM} agreeing epochs")
            return self._count(Verdict(False, UNCONFIRMED))
        verdict = self.follows(self._reference, epoch)
        if verdict.ok:
            self._accept(epoch, (verdict,))
            return verdict
        return self._refuse(epoch, verdict, chain=True)

    def restart(self) -> None:
        """The receiver was found and configured again (a recovery): its next epochs are
        held like a first fix. The last reference may be seconds old, and the bound that
        grows with the square of that time checks little (after 2 s at 10 g: 100 m); a
        restarted receiver's first epochs are also the likeliest to be wrong."""
        self._reference = None
        self._new_level.clear()

    def _accept(self, epoch: Epoch, verdicts: tuple[Verdict, ...]) -> None:
        self._reference = epoch
        self._new_level.clear()
        for v in verdicts:
            for rule, ratio in v.ratios:
                self.worst_ratio[rule] = max(self.worst_ratio.get(rule, 0.0), ratio)

    def _refuse(self, epoch: Epoch, verdict: Verdict, *, chain: bool) -> Verdict:
        if chain and self._new_level.refused(epoch):
            # the reference was the odd one out: a new level the epochs agree on
            self._reference = epoch
            return Verdict(True, f"new reference after {CONFIRM} agreeing epochs")
        return self._count(verdict)

    def _count(self, verdict: Verdict) -> Verdict:
        self.refused[verdict.reason] = self.refused.get(verdict.reason, 0) + 1
        return verdict

    def _agree(self, earlier: Epoch, later: Epoch) -> bool:
        return self.follows(earlier, later).ok

    @staticmethod
    def _alone(epoch: Epoch) -> Verdict:
        """What one epoch can be checked against without another: the geoid's range."""
        n = epoch.geoid_separation_m
        if n is not None and not GEOID_RANGE_M[0] <= n <= GEOID_RANGE_M[1]:
            return Verdict(False, "geoid separation", (("geoid separation", math.inf),))
        return Verdict(True)

    def follows(self, earlier: Epoch, epoch: Epoch) -> Verdict:
        """Whether ``epoch`` can follow ``earlier``: time, geoid separation, then position
        against velocity (each rule's residual over its bound; the first that refuses)."""
        ratios: list[tuple[str, float]] = []
        if earlier.gps_minus_utc_s is not None and epoch.gps_minus_utc_s is not None:
            d = (epoch.gps_minus_utc_s - earlier.gps_minus_utc_s + DAY_S / 2) % DAY_S \
                - DAY_S / 2
            ratios.append(("time", abs(d) / LEAP_TOLERANCE_S))
        if earlier.utc_day is not None and epoch.utc_day is not None:
            # the date moves on by a day at midnight, and never back
            ratios.append(("date", 0.0 if 0 <= epoch.utc_day - earlier.utc_day <= 1
                           else math.inf))
        north, east, down = local_offset_m(earlier, epoch)
        n0, n1 = earlier.geoid_separation_m, epoch.geoid_separation_m
        if n0 is not None and n1 is not None:
            allowed = GEOID_RESOLUTION_M + GEOID_SLOPE * math.hypot(north, east)
            ratios.append(("geoid separation", abs(n1 - n0) / allowed))
        if earlier.velocity_ned_m_s is not None and epoch.velocity_ned_m_s is not None:
            ratios += self._position(earlier, epoch, (north, east, down))
        for rule, ratio in ratios:
            if ratio > 1.0:
                return Verdict(False, rule, tuple(ratios))
        return Verdict(True, "", tuple(ratios))

    def _position(self, earlier: Epoch, epoch: Epoch, moved: tuple[float, float, float]
                  ) -> list[tuple[str, float]]:
        """Residuals of the position check over their bounds, horizontal and vertical."""
        assert earlier.velocity_ned_m_s is not None and epoch.velocity_ned_m_s is not None
        dt_s = max(0, epoch.t_ns - earlier.t_ns) * 1e-9
        mean_v = [(a + b) / 2.0 for a, b in zip(earlier.velocity_ned_m_s,
                                                epoch.velocity_ned_m_s, strict=True)]
        residual = [m - v * dt_s for m, v in zip(moved, mean_v, strict=True)]
        # |v'| <= A puts the travelled distance within A dt^2 / 4 of the trapezoid
        manoeuvre_m = self.max_acceleration_m_s2 * dt_s * dt_s / 4.0
        # The new epoch's accuracies come from the same frame as its position, so a flip
        # could widen them with it (hAcc 8.4 km and the latitude 93 km off: bit 7 of byte
        # 2 of each, the same parity): they count no worse than the earlier epoch's. A
        # receiver whose fix really degrades has its jumps confirmed (CONFIRM) and its
        # larger accuracy is then the reference's.
        s0 = earlier.speed_accuracy_m_s
        s1 = min(epoch.speed_accuracy_m_s, s0)
        h0 = earlier.horizontal_accuracy_m
        h1 = min(epoch.horizontal_accuracy_m, h0)
        # the mean of two velocities, each with sAcc per axis, over dt
        speed_var = (s0 * s0 + s1 * s1) * (dt_s / 2.0) ** 2
        horizontal_sigma = math.sqrt(h0 * h0 + h1 * h1 + 2.0 * speed_var)
        # Each bound is at least what the fields' resolution can make of nothing (two
        # epochs with one time stamp and zero accuracies leave no other term: a hit epoch
        # stamped like its reference divided by zero, and the driver was recovered).
        out = [("horizontal position", math.hypot(residual[0], residual[1])
                / max(GATE_SIGMAS * horizontal_sigma + manoeuvre_m, POSITION_RESOLUTION_M))]
        v0 = earlier.vertical_accuracy_m
        if (v0 is not None and epoch.vertical_accuracy_m is not None
                and earlier.vertical_velocity_measured and epoch.vertical_velocity_measured):
            # Not the two epochs' height errors as if independent (sqrt(2) vAcc: 5.7 m at
            # 4 m, which let a 32.8 m flip of both heights through above vAcc 4.5 m) but how
            # far a height error of the reference's vAcc moves between them (the new
            # epoch's vAcc comes from the frame under test, as hAcc does).
            vertical_sigma = math.sqrt(height_error_change_m(v0, dt_s) ** 2 + speed_var)
            bound_m = GATE_SIGMAS * vertical_sigma + vertical_manoeuvre_m(
                self.max_acceleration_m_s2, dt_s,
                epoch.velocity_ned_m_s[2] - earlier.velocity_ned_m_s[2])
            out.append(("vertical position", abs(residual[2])
                        / max(bound_m, GEOID_RESOLUTION_M)))
        return out


def height_error_change_m(vertical_accuracy_m: float, dt_s: float) -> float:
    """The standard deviation of the change of a receiver's height error over ``dt_s``, for
    a height error of ``vertical_accuracy_m`` rms that wanders with a correlation time of at
    least HEIGHT_ERROR_TAU_S (a first-order Gauss-Markov process: the change's variance is
    ``2 vAcc^2 (1 - exp(-dt / tau))``). Over a long gap it tends to two independent errors,
    ``sqrt(2) vAcc``; between two epochs 0.2 s apart it is 0.2 vAcc."""
    a = math.exp(-max(dt_s, 0.0) / HEIGHT_ERROR_TAU_S)
    return vertical_accuracy_m * math.sqrt(2.0 * (1.0 - a))


def vertical_manoeuvre_m(max_acceleration_m_s2: float, dt_s: float, dv_m_s: float) -> float:
    """How far a vehicle accelerating at no more than ``max_acceleration_m_s2`` can leave the
    trapezoid between two vertical velocities ``dv_m_s`` apart over ``dt_s``: it climbs at the
    limit and turns back at the limit to meet the second velocity, ``(A^2 dt^2 - dv^2) / 4A``
    (A dt^2 / 4 when the velocities are equal, nothing when they differ by A dt: then the
    only path is the straight ramp)."""
    a = max_acceleration_m_s2
    return max(0.0, (a * a * dt_s * dt_s - dv_m_s * dv_m_s) / (4.0 * a))

