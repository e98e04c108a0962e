"""Nonlinear filters of a NonlinearModel: the extended and unscented Kalman filters and the
particle filter; the median and mean filters and quantized measurements (Söderström 9.6-9.7)."""

from kfast.nonlinear.batch import ekf_batch, ukf_batch
from kfast.nonlinear.median import mean_filter, median_filter, order_statistic_pdf
from kfast.nonlinear.model import BuiltinFunction, NonlinearModel
from kfast.nonlinear.likelihood import StudentT, UniformNoise
from kfast.nonlinear.particle import ParticleResult
from kfast.nonlinear.quantized import Quantized, QuantizedMoments, quantize, quantized_loglik, quantized_moments, sheppard
from kfast.nonlinear.streaming import ExtendedKalmanFilter, ParticleFilter, UnscentedKalmanFilter

__all__ = ["NonlinearModel", "BuiltinFunction", "ExtendedKalmanFilter", "UnscentedKalmanFilter", "ekf_batch", "ukf_batch", "ParticleResult", "ParticleFilter",
           "median_filter", "mean_filter", "order_statistic_pdf",
           "quantize", "sheppard", "quantized_loglik", "quantized_moments", "QuantizedMoments", "Quantized", "StudentT", "UniformNoise"]
