"""Nonlinear Gaussian filters: the extended and unscented Kalman filters of a NonlinearModel."""

from kfast.nonlinear.model import BuiltinFunction, NonlinearModel

__all__ = ["NonlinearModel", "BuiltinFunction"]
