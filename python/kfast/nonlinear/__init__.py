"""Nonlinear filters of a NonlinearModel: the extended and unscented Kalman filters and the
particle filter."""

from kfast.nonlinear.batch import ekf_batch, ukf_batch
from kfast.nonlinear.model import BuiltinFunction, NonlinearModel
from kfast.nonlinear.particle import ParticleResult
from kfast.nonlinear.streaming import ExtendedKalmanFilter, UnscentedKalmanFilter

__all__ = ["NonlinearModel", "BuiltinFunction", "ExtendedKalmanFilter", "UnscentedKalmanFilter", "ekf_batch", "ukf_batch", "ParticleResult"]
