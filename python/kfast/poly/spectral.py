"""Scalar spectral factorization (Söderström Sec. 4.4, Thm 4.2, Lemma 4.6; (7.80), (11.81)):
a symmetric Laurent polynomial φ(z) = r_0 + Σ_k r_k (z^k + z^-k), nonnegative on the unit
circle, written as λ² B(z) B(z^-1) with B monic of degree d and its zeros in |z| <= 1. Two
routes that must agree: the zeros of z^d φ(z) (those inside the circle), and the stationary
Kalman filter of the process with covariances r_k (the Riccati route of Thm 4.2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast._args import choice
from kfast._kfast import KfastError, NoStabilizingSolutionError
from kfast import _kfast
from kfast._arrays import as_float64
from kfast.poly._poly import roots

__all__ = ["SpectralFactor", "spectral_factor", "evaluate_spectrum"]

SpectralMethod = Literal["roots", "riccati"]

# A zero this close to the unit circle counts as on it (Lemma 4.6: they come in pairs).
_CIRCLE_TOL = 1e-6


@dataclass(frozen=True, repr=False)
class SpectralFactor:
    """φ(z) = lam2 · B(z) B(z^-1) / (A(z) A(z^-1)), B and A monic with their zeros in |z| <= 1."""

    B: np.ndarray
    """Monic numerator factor (descending powers of z)."""
    A: np.ndarray
    """Monic denominator factor ([1.] for a polynomial spectrum)."""
    lam2: float
    """The scale λ² (the innovation variance of the model y = (B/A) e)."""
    on_circle: bool
    """Whether B has zeros on the unit circle (Lemma 4.6: no invertible model then)."""
    method: str

    def __repr__(self) -> str:
        return f"SpectralFactor(deg B={len(self.B) - 1}, deg A={len(self.A) - 1}, lam2={self.lam2:.6g}, method={self.method!r})"


def _laurent(name: str, value: ArrayLike) -> np.ndarray:
    """A symmetric Laurent coefficient array (odd length, highest power first), outer zeros removed."""
    r = as_float64(name, value)
    r = r.reshape(1) if r.ndim == 0 else r
    if r.ndim != 1 or not np.all(np.isfinite(r)):
        raise KfastError(f"{name}: expected a 1-D array of finite Laurent coefficients, got {r!r}")
    if r.size % 2 == 0:
        raise KfastError(f"{name}: a symmetric Laurent polynomial has an odd number of coefficients (z^d .. z^-d), got {r.size}")
    scale = float(np.abs(r).max(initial=0.0))
    if scale == 0.0:
        raise KfastError(f"{name}: is the zero spectrum")
    if not np.allclose(r, r[::-1], rtol=0.0, atol=1e-12 * scale):
        raise KfastError(f"{name}: must be symmetric (r_k = r_-k), got {r}")
    while r.size > 1 and r[0] == 0.0 and r[-1] == 0.0:
        r = r[1:-1]
    return (r + r[::-1]) / 2


def evaluate_spectrum(r: ArrayLike, omega: ArrayLike) -> np.ndarray:
    """φ(e^{iω}) = r_0 + 2 Σ_k r_k cos(k ω) of the symmetric Laurent coefficients ``r``."""
    r = np.asarray(r, float)
    d = (r.size - 1) // 2
    w = np.asarray(omega, float)
    k = np.arange(1, d + 1)
    return r[d] + 2 * np.cos(np.multiply.outer(w, k)) @ r[d + 1:] if d else np.full(w.shape, r[0])


def _check_nonnegative(name: str, r: np.ndarray) -> None:
    """φ >= 0 on a grid of at least 4096 frequencies in [0, π], by one real FFT."""
    d = (r.size - 1) // 2
    size = 8192 * (1 + 4 * d // 8192)
    seq = np.zeros(size)
    seq[: d + 1] = r[d:]
    if d:
        seq[-d:] = r[:d]
    phi = np.fft.rfft(seq).real  # r_0 + 2 Σ r_k cos(2π j k / size), j = 0 .. size/2
    grid = np.linspace(0.0, np.pi, len(phi))
    low = int(np.argmin(phi))
    if phi[low] < -1e-10 * np.abs(r).max():
        raise KfastError(
            f"{name}: the spectrum is negative on the unit circle (φ(ω) = {phi[low]:.6g} at ω = {grid[low]:.6g}): "
            "not a spectral density"
        )


def _by_roots(name: str, r: np.ndarray) -> tuple[np.ndarray, float, bool]:
    """The zeros of z^d φ pair as (z, 1/z̄): the d smallest in modulus are one of each pair, also
    for a double zero on the circle, which rounding splits to 1 ± O(√ε) (Lemma 4.6). In Rust
    (kfast::poly::spectral_factor), which also checks φ >= 0 on the circle."""
    try:
        B, lam2, on_circle = _kfast.spectral_factor_roots(r)
    except KfastError as exc:
        raise KfastError(str(exc).replace("r: ", f"{name}: ", 1)) from None
    return np.asarray(B), float(lam2), bool(on_circle)


def _by_riccati(name: str, r: np.ndarray) -> tuple[np.ndarray, float, bool]:
    """The innovations model of a process with covariances r_0, .., r_d (Söderström Thm 4.2):
    Σ_k r_k z^-k (k >= 1) = H (zI - F)^-1 G with F the down-shift, G = e1, H = (r_1 .. r_d);
    the filter DARE with Q = 0, R = r_0, N = G (the positive-real form, solved for -P) gives
    the predictor gain K, λ² = r_0 - H P H' and B(z) = det(zI - F + K H)."""
    from kfast.riccati.solvers import dare

    d = (r.size - 1) // 2
    if d == 0:
        return np.ones(1), float(r[0]), False
    F = np.eye(d, k=-1)
    G = np.zeros((d, 1))
    G[0, 0] = 1.0
    H = r[d + 1:].reshape(1, d)
    try:
        sol = dare(F.T, H.T, np.zeros((d, d)), np.array([[r[d]]]), s=G, eigenvalues=False)
    except NoStabilizingSolutionError:
        raise KfastError(
            f"{name}: the spectrum has zeros on (or too near) the unit circle: the Riccati route found no "
            "stabilizing solution (Söderström Lemma 4.6); use method=\"roots\""
        ) from None
    K = sol["gain"].T
    lam2 = float(r[d] + (H @ sol["x"] @ H.T)[0, 0])
    B = np.real(np.poly(F - K @ H))
    # A double zero on the circle leaves the closed loop F - K H marginally stable: the DARE's
    # solution converges only like the distance to the circle (about 1e-8 here).
    on_circle = bool(np.any(np.abs(roots(B)) > 1.0 - _CIRCLE_TOL)) if d else False
    return B, lam2, on_circle


def _factor(name: str, value: ArrayLike, method: str) -> tuple[np.ndarray, float, bool]:
    r = _laurent(name, value)
    if method == "roots":
        return _by_roots(name, r)
    _check_nonnegative(name, r)
    return _by_riccati(name, r)


def spectral_factor(
    r: Optional[ArrayLike] = None,
    *,
    num: Optional[ArrayLike] = None,
    den: Optional[ArrayLike] = None,
    method: SpectralMethod = "roots",
) -> SpectralFactor:
    """The spectral factor of a rational spectrum (Söderström Sec. 4.4, (7.80), (11.81)).

    Parameters
    ----------
    r : array_like, optional
        Symmetric Laurent coefficients of φ(z), highest power first: (r_d, .., r_1, r_0, r_1, ..,
        r_d) for φ(z) = r_0 + Σ r_k (z^k + z^-k), i.e. φ(e^{iω}) = r_0 + 2 Σ r_k cos kω.
    num, den : array_like, optional
        Instead of ``r``: a rational spectrum num(z)/den(z), each a symmetric Laurent polynomial
        as ``r`` (``den`` defaults to 1).
    method : {"roots", "riccati"}
        "roots": the zeros of z^d φ(z) inside the unit circle (zeros on the circle handled as
        pairs, Lemma 4.6, to about 1e-8); "riccati": the stationary Kalman filter of a process
        with those covariances (Thm 4.2; zeros on the circle make its closed loop marginally
        stable: about 1e-8 accurate, or refused when the DARE finds no stabilizing solution).
        They agree to rounding away from the circle.

    Returns
    -------
    SpectralFactor
        B, A monic with zeros in |z| <= 1 and λ²: φ = λ² B B* / (A A*).

    Raises
    ------
    KfastError
        When the spectrum is negative somewhere on the unit circle, not symmetric, or (Riccati
        route) has zeros on the circle.

    Examples
    --------
    φ(ω) = 1.4225 - 1.5 cos ω + 0.5 cos 2ω: the minimum-phase factor 1 - 0.6 z^-1 + 0.25 z^-2.

    >>> f = kfast.poly.spectral_factor([0.25, -0.75, 1.4225, -0.75, 0.25])
    >>> print(f.B.round(12), round(f.lam2, 12))
    [ 1.   -0.6   0.25] 1.0
    """
    how = choice("method", method, ("roots", "riccati"))
    if (r is None) == (num is None):
        raise KfastError("r: give either r (a polynomial spectrum) or num (and den), not both or neither")
    if r is not None:
        B, lam2, on_circle = _factor("r", r, how)
        return SpectralFactor(B=B, A=np.ones(1), lam2=lam2, on_circle=on_circle, method=how)
    assert num is not None
    B, lam_num, on_circle = _factor("num", num, how)
    A, lam_den, den_on_circle = _factor("den", 1.0 if den is None else den, how)
    if den_on_circle:
        raise KfastError("den: has zeros on the unit circle: the spectrum is not integrable (infinite variance)")
    return SpectralFactor(B=B, A=A, lam2=lam_num / lam_den, on_circle=on_circle, method=how)
