"""Measurements of late polls on emulated boards, shared by tests/integration/
test_overdue_polls.py (which bounds them) and tests/benchmarks/late_polls.py (which prints
them for docs/acquisition.md, "Late polls"). Every fault goes through the fault-injection
interface (imuhal.emulation.faults)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import yaml

from imuhal.core.samples import MagSample, PressureSample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import Registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile, parse_profile
from imuhal.profile.model import BoardProfile
from imuhal.sim.errors import ScalarErrorSpec, SensorErrorSpec

MATCH_UT = 0.3
"""An ideal AK8963's field lies within its quantisation (0.15 uT x ASA per axis, under 0.3
uT as a vector) of the truth at the instant it measured."""
FAST_TURN = {"rotation_s": 0.5, "ramp_s": 0.1, "hold_s": 0.0}
"""``tumble`` turning a revolution in 0.5 s: about 4.7 uT between two AK8963 measurements
(100 Hz), so an ideal chip's field tells which measurement it carries."""
LIFT = {"start_hold_s": 1.2, "speed_m_s": 4.0, "floors": 12, "ramp_s": 0.5}
"""``elevator`` climbing 4 m/s from 1.7 s: about 48 Pa/s."""
MS5611_NOISE_PA = 1.2
"""The MS5611's RMS noise at OSR 4096 (its error spec), the only error of the lift run."""


@dataclass
class CopyLags:
    fields: int
    """Valid magnetometer fields delivered."""
    lags_ns: list[int]
    """Stamp minus the AK8963's measurement instant, for each field whose value tells it
    apart (exactly one measurement within MATCH_UT)."""


def gps_vario_without_startup(registry: Registry) -> BoardProfile:
    """seed-gps-vario without the still-board gyro start-up (a board that moves from t=0)."""
    doc = yaml.safe_load(bundled_profiles()["seed-gps-vario.yaml"].read_text())
    del doc["devices"]["imu"]["calibration"]
    return parse_profile(yaml.safe_dump(doc, sort_keys=False), "seed-gps-vario.yaml", registry)


def auto_read_copy_lags(registry: Registry, *, seconds: float = 2.5) -> CopyLags:
    """seed-gps-vario (AK8963 through the MPU-9250's slave 0), ideal chips, FAST_TURN; the
    host stalls 43.7 ms before a barometer poll every 0.25 s from 0.5 s, so the MPU-9250
    falls due inside each stall."""
    stall = HostStall(device="baro", start_s=0.5, end_s=seconds, every_s=0.25, stall_s=0.0437)
    with open_emulated(gps_vario_without_startup(registry), registry, scenario="tumble",
                       scenario_params=FAST_TURN, seed=3, sensor_errors=False,
                       faults=[stall]) as p:
        fields = [e for e in p.events(seconds) if isinstance(e, MagSample) and e.valid]
        instants = np.asarray(p.board.emulators["mag"].measured_ns)
        truth = np.array([p.board.truth_at(int(t)).magnetic_field_body_ut for t in instants])
    lags_ns = []
    for m in fields:
        near = np.nonzero(np.abs(instants - m.t_ns) < 100_000_000)[0]
        match = near[np.linalg.norm(truth[near] - np.asarray(m.vector), axis=1) <= MATCH_UT]
        if len(match) == 1:  # a field the turn tells apart from its neighbours'
            lags_ns.append(m.t_ns - int(instants[match[0]]))
    return CopyLags(len(fields), lags_ns)


def lift_pressure_errors_pa(registry: Registry, *, stall_s: float = 0.3,
                            seconds: float = 7.6) -> list[float]:
    """|pressure - truth at its stamp| of every valid MS5611 pressure of seed-gps-vario in
    the LIFT, its host stalling ``stall_s`` before a magnetometer poll every 0.5 s from
    2.5 s (the MS5611 falls due inside each stall); the IMU and magnetometer with their
    datasheet errors, the MS5611 with its noise alone."""
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    specs: dict[str, SensorErrorSpec | None] = {
        name: registry.emulators.get(dev.driver).error_spec
        for name, dev in profile.devices.items() if name in ("imu", "mag")}
    specs["baro"] = SensorErrorSpec(pressure=ScalarErrorSpec(noise_std=MS5611_NOISE_PA),
                                    temperature=ScalarErrorSpec(noise_std=0.002))
    stall = HostStall(device="mag", start_s=2.5, end_s=seconds - 0.2, every_s=0.5,
                      stall_s=stall_s)
    with open_emulated(profile, registry, scenario="elevator", scenario_params=LIFT, seed=1,
                       error_specs=specs, faults=[stall]) as p:
        pressures = [e for e in p.events(seconds) if isinstance(e, PressureSample) and e.valid]
        return [abs(e.pressure_pa - p.board.truth_at(e.t_ns).pressure_pa) for e in pressures]
