"""Seeded random state-space models for the tests (shared by several test files)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np


@dataclass
class Case:
    """A model, data and prior, as keyword arguments for kfast and the reference."""

    model: dict  # F, H, Q, R and optionally B, D, N
    y: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    u: Optional[np.ndarray] = None
    info: dict = field(default_factory=dict)


def random_spd(rng, n, jitter=0.1):
    A = rng.standard_normal((n, n))
    return A @ A.T / n + jitter * np.eye(n)


def stable_monic(rng, degree, radius=0.9):
    """A monic real polynomial of the given degree with seeded random zeros (real ones and
    conjugate pairs) inside |z| < radius; np.ones(1) for degree 0."""
    zeros = []
    while len(zeros) < degree:
        if degree - len(zeros) >= 2 and rng.uniform() < 0.5:
            z = rng.uniform(0.05, radius) * np.exp(1j * rng.uniform(0.1, np.pi - 0.1))
            zeros += [z, np.conj(z)]
        else:
            zeros.append(rng.uniform(-radius, radius))
    return np.atleast_1d(np.real(np.poly(zeros)))


def random_transition(rng, n, radius):
    F = rng.standard_normal((n, n))
    rho = max(abs(np.linalg.eigvals(F)))
    return F * (radius / rho) if rho > 0 else F


def random_case(
    seed: int,
    n: int,
    m: int,
    T: int = 30,
    inputs: bool = False,
    correlated: bool = False,
    time_varying: bool = False,
    missing: str = "none",  # "none", "rows", "partial"
    k: int = 2,
) -> Case:
    """A random model with radius(F) in [0.5, 1], joint noise covariance positive definite,
    data simulated from it, and the chosen pattern of missing values."""
    rng = np.random.default_rng(seed)
    steps = T if time_varying else None

    def per_step(make):
        return np.stack([make() for _ in range(T)]) if time_varying else make()

    radius = rng.uniform(0.5, 1.0)
    F0 = random_transition(rng, n, radius)
    H0 = rng.standard_normal((m, n))
    F = per_step(lambda: F0 + (0.05 * rng.standard_normal((n, n)) if time_varying else 0))
    H = per_step(lambda: H0 + (0.1 * rng.standard_normal((m, n)) if time_varying else 0))
    J = per_step(lambda: random_spd(rng, n + m))
    Q, R = J[..., :n, :n].copy(), J[..., n:, n:].copy()
    model = {"F": F, "H": H, "Q": Q, "R": R}
    if correlated:
        model["N"] = J[..., :n, n:].copy()
    u = None
    if inputs:
        model["B"] = per_step(lambda: rng.standard_normal((n, k)))
        model["D"] = per_step(lambda: rng.standard_normal((m, k)))
        u = rng.standard_normal((T, k))
    x0 = rng.standard_normal(n)
    P0 = random_spd(rng, n, jitter=0.5)
    y = simulate(rng, model, x0, P0, T, u)
    if missing == "rows":
        y[rng.random(T) < 0.25] = np.nan
    elif missing == "partial":
        y[rng.random((T, m)) < 0.25] = np.nan
        y[rng.random(T) < 0.1] = np.nan
    info = dict(seed=seed, n=n, m=m, T=T, steps=steps, inputs=inputs, correlated=correlated, missing=missing)
    return Case(model=model, y=y, x0=x0, P0=P0, u=u, info=info)


def at(M, t):
    """The matrix in force at step t: M itself, or M[t] for a per-step stack."""
    return M[t] if M.ndim == 3 else M


def simulate(rng, model, x0, P0, T, u=None):
    """y from the model with jointly Gaussian (w, v) of covariance [[Q, N], [N', R]]."""
    n = len(x0)
    m = model["H"].shape[-2]
    x = rng.multivariate_normal(x0, P0)
    y = np.zeros((T, m))
    for t in range(T):
        Q, R = at(model["Q"], t), at(model["R"], t)
        N = at(model["N"], t) if "N" in model else np.zeros((n, m))
        J = np.block([[Q, N], [N.T, R]])
        wv = rng.multivariate_normal(np.zeros(n + m), J)
        y[t] = at(model["H"], t) @ x + wv[n:]
        x_next = at(model["F"], t) @ x + wv[:n]
        if u is not None:
            y[t] += at(model["D"], t) @ u[t]
            x_next += at(model["B"], t) @ u[t]
        x = x_next
    return y
