"""Core model: samples, errors, frames, clocks. Knows no chip and no estimator."""
