"""Nonlinear Gaussian filters: the extended and unscented Kalman filters of a NonlinearModel."""

from kfast.nonlinear.batch import ekf_batch, ukf_batch
from kfast.nonlinear.model import BuiltinFunction, NonlinearModel
from kfast.nonlinear.streaming import ExtendedKalmanFilter, UnscentedKalmanFilter

__all__ = ["NonlinearModel", "BuiltinFunction", "ExtendedKalmanFilter", "UnscentedKalmanFilter", "ekf_batch", "ukf_batch"]
