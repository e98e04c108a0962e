"""The measurement likelihoods p(y | x) of the particle filters (``likelihood=``): the Gaussian
N(y; h(x), R) by default, or heavy-tailed, uniform or quantized noise. R keeps its place in the
model: the scale matrix of the Student-t, the variances of the uniform noise, the noise before
quantization. Any other p(y | x) is a function ``likelihood(X, y, t, u)`` of all the particles
(see ``NonlinearModel.particle_filter``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Optional, Union

import numpy as np

from kfast import _kfast
from kfast._numbers import positive_real
from kfast.nonlinear.quantized import Quantized

__all__ = ["StudentT", "UniformNoise", "Quantized", "Likelihood", "ParticleMove"]


@dataclass(frozen=True)
class StudentT:
    """y = h(x) + v with v multivariate Student-t of ``nu`` degrees of freedom and scale matrix
    R (the model's R; the covariance is nu/(nu - 2) R for nu > 2):

        log p(y | x) = log G((nu + m)/2) - log G(nu/2) - (m/2) log(nu pi) - 1/2 log det R
                       - (nu + m)/2 log(1 + e' R^-1 e / nu),     e = y - h(x)

    Heavy tails: an outlier moves the weights far less than under the Gaussian (which is the
    limit nu -> inf). Angular outputs have their residuals wrapped."""

    nu: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "nu", positive_real("nu", self.nu))


@dataclass(frozen=True)
class UniformNoise:
    """y = h(x) + v with v_i uniform on +-sqrt(3 R_ii), independent (the model's R diagonal,
    its diagonal the variances): p(y | x) = prod 1/(2 a_i) when every |y_i - h_i(x)| <= a_i, else
    0. A particle outside the box gets weight 0; if none is inside, the step is an error."""


ParticleFunction = Callable[[np.ndarray, np.ndarray, int, Optional[np.ndarray]], Any]
"""``fn(X, y, t, u)`` of the particles X (M, n), y(t) (m,), the step and the input row (or None),
or a compiled function (numba ``@cfunc``, ``scipy.LowLevelCallable``, ctypes) of
``kfast.nonlinear.model.PARTICLE_C_SIGNATURE``."""

Likelihood = Union[StudentT, UniformNoise, Quantized, ParticleFunction, Any]
"""A ready likelihood, or the user's ``likelihood(X, y, t, u)`` returning the M log p(y | x_i)."""

ParticleMove = Union[ParticleFunction, Any]
"""The user's ``move(X, y, t, u)`` returning the M moved particles (M, n)."""


def _spec(likelihood: Any, m: int) -> Optional[tuple]:
    """The compiled calls' form of ``likelihood`` for m outputs (None: the Gaussian)."""
    if likelihood is None:
        return None
    if isinstance(likelihood, StudentT):
        return ("student_t", float(likelihood.nu), None)
    if isinstance(likelihood, UniformNoise):
        return ("uniform", 0.0, None)
    if isinstance(likelihood, Quantized):
        return ("quantized", 0.0, likelihood._spec(m))
    raise _kfast.KfastError(
        "likelihood: expected None (Gaussian), kfast.StudentT, kfast.UniformNoise, kfast.Quantized or a function "
        f"likelihood(X, y, t, u), got {type(likelihood).__name__}"
    )
