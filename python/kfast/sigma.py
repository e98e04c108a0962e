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
========  ==========================  =====================================================

(Julier 2002 and Wan & van der Merwe 2000; Julier & Uhlmann 1997; Arasaratnam & Haykin 2009.)
The filter computes the unscented transform in a centred form (deviations from the centre
point), so a small alpha -- whose W_0 is about -n / alpha^2 -- does not cancel digits away.
"""

from __future__ import annotations

from dataclasses import dataclass

from kfast import _kfast
from kfast._args import choice

__all__ = ["SigmaPoints", "merwe", "julier", "cubature"]


@dataclass(frozen=True)
class SigmaPoints:
    """A sigma-point set: ``kind`` ("merwe", "julier" or "cubature") and its parameters."""

    kind: str
    alpha: float = 1.0
    beta: float = 0.0
    kappa: float = 0.0

    def __post_init__(self) -> None:
        choice("kind", self.kind, ("merwe", "julier", "cubature"))
        for name in ("alpha", "beta", "kappa"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise _kfast.KfastError(f"{name}: expected a number, got {value!r}")
            object.__setattr__(self, name, float(value))

    def _spec(self) -> tuple[str, float, float, float]:
        return (self.kind, self.alpha, self.beta, self.kappa)


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
