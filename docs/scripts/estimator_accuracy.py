"""Accuracy of every installed estimator against simulated ground truth on the seed board.

Usage::

    .venv/bin/python docs/scripts/estimator_accuracy.py [--duration S] [--write]

The seed paraglider board (profiles/seed-paraglider-vario.yaml: MAX21100 + HMC5883L + MS5611)
is emulated with each chip's datasheet error model (realistic, per-device bias draws), flying
the built-in scenarios. Everything is seeded (``SEED``), so the table is reproducible.

Attitude: each AHRS estimator runs with the board-rate settings of ``AHRS_ESTIMATORS`` (its
defaults otherwise), substituted for the profile's ``ahrs`` estimator. Its body -> NED
quaternion is compared with the scenario's truth at the estimate's timestamp: total error is
the rotation angle of q_est^-1 q_true, tilt error the angle between the estimated and the true
gravity (down) direction seen in the body. RMS over ``SETTLE_S`` .. end.

Vertical: the seed profile's own chain (madgwick -> vario-kf3, and baro-vario alone), plus
vario-kf3 with sigma_zmeas^2 measured as the seed advises. Climb-rate RMS error against truth,
altitude RMS error with the constant offset removed (barometer bias and QNH are not the
filter's business), and on ``elevator`` the delay to detect the climb step: the time from the
true climb rate crossing half the lift speed to the estimate crossing it.

Calibration conditions (``Condition``): ``calibrated`` is what the seed asks of a user (accel
six-position and magnetometer figure-of-8 once, gyro offsets at every power-up), measured here
with imuhal's own procedures on the emulated ``calibration`` scenario; ``gyro start-up`` only
re-measures the gyro offsets at power-up; ``as delivered`` applies nothing.

``--write`` rewrites the block between the accuracy-table markers in docs/estimators.md.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np

from imuhal.calibrate.emulated import measure_board_calibration, with_calibration
from imuhal.calibration.model import DeviceCalibration
from imuhal.core.atomic import atomic_write_text
from imuhal.core.samples import PressureSample
from imuhal.emulation import EmulatedBoard, open_emulated
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.pipeline.pipeline import Event, Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile, EstimatorConfig
from imuhal_filters.vario.tuning import estimate_altitude_variance

SEED = 1
"""Seed of the simulated world and of every chip's error draws."""
SETTLE_S = 5.0
"""Errors are averaged from this time (s after power-up) to the end of the run."""
DOC = Path(__file__).resolve().parent.parent / "estimators.md"
START_MARK = "<!-- accuracy-table:start -->"
END_MARK = "<!-- accuracy-table:end -->"

ATTITUDE_SCENARIOS = ("thermal", "rc-flight", "tumble", "magnet")
VARIO_SCENARIOS = ("thermal", "elevator")
STEP_SCENARIO = "elevator"
STEP_FRACTION = 0.5
"""The step-detection threshold, as a fraction of the lift's cruise speed."""
TUNING_WINDOW_S = 1.5
"""Barometer data at rest used for sigma_zmeas^2 (the seed: 1-2 s)."""

_BOARD_RATE = {"sample_period_s": 0.004}
AHRS_ESTIMATORS: dict[str, dict[str, Any]] = {
    "madgwick": dict(_BOARD_RATE),
    "mahony": dict(_BOARD_RATE),
    "imufilter": dict(_BOARD_RATE),
    "freescale-9dof": {"sensor_rate_hz": 250.0, "field_strength_ut": 41.0},
    "freescale-6dof": {"sensor_rate_hz": 250.0},
}
"""Estimator -> settings. Only what the board dictates is set (the MAX21100's 250 Hz, and for
freescale-9dof the local field strength of the simulated site, 41 uT); the rest are defaults
(no speed source, so no turn compensation: flight_benchmark.py measures that).
The freescale filters integrate each gyro sample over 1 / sensor_rate_hz, so it must match."""
SIX_DOF = frozenset({"imufilter", "freescale-6dof"})
"""Estimators without a magnetometer: yaw is unobservable, so only tilt is reported."""


class Condition(str, Enum):
    CALIBRATED = "calibrated"
    GYRO_STARTUP = "gyro start-up"
    AS_DELIVERED = "as delivered"


# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class AttitudeRow:
    estimator: str
    scenario: str
    condition: Condition
    total_rms_deg: float | None
    """None for 6-DOF filters (their heading is relative to the start-up heading)."""
    tilt_rms_deg: float
    tilt_max_deg: float
    estimates: int


@dataclass(frozen=True)
class VarioRow:
    estimator: str
    scenario: str
    climb_rms_m_s: float
    altitude_rms_m: float
    """Altitude error RMS after removing its mean (the barometer's offset)."""
    delay_up_s: float | None
    """Step-detection delay on the way up (s); None outside the step scenario."""
    delay_down_s: float | None


# --------------------------------------------------------------------------- errors


def attitude_errors_deg(q_est: np.ndarray, q_true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-row (total, tilt) errors in degrees of (N, 4) body -> NED quaternions (w, x, y, z).

    Total: rotation angle of q_est^-1 q_true. Tilt: angle between the NED down axis seen in
    the body by each attitude (the third row of R(q)), which no heading error changes.
    """
    dot = np.abs(np.sum(q_est * q_true, axis=1)) / (
        np.linalg.norm(q_est, axis=1) * np.linalg.norm(q_true, axis=1))
    total = np.degrees(2.0 * np.arccos(np.clip(dot, 0.0, 1.0)))
    down_est, down_true = _body_down(q_est), _body_down(q_true)
    cos_tilt = np.sum(down_est * down_true, axis=1) / (
        np.linalg.norm(down_est, axis=1) * np.linalg.norm(down_true, axis=1))
    return total, np.degrees(np.arccos(np.clip(cos_tilt, -1.0, 1.0)))


def _body_down(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q.T
    return np.c_[2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]


def rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def crossing_time_s(t_s: np.ndarray, values: np.ndarray, threshold: float,
                    after_s: float) -> float | None:
    """First time at or after ``after_s`` that ``values`` reaches ``threshold`` (from below
    for a positive threshold, from above for a negative one), linearly interpolated."""
    sign = 1.0 if threshold >= 0 else -1.0
    v = sign * values
    th = sign * threshold
    idx = np.nonzero((t_s >= after_s) & (v >= th))[0]
    if idx.size == 0:
        return None
    i = int(idx[0])
    if i == 0 or v[i - 1] >= th:
        return float(t_s[i])
    f = (th - v[i - 1]) / (v[i] - v[i - 1])
    return float(t_s[i - 1] + f * (t_s[i] - t_s[i - 1]))


# --------------------------------------------------------------------------- profiles


def seed_profile(registry: Registry) -> BoardProfile:
    return load_profile(default_profile_path(), registry)


def with_estimators(profile: BoardProfile, estimators: dict[str, EstimatorConfig]
                    ) -> BoardProfile:
    return profile.model_copy(update={"estimators": estimators})


def ahrs_profile(profile: BoardProfile, names: Sequence[str]) -> BoardProfile:
    """The profile with its estimators replaced by the AHRS under test, each fed by the IMU
    and the magnetometer only (so they never see one another's output) and named after
    itself. Running them side by side in one pipeline feeds each the very sample stream it
    would get alone, at a fraction of the cost."""
    return with_estimators(profile, {
        name: EstimatorConfig(estimator=name, inputs=["imu", "mag"],
                              settings=AHRS_ESTIMATORS[name])
        for name in names})


def condition_profile(profile: BoardProfile, condition: Condition,
                      calibrations: dict[str, DeviceCalibration]) -> BoardProfile:
    """The profile calibrated as ``condition`` says (``calibrations``: the accel and mag
    records of ``measure_board_calibration``, used by ``calibrated`` only)."""
    if condition is Condition.CALIBRATED:
        return with_calibration(profile, calibrations, gyro_startup="imu")
    return with_calibration(profile, {}, gyro_startup="imu"
                            if condition is Condition.GYRO_STARTUP else None)


# --------------------------------------------------------------------------- runs


def _events(profile: BoardProfile, registry: Registry, scenario: str, duration_s: float,
            seed: int) -> Iterator[tuple[Event, Pipeline]]:
    with open_emulated(profile, registry, scenario=scenario, seed=seed,
                       sensor_errors=True) as pipeline:
        # a profile asking for gyro_at_startup gets it inside events()
        for event in pipeline.events(duration_s):
            yield event, pipeline


def measure_attitude(profile: BoardProfile, registry: Registry, scenario: str,
                     duration_s: float, condition: Condition, *, seed: int = SEED,
                     settle_s: float = SETTLE_S) -> list[AttitudeRow]:
    """One emulated run of ``profile`` (its estimators: the AHRS under test) on ``scenario``;
    one row per AHRS estimator."""
    est: dict[str, list[tuple[float, ...]]] = {name: [] for name in profile.estimators}
    true: dict[str, list[tuple[float, ...]]] = {name: [] for name in profile.estimators}
    times: dict[str, list[float]] = {name: [] for name in profile.estimators}
    for event, pipeline in _events(profile, registry, scenario, duration_s, seed):
        if not isinstance(event, AttitudeEstimate) or event.t_ns < settle_s * 1e9:
            continue
        truth = EmulatedBoard.of(pipeline).truth_at(event.t_ns)
        est[event.source].append(event.q_body_to_ned)
        true[event.source].append(tuple(truth.q_body_to_ned))
        times[event.source].append(event.t_ns / 1e9)
    rows = []
    for name, cfg in profile.estimators.items():
        if not est[name]:
            raise RuntimeError(f"{cfg.estimator} produced no estimate after {settle_s} s "
                               f"on {scenario}")
        total, tilt = attitude_errors_deg(np.array(est[name]), np.array(true[name]))
        rows.append(AttitudeRow(
            estimator=cfg.estimator, scenario=scenario, condition=condition,
            total_rms_deg=None if cfg.estimator in SIX_DOF else rms(total),
            tilt_rms_deg=rms(tilt), tilt_max_deg=float(tilt.max()), estimates=len(tilt)))
    return rows


def tuned_altitude_variance_m2(profile: BoardProfile, registry: Registry,
                               seed: int = SEED) -> float:
    """sigma_zmeas^2 as the seed advises: the variance of ``TUNING_WINDOW_S`` of barometric
    altitude with the board at rest (emulated ``static``), through the tuning helper."""
    from imuhal.core.atmosphere import altitude_m_from_pressure

    altitudes = []
    with open_emulated(with_estimators(profile, {}), registry, scenario="static",
                       seed=seed) as pipeline:
        for event in pipeline.events(TUNING_WINDOW_S + 0.5):
            if isinstance(event, PressureSample) and event.valid and event.t_ns >= 0.5e9:
                altitudes.append(altitude_m_from_pressure(event.pressure_pa))
    rate_hz = len(altitudes) / TUNING_WINDOW_S
    return estimate_altitude_variance(altitudes, rate_hz)


def vario_profile(profile: BoardProfile, altitude_variance_m2: float) -> BoardProfile:
    """The seed profile's estimators (madgwick -> ``vario``, and ``baro-only``), plus two
    vario-kf3 tuned as the seed advises: ``vario-zmeas`` with the measured sigma_zmeas^2
    (other variances at the reference values) and ``vario-seed-start`` with, in addition,
    sigma_acc^2 numerically equal to sigma_zmeas^2 in cm units (the seed's starting point)."""
    estimators = dict(profile.estimators)
    vario = estimators["vario"]
    zmeas = {**vario.settings, "altitude_variance_m2": altitude_variance_m2}
    estimators["vario-zmeas"] = vario.model_copy(update={"settings": zmeas})
    # sigma_acc^2 [cm^2/s^4] = sigma_zmeas^2 [cm^2]: the same number in m^2/s^4 and m^2
    estimators["vario-seed-start"] = vario.model_copy(update={"settings": {
        **zmeas, "accel_variance_m2_s4": altitude_variance_m2}})
    return with_estimators(profile, estimators)


VARIO_LABELS = {
    "vario": "vario-kf3 (defaults)",
    "vario-zmeas": "vario-kf3 (sigma_zmeas^2 measured)",
    "vario-seed-start": "vario-kf3 (sigma_acc^2 = sigma_zmeas^2)",
    "baro-only": "baro-vario",
}


def measure_vario(profile: BoardProfile, registry: Registry, scenario: str, duration_s: float,
                  *, seed: int = SEED, settle_s: float = SETTLE_S) -> list[VarioRow]:
    """One emulated run; one row per vertical estimator of ``profile``."""
    t: dict[str, list[float]] = {}
    climb: dict[str, list[float]] = {}
    alt_err: dict[str, list[float]] = {}
    true_t: list[float] = []
    true_climb: list[float] = []
    for event, pipeline in _events(profile, registry, scenario, duration_s, seed):
        if not isinstance(event, VerticalEstimate):
            continue
        truth = EmulatedBoard.of(pipeline).truth_at(event.t_ns)
        t.setdefault(event.source, []).append(event.t_ns / 1e9)
        climb.setdefault(event.source, []).append(event.climb_m_s - truth.climb_m_s)
        alt_err.setdefault(event.source, []).append(event.altitude_m - truth.altitude_m)
        if not true_t or true_t[-1] != event.t_ns / 1e9:
            true_t.append(event.t_ns / 1e9)
            true_climb.append(truth.climb_m_s)
    rows = []
    for name in profile.estimators:
        if name not in t:
            continue
        ts = np.array(t[name])
        keep = ts >= settle_s
        err = np.array(climb[name])
        alt = np.array(alt_err[name])[keep]
        up = down = None
        if scenario == STEP_SCENARIO:
            est_climb = err + np.interp(ts, true_t, true_climb)
            up, down = step_delays_s(ts, est_climb, np.array(true_t), np.array(true_climb),
                                     registry, seed)
        rows.append(VarioRow(
            estimator=VARIO_LABELS.get(name, name), scenario=scenario,
            climb_rms_m_s=rms(err[keep]), altitude_rms_m=rms(alt - alt.mean()),
            delay_up_s=up, delay_down_s=down))
    return rows


def step_delays_s(t_s: np.ndarray, est_climb: np.ndarray, true_t: np.ndarray,
                  true_climb: np.ndarray, registry: Registry, seed: int
                  ) -> tuple[float | None, float | None]:
    """Delay (s) of the estimate behind the truth in crossing +-STEP_FRACTION of the lift's
    speed, on the way up and on the way down. Searching starts at each ride's phase start."""
    scenario = registry.scenarios.get(STEP_SCENARIO)(None, seed=seed)
    threshold = STEP_FRACTION * scenario.params.speed_m_s  # type: ignore[attr-defined]
    phases = {p.name: p for p in scenario.phases()}
    out = []
    for phase, th in (("up", threshold), ("down", -threshold)):
        start = phases[phase].start_s
        t_true = crossing_time_s(true_t, true_climb, th, start)
        t_est = crossing_time_s(t_s, est_climb, th, start)
        out.append(None if t_true is None or t_est is None else t_est - t_true)
    return out[0], out[1]


# --------------------------------------------------------------------------- report


def _f(v: float | None, digits: int = 2) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


ATTITUDE_COLUMNS = ("estimator", "scenario", "total RMS", "tilt RMS", "tilt max",
                    "gyro start-up only: total RMS", "tilt RMS",
                    "as delivered: total RMS", "tilt RMS")
"""Degrees. The first three are the calibrated board."""
VARIO_COLUMNS = ("estimator", "scenario", "climb RMS (m/s)", "altitude RMS, offset removed (m)",
                 "step delay up (s)", "step delay down (s)")


def attitude_table(rows: Sequence[AttitudeRow]) -> str:
    """Markdown: one line per (estimator, scenario), the calibrated board first, then the
    other conditions (see ``ATTITUDE_COLUMNS``)."""
    by = {(r.estimator, r.scenario, r.condition): r for r in rows}
    lines = [_row(ATTITUDE_COLUMNS), _row(["---"] * 2 + ["---:"] * 7)]
    for est, scen in dict.fromkeys((r.estimator, r.scenario) for r in rows):
        main = by.get((est, scen, Condition.CALIBRATED))
        gyro = by.get((est, scen, Condition.GYRO_STARTUP))
        raw = by.get((est, scen, Condition.AS_DELIVERED))
        lines.append(_row([
            est, scen,
            _f(main.total_rms_deg if main else None),
            _f(main.tilt_rms_deg if main else None),
            _f(main.tilt_max_deg if main else None),
            _f(gyro.total_rms_deg if gyro else None),
            _f(gyro.tilt_rms_deg if gyro else None),
            _f(raw.total_rms_deg if raw else None),
            _f(raw.tilt_rms_deg if raw else None),
        ]))
    return "\n".join(lines)


def vario_table(rows: Sequence[VarioRow]) -> str:
    lines = [_row(VARIO_COLUMNS), _row(["---"] * 2 + ["---:"] * 4)]
    for r in rows:
        lines.append(_row([r.estimator, r.scenario, _f(r.climb_rms_m_s, 3),
                           _f(r.altitude_rms_m, 3), _f(r.delay_up_s), _f(r.delay_down_s)]))
    return "\n".join(lines)


def _row(cells: Sequence[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def report(attitude: Sequence[AttitudeRow], vario: Sequence[VarioRow], *, duration_s: float,
           altitude_variance_m2: float) -> str:
    """The generated block: both tables and the facts needed to reproduce them."""
    return "\n".join([
        f"Generated by `docs/scripts/estimator_accuracy.py --duration {duration_s:g}` "
        f"(seed {SEED}, errors over t >= {SETTLE_S:g} s; every scenario runs "
        f"min({duration_s:g} s, its default length)).",
        "",
        "Attitude (calibrated board unless the column says otherwise; 6-DOF filters: total "
        "is not reported, their yaw is unobservable):",
        "",
        attitude_table(attitude),
        "",
        f"Vertical (calibrated board; AHRS: madgwick as in the seed profile; measured "
        f"sigma_zmeas^2 = {altitude_variance_m2:.4f} m^2 over {TUNING_WINDOW_S:g} s at rest; "
        f"step delay: estimate vs truth crossing +-{STEP_FRACTION:g} x lift speed on "
        f"`{STEP_SCENARIO}`; climb and altitude RMS over t >= {SETTLE_S:g} s):",
        "",
        vario_table(vario),
    ])


def replace_block(text: str, block: str, marks: tuple[str, str] = (START_MARK, END_MARK)
                  ) -> str:
    """``text`` with the lines between the two markers replaced by ``block``."""
    start_mark, end_mark = marks
    start = text.index(start_mark) + len(start_mark)
    end = text.index(end_mark, start)
    return text[:start] + "\n" + block.rstrip("\n") + "\n" + text[end:]


# --------------------------------------------------------------------------- main


def run(duration_s: float, *, registry: Registry | None = None,
        attitude_scenarios: Sequence[str] = ATTITUDE_SCENARIOS,
        vario_scenarios: Sequence[str] = VARIO_SCENARIOS,
        estimators: Sequence[str] = tuple(AHRS_ESTIMATORS),
        conditions: Sequence[Condition] = tuple(Condition),
        log: Any = None) -> str:
    """Measure everything and return the markdown block."""
    reg = registry or load_registry()
    base = seed_profile(reg)

    def say(msg: str) -> None:
        if log is not None:
            print(msg, file=log, flush=True)

    t0 = time.perf_counter()
    cals = measure_board_calibration(base, reg, seed=SEED)
    say(f"board calibration measured ({time.perf_counter() - t0:.1f} s)")
    attitude: list[AttitudeRow] = []
    for scenario in attitude_scenarios:
        length = min(duration_s, reg.scenarios.get(scenario).default_duration_s)
        for cond in conditions:
            prof = condition_profile(ahrs_profile(base, estimators), cond, cals)
            attitude += measure_attitude(prof, reg, scenario, length, cond)
            say(f"attitude {scenario} {cond.value} ({time.perf_counter() - t0:.1f} s)")
    variance = tuned_altitude_variance_m2(base, reg)
    vario: list[VarioRow] = []
    for scenario in vario_scenarios:
        length = min(duration_s, reg.scenarios.get(scenario).default_duration_s)
        prof = condition_profile(vario_profile(base, variance), Condition.CALIBRATED, cals)
        vario += measure_vario(prof, reg, scenario, length)
        say(f"vario {scenario} ({time.perf_counter() - t0:.1f} s)")
    return report(attitude, vario, duration_s=duration_s, altitude_variance_m2=variance)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=60.0, metavar="S",
                        help="seconds per scenario, at most its default length (default 60)")
    parser.add_argument("--write", action="store_true",
                        help=f"rewrite the accuracy table in {DOC.name}")
    args = parser.parse_args(argv)
    block = run(args.duration, log=sys.stderr)
    print(block)
    if args.write:
        atomic_write_text(DOC, replace_block(DOC.read_text(encoding="utf-8"), block))
        print(f"wrote {DOC}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
