"""What the particle filter returns."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

__all__ = ["ParticleResult"]


@dataclass(frozen=True, repr=False)
class ParticleResult:
    """What the particle filter computed over T steps with M particles (n states).

    Conventions as :class:`FilterResult`: the prior (x0, P0) is x(0|-1), row t of ``x_filt`` is
    x(t|t). The estimates are the weighted moments of the particles after the update with y(t)
    (Söderström (9.99)-(9.100)), before any resampling.
    """

    x_filt: np.ndarray
    """x(t|t), the weighted mean of the particles, shape (T, n)."""
    P_filt: np.ndarray
    """P(t|t), their weighted covariance, shape (T, n, n)."""
    ess: np.ndarray
    """The effective sample size 1 / sum_i W_i^2 after each update, in [1, M], shape (T,)."""
    resampled: np.ndarray
    """Whether the particles were resampled after the update of step t, bool, shape (T,) (the
    last step is not followed by a time update, so it is never resampled)."""
    loglik: float
    """The particle estimate of log p(y(0..T-1)): the sum of ``loglik_t``. Its exponential is an
    unbiased estimate of p(y) (not of the log); the log is biased low."""
    loglik_t: np.ndarray
    """The estimates of log p(y(t) | y(0..t-1)): log sum_i W_i(t-1) p(y(t) | x_i), with the
    weights carried into the step; 0 where nothing is observed. Shape (T,)."""
    particles: Optional[np.ndarray] = None
    """With ``keep="last"``: the particles of the last step, (M, n); ``keep="all"``: of every
    step, (T, M, n) (after the update, before resampling)."""
    log_weights: Optional[np.ndarray] = None
    """Their normalized log-weights (log sum exp = 0): (M,) or (T, M)."""

    def __repr__(self) -> str:
        steps, n = self.x_filt.shape
        return f"ParticleResult(T={steps}, n={n}, loglik={self.loglik:.6g}, resampled={int(self.resampled.sum())} steps)"
