"""The "decoupled" kernel's state as the arrays its compiled step works on (decoupled/fast.py).

``DecoupledKernel`` (core.py) stays the reference and the one place the state is read and
saved: the compiled step runs on arrays packed from it (``pack``), and ``unpack`` writes them
back before anything reads the kernel (a saved state, the offline passes' records).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from imuhal.core.frames import FloatArray
from imuhal_filters.common.innovation import ManoeuvreParams
from imuhal_filters.decoupled import fast as f
from imuhal_filters.decoupled.butterworth import ButterworthLowPass
from imuhal_filters.decoupled.core import DecoupledKernel, DecoupledParams

LOOKBACK_ROWS = 1024
"""The look-back ring's first size (entries); ``grown`` doubles it when it would fill (an
episode keeps its input up to the manoeuvre detector's leak time, 3 s: 750 entries at 250
Hz)."""


def covers(p: DecoupledParams) -> bool:
    """The compiled step implements these settings (not: the innovation-speed weight, the
    soft gate, the turbulence correction)."""
    return (p.innovation_speed_m_s is None and p.accel_soft_gate_g is None
            and p.turbulence_rate_rad_s is None)


def params_array(p: DecoupledParams) -> FloatArray:
    """The kernel's constants in ``fast``'s ``P_*`` layout."""
    out = np.zeros(f.PARAMS_SIZE)
    m = p.manoeuvre
    floor = (ManoeuvreParams() if m is None else m).floor_m_s2
    values = {
        f.P_TAU_ACC: p.tau_acc_s, f.P_TAU_REST: p.tau_acc_rest_s or 0.0,
        f.P_TAU_MAG: p.tau_mag_s, f.P_REST_GYRO_TH: p.rest_gyro_th_rad_s,
        f.P_REST_ACC_TH: p.rest_acc_th_g, f.P_REST_TAU: p.rest_filter_tau_s,
        f.P_REST_MIN: p.rest_min_s, f.P_BIAS_CLIP_CORE: p.bias_clip_rad_s,
        f.P_SIGMA_INIT: p.bias.sigma_init_deg_s, f.P_FORGETTING: p.bias.forgetting_s,
        f.P_SIGMA_MOTION: p.bias.sigma_motion_deg_s or 0.0,
        f.P_MOTION_ON: float(p.bias.sigma_motion_deg_s is not None),
        f.P_VERT_FORGET: p.bias.vertical_forgetting, f.P_SIGMA_REST: p.bias.sigma_rest_deg_s,
        f.P_KF_CLIP: p.bias.clip_rad_s, f.P_MAG_NORM_TH: p.mag_norm_th,
        f.P_MAG_DIP_TH_RAD: float(np.radians(p.mag_dip_th_deg)),
        f.P_MAG_REF_TAU: p.mag_ref_tau_s, f.P_MAG_NEW: p.mag_new_s,
        f.P_MAN_ON: float(m is not None), f.P_LB_S: p.lookback_s,
        f.P_PACE_ON: float(p.gyro_relative_error is not None),
        f.P_PACE_EPS: p.gyro_relative_error or 0.0, f.P_PACE_FLOOR: floor,
    }
    if m is not None:
        values.update({f.P_M_SPEED: m.speed_m_s, f.P_M_RATIO: m.ratio,
                       f.P_M_WINDOW: m.window_s, f.P_M_LEAK: m.leak_s,
                       f.P_M_DRIFT_TAU: m.drift_tau_s, f.P_M_FLOOR: m.floor_m_s2,
                       f.P_M_POWER: m.power, f.P_LB_TOL: m.floor_m_s2 * m.window_s})
    for i, v in values.items():
        out[i] = v
    return out


def _put(s: FloatArray, at: int, values: object, n: int) -> None:
    """A None-able value into its "set" slot and the ``n`` slots after it."""
    if values is None:
        s[at:at + 1 + n] = 0.0
    else:
        s[at] = 1.0
        s[at + 1:at + 1 + n] = list(values)  # type: ignore[call-overload]  # a tuple or list of n floats


def _get(s: FloatArray, at: int, n: int) -> tuple[float, ...] | None:
    return None if s[at] == 0.0 else tuple(s[at + 1:at + 1 + n].tolist())


def pack(k: DecoupledKernel, rows: int = LOOKBACK_ROWS) -> tuple[FloatArray, FloatArray]:
    """The state array S and the look-back ring L of ``k``."""
    s = np.zeros(f.STATE_SIZE)
    s[f._QG:f._QG + 4] = k.q_gyro
    s[f._QI:f._QI + 4] = k.q_inc
    s[f._DELTA] = k.delta_rad
    _put(s, f._ACCI, k.acc_i, 3)
    _put(s, f._ACCF, k._acc_filter.state, 6)
    _put(s, f._RF, k._r_filter.state, 18)
    _put(s, f._RBF, k._rb_filter.state, 4)
    s[f._B:f._B + 3] = k.kf.b
    s[f._BP:f._BP + 9] = [c for row in k.kf.p for c in row]
    _put(s, f._GLP, k.gyro_lp, 3)
    _put(s, f._ALP, k.acc_lp, 3)
    s[f._REST_S] = k.rest_s
    _put(s, f._MREF, k.mag_ref, 2)
    _put(s, f._MCAND, k.mag_cand, 2)
    s[f._MCAND_S] = k.mag_cand_s
    s[f._MDIST] = float(k.mag_disturbed)
    if k.manoeuvre is not None:
        s[f._MAN:f._MAN + 10] = k.manoeuvre.as_list()
    lb = k.lookback
    entries: list[list[float]] = []
    if lb is not None:
        s[f._LB], s[f._LB + 1] = lb.kept_s, lb.last_weight
        s[f._LB + 2] = float(lb.episode_s is not None)
        s[f._LB + 3] = lb.episode_s or 0.0
        s[f._DV:f._DV + 3], s[f._PEAK:f._PEAK + 3] = lb.dv_m_s, lb.peak_m_s
        s[f._READM] = lb.readmitted
        _put(s, f._BEFORE, lb.before.state, 6)
        # entries saved before the pace have no pace: 1
        entries = [e if len(e) == f.ENTRY else [*e, 1.0] for e in lb.entries]
    if k.pace is not None:
        s[f._PACE:f._PACE + 3] = k.pace.as_list()
    s[f._MISSED] = float(k.accel_missed)
    size = max(rows, 2 * len(entries) + 2)
    look = np.zeros((size, f.ENTRY))
    if entries:
        look[:len(entries)] = entries
    s[f._HEAD], s[f._HEAD + 1] = 0.0, float(len(entries))
    return s, look


def _filter(filt: ButterworthLowPass, state: tuple[float, ...] | None) -> None:
    filt.state = None if state is None else list(state)


def unpack(s: FloatArray, look: FloatArray, k: DecoupledKernel) -> None:
    """Write S and L back into ``k`` (the inverse of ``pack``)."""
    k.q_gyro = tuple(s[f._QG:f._QG + 4].tolist())
    k.q_inc = tuple(s[f._QI:f._QI + 4].tolist())
    k.delta_rad = float(s[f._DELTA])
    k.acc_i = _get(s, f._ACCI, 3)  # type: ignore[assignment]  # three floats or None
    _filter(k._acc_filter, _get(s, f._ACCF, 6))
    _filter(k._r_filter, _get(s, f._RF, 18))
    _filter(k._rb_filter, _get(s, f._RBF, 4))
    k.kf.b = tuple(s[f._B:f._B + 3].tolist())
    p = s[f._BP:f._BP + 9].tolist()
    k.kf.p = [p[0:3], p[3:6], p[6:9]]
    k.gyro_lp = _get(s, f._GLP, 3)  # type: ignore[assignment]  # three floats or None
    k.acc_lp = _get(s, f._ALP, 3)  # type: ignore[assignment]  # three floats or None
    k.rest_s = float(s[f._REST_S])
    k.mag_ref = _get(s, f._MREF, 2)  # type: ignore[assignment]  # two floats or None
    k.mag_cand = _get(s, f._MCAND, 2)  # type: ignore[assignment]  # two floats or None
    k.mag_cand_s = float(s[f._MCAND_S])
    k.mag_disturbed = bool(s[f._MDIST])
    k.accel_missed = bool(s[f._MISSED])
    if k.manoeuvre is not None:
        k.manoeuvre.load_list(s[f._MAN:f._MAN + 10].tolist())
    lb = k.lookback
    if lb is not None:
        lb.kept_s, lb.last_weight = float(s[f._LB]), float(s[f._LB + 1])
        lb.episode_s = float(s[f._LB + 3]) if s[f._LB + 2] != 0.0 else None
        lb.dv_m_s, lb.peak_m_s = s[f._DV:f._DV + 3].tolist(), s[f._PEAK:f._PEAK + 3].tolist()
        lb.readmitted = int(s[f._READM])
        _filter(lb.before, _get(s, f._BEFORE, 6))
        head, count = int(s[f._HEAD]), int(s[f._HEAD + 1])
        rows = [(head + j) % look.shape[0] for j in range(count)]
        lb.entries = deque(look[rows].tolist())
    if k.pace is not None:
        k.pace.load_list(s[f._PACE:f._PACE + 3].tolist())


def grown(s: FloatArray, look: FloatArray) -> FloatArray:
    """A ring twice the size with the same entries from row 0 (S's head set to 0)."""
    head, count = int(s[f._HEAD]), int(s[f._HEAD + 1])
    rows = [(head + j) % look.shape[0] for j in range(count)]
    out = np.zeros((2 * look.shape[0], f.ENTRY))
    out[:count] = look[rows]
    s[f._HEAD] = 0.0
    return out
