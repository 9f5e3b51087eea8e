"""The estimator interface and its output types. Estimators live in plugins."""

from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.outputs import AttitudeEstimate, Estimate, VerticalEstimate

__all__ = ["AttitudeEstimate", "Estimate", "Estimator", "EstimatorSettings", "VerticalEstimate"]
