"""Code the AHRS estimator plugins share: sample collection, gating, quaternion helpers."""
