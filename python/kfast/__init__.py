"""kfast: Kalman filters, smoothers and Riccati solvers with a Rust core.

Model and conventions (docs/conventions.md)::

    x[t+1] = F x[t] + B u[t] + w[t]      w ~ N(0, Q)
    y[t]   = H x[t] + D u[t] + v[t]      v ~ N(0, R),  E[w[t] v[t]'] = N
    prior  x[0] ~ N(x0, P0)              (x0, P0) is x(0|-1): the first step is an update

>>> import kfast
>>> m = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
>>> res = m.filter([0.3, -0.1, 0.7], x0=0.0, P0=1.0)
>>> float(res.P_pred[1, 0, 0])  # Söderström ex. 6.17: P = 1 is the stationary solution
1.0
"""

from kfast._kfast import (
    FixedLagSmoother,
    InnovationCovarianceError,
    KalmanFilter,
    KfastError,
    NoStabilizingSolutionError,
    __version__,
)
from kfast.linear.model import (
    FilterResult,
    FixedLagResult,
    FixedPointResult,
    Forecast,
    LinearGaussian,
    Simulation,
    SmootherResult,
)

from kfast.linear.diagnostics import Diagnostics
from kfast.linear.posterior import DisturbanceSmootherResult, PosteriorDraws
from kfast.arithmetic import deterministic, kernel_info, set_deterministic
from kfast.nonlinear.model import NonlinearModel
from kfast.nonlinear.particle import ParticleResult
from kfast.nonlinear.median import mean_filter, median_filter, order_statistic_pdf
from kfast.nonlinear.likelihood import StudentT, UniformNoise
from kfast.nonlinear.quantized import (
    Quantized,
    QuantizedMoments,
    quantize,
    quantized_loglik,
    quantized_moments,
    quantized_second_moment,
    sheppard,
)
from kfast.nonlinear.streaming import ExtendedKalmanFilter, ParticleFilter, UnscentedKalmanFilter
from kfast.nonlinear.batch import ekf_batch, ukf_batch
from kfast.multiple import IMM, IMMFilter, IMMResult, ModelBank, gaussian_sum, imm_filter, model_bank
from kfast.linear.batch import BatchResult, filter_batch
from kfast.linear.estimation import EMResult, FitResult, fit
from kfast.linear.score import loglik_score
from kfast.sampling import KalmanBucy, discretize, expm, kalman_bucy, stationary_cov_continuous
from kfast.riccati.stationary import InnovationsForm, SteadyState
from kfast.riccati.solvers import (
    solve_continuous_are,
    solve_continuous_lyapunov,
    solve_discrete_are,
    solve_discrete_lyapunov,
)

from kfast import models  # noqa: E402  (the model catalogue: kfast.models.constant_velocity, ...)
from kfast import sigma  # noqa: E402  (sigma-point sets: kfast.sigma.merwe, julier, cubature)
from kfast import plot  # noqa: E402  (matplotlib is imported on the first plot)
from kfast import dask  # noqa: E402  (series over Dask collections; dask is imported on the first call)
from kfast import control  # noqa: E402  (LQ, LQG and dynamic programming: kfast.control.lqr, ...)
from kfast import poly  # noqa: E402  (polynomial methods: kfast.poly.spectral_factor, diophantine, ...)

__all__ = [
    "models",
    "sigma",
    "control",
    "poly",
    "LinearGaussian",
    "NonlinearModel",
    "ExtendedKalmanFilter",
    "UnscentedKalmanFilter",
    "ParticleFilter",
    "median_filter",
    "mean_filter",
    "order_statistic_pdf",
    "quantize",
    "sheppard",
    "quantized_loglik",
    "quantized_moments",
    "quantized_second_moment",
    "QuantizedMoments",
    "Quantized",
    "StudentT",
    "UniformNoise",
    "IMMFilter",
    "IMM",
    "ModelBank",
    "IMMResult",
    "imm_filter",
    "model_bank",
    "gaussian_sum",
    "FilterResult",
    "Diagnostics",
    "DisturbanceSmootherResult",
    "PosteriorDraws",
    "SmootherResult",
    "ParticleResult",
    "FixedLagResult",
    "FixedPointResult",
    "Forecast",
    "Simulation",
    "KalmanFilter",
    "FixedLagSmoother",
    "filter_batch",
    "ekf_batch",
    "ukf_batch",
    "BatchResult",
    "fit",
    "loglik_score",
    "FitResult",
    "EMResult",
    "KfastError",
    "InnovationCovarianceError",
    "NoStabilizingSolutionError",
    "solve_discrete_are",
    "solve_continuous_are",
    "solve_discrete_lyapunov",
    "solve_continuous_lyapunov",
    "expm",
    "discretize",
    "kalman_bucy",
    "SteadyState",
    "InnovationsForm",
    "KalmanBucy",
    "stationary_cov_continuous",
    "set_deterministic",
    "deterministic",
    "kernel_info",
]
