"""Sigma-point sets for the unscented Kalman filter (``NonlinearModel.ukf(points=...)``).

Each set places points at the mean x and at x +- c a_i for the columns a_i of the lower Cholesky
factor of P, in the order [centre, +1 .. +n, -1 .. -n], and weights them:

========  ==========================  =====================================================
set       c                           weights
========  ==========================  =====================================================
merwe     sqrt(n + lambda),           Wm_0 = lambda / (n + lambda),
          lambda = alpha^2 (n+kappa)  Wc_0 = Wm_0 + 1 - alpha^2 + beta, W_i = 1 / 2(n + lambda)
          - n
julier    sqrt(n + kappa)             W_0 = kappa / (n + kappa), W_i = 1 / 2(n + kappa)
cubature  sqrt(n)                     no centre point, W_i = 1 / 2n
custom    X_i = x + L xi_i            the given Wm (summing to 1) and Wc
========  ==========================  =====================================================

(Julier 2002 and Wan & van der Merwe 2000; Julier & Uhlmann 1997; Arasaratnam & Haykin 2009.)
The filter computes the unscented transform in a centred form (deviations from the centre
point), so a small alpha -- whose W_0 is about -n / alpha^2 -- does not cancel digits away;
a custom set by the plain sums about the mean, z = sum Wm_i Z_i and
Cov(z) = sum Wc_i (Z_i - z)(Z_i - z)'.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast import _kfast
from kfast._args import choice
from kfast._arrays import frozen_copy

__all__ = ["SigmaPoints", "merwe", "julier", "cubature", "custom"]


@dataclass(frozen=True)
class SigmaPoints:
    """A sigma-point set: ``kind`` ("merwe", "julier", "cubature" or "custom") and its
    parameters (a custom set: its unit points and weights, see :func:`custom`)."""

    kind: str
    alpha: float = 1.0
    beta: float = 0.0
    kappa: float = 0.0
    unit: Optional[np.ndarray] = field(default=None, repr=False, compare=False)
    Wm: Optional[np.ndarray] = field(default=None, repr=False, compare=False)
    Wc: Optional[np.ndarray] = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        choice("kind", self.kind, ("merwe", "julier", "cubature", "custom"))
        if (self.kind == "custom") != (self.unit is not None):
            raise _kfast.KfastError("points: unit points go with kind 'custom' only (use kfast.sigma.custom)")
        for name in ("alpha", "beta", "kappa"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise _kfast.KfastError(f"{name}: expected a number, got {value!r}")
            object.__setattr__(self, name, float(value))

    def _spec(self) -> _kfast.PointsSpec:
        return (self.kind, self.alpha, self.beta, self.kappa, self.unit, self.Wm, self.Wc)


def merwe(alpha: float = 1e-3, beta: float = 2.0, kappa: float = 0.0) -> SigmaPoints:
    """Scaled sigma points (Julier 2002; Wan & van der Merwe 2000): 2n + 1 points,
    lambda = alpha^2 (n + kappa) - n. beta = 2 is optimal for a Gaussian prior.

    >>> kfast.sigma.merwe(alpha=0.5)
    SigmaPoints(kind='merwe', alpha=0.5, beta=2.0, kappa=0.0)
    """
    return SigmaPoints("merwe", alpha, beta, kappa)


def julier(kappa: float = 0.0) -> SigmaPoints:
    """Julier & Uhlmann's (1997) points: 2n + 1 points, c = sqrt(n + kappa) (kappa = 3 - n
    matches the Gaussian's kurtosis in one dimension)."""
    return SigmaPoints("julier", kappa=kappa)


def cubature() -> SigmaPoints:
    """The third-degree spherical-radial cubature rule (Arasaratnam & Haykin 2009): 2n points
    x +- sqrt(n) a_i with equal weights 1 / 2n; all weights positive."""
    return SigmaPoints("cubature")


def custom(points: ArrayLike, Wm: ArrayLike, Wc: Optional[ArrayLike] = None) -> SigmaPoints:
    """A sigma-point set of your own for state size n: unit points xi_i (the rows of ``points``,
    shape (k, n)), placed at X_i = x + L xi_i with L the lower Cholesky factor of P, mean
    weights ``Wm`` (k,) summing to 1 and covariance weights ``Wc`` (k,; default ``Wm``). The
    unscented transform takes the plain sums about the mean; angular outputs are differenced
    to the first point and wrapped. Checked when a filter runs with it (n must match).

    The cubature rule written out for n = 2:

    >>> xi = np.sqrt(2) * np.array([[1.0, 0], [0, 1], [-1, 0], [0, -1]])
    >>> kfast.sigma.custom(xi, np.full(4, 0.25))
    SigmaPoints(kind='custom', alpha=1.0, beta=0.0, kappa=0.0)
    """
    unit = frozen_copy("points", points)
    if unit.ndim != 2 or unit.shape[0] == 0 or unit.shape[1] == 0:
        raise _kfast.KfastError(f"points: expected unit points of shape (k, n), got {unit.shape}")
    wm = frozen_copy("Wm", Wm)
    wc = wm if Wc is None else frozen_copy("Wc", Wc)
    for name, w in (("Wm", wm), ("Wc", wc)):
        if w.shape != (unit.shape[0],):
            raise _kfast.KfastError(f"{name}: expected one weight per point, shape ({unit.shape[0]},), got {w.shape}")
    return SigmaPoints("custom", unit=unit, Wm=wm, Wc=wc)
