"""The "decoupled" estimator: inclination and heading corrected separately, gyro bias at rest."""
