"""Variometer estimators: altitude and climb rate from a barometer, optionally fused with AHRS.

- ``baro-vario`` (baro_estimator, baro_kalman): 2-state barometer-only Kalman filter.
- ``vario-kf3`` (kf3_estimator, kf3, kf3_settings): the seed's 3-state altitude / climb /
  accelerometer-bias filter; ``kf3.Kalman3`` is the core in the seed's cm units with
  reference modes esp32 (default), avario and y2021.
- batch: ``run_batch`` / ``run_baro_batch`` over recorded arrays (SI units).
- tuning: ``estimate_altitude_variance`` (sigma_zmeas^2 from 1-2 s at rest).
- downsample: IMU-rate acceleration -> one mean per barometer interval.
- gate: the altitude innovation gate both filters share (``InnovationGate``).
"""
