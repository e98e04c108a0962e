"""Wiener filters for a signal in coloured noise (Söderström Sec. 7.3-7.4):

    y(t) = s(t) + w(t),   s = [C(q)/A(q)] v,   w = [M(q)/N(q)] e,   v ⊥ e white, var λv², λe²

(C, A monic of degree n; M, N monic of degree r; all zeros inside the unit circle), estimating
s(t - m) from y(t), y(t-1), ... — m = 0 filtering, m > 0 smoothing with lag m, m < 0 prediction
(Söderström's convention). Transfer functions are returned as numerator and denominator in
descending powers of q: ŝ(t - m) = [num(q)/den(q)] y(t).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast._args import index
from kfast import _kfast
from kfast._kfast import KfastError
from kfast._numbers import positive_real
from kfast.poly._poly import laurent, monic, polymul, polysub, reciprocal, require_stable, trim
from kfast.poly.equations import two_sided
from kfast.poly.spectral import spectral_factor

__all__ = ["WienerFilter", "wiener_causal", "wiener_noncausal", "wiener_fir"]


@dataclass(frozen=True, repr=False)
class WienerFilter:
    """ŝ(t - m) = [num(q) / den(q)] y(t); for the non-causal filter num and den are Laurent
    polynomials (highest power ``num_top`` / ``den_top``), for the FIR filter den = [1]."""

    num: np.ndarray
    den: np.ndarray
    error_variance: float
    """E (s(t - m) - ŝ(t - m))²."""
    lag: int
    num_top: int
    """The power of z of num[0] (deg num for a causal filter)."""
    den_top: int
    model: tuple
    """(C, A, lam_v2, M, N, lam_e2) of the signal and noise."""
    error_variance_by_order: Optional[np.ndarray] = None
    """FIR filters only: entry k is the error variance of the FIR filter of order k
    (k = 0..order), from the same Levinson recursion; non-increasing in k."""

    def frequency_response(self, omega: ArrayLike) -> np.ndarray:
        """G(e^{iω}) at the frequencies ``omega`` (rad/sample)."""
        z = np.exp(1j * np.asarray(omega, float))

        def value(c: np.ndarray, top: int) -> np.ndarray:
            return np.polyval(c, z) * z ** (top - (len(c) - 1))

        return value(self.num, self.num_top) / value(self.den, self.den_top)

    def error_spectrum(self, omega: ArrayLike) -> np.ndarray:
        """The spectrum of the error s(t - m) - ŝ(t - m) at ``omega``:
        λv² |e^{-imω} - G|² |C/A|² + λe² |G|² |M/N|² (for the causal filter Söderström (7.89),
        for the non-causal one the bound (7.93)); its mean over [0, 2π) is the error variance."""
        C, A, lv, M, N, le = self.model
        w = np.asarray(omega, float)
        z = np.exp(1j * w)
        G = self.frequency_response(w)
        phi_s = lv * np.abs(np.polyval(C, z) / np.polyval(A, z)) ** 2
        phi_w = le * np.abs(np.polyval(M, z) / np.polyval(N, z)) ** 2
        return np.abs(np.exp(-1j * self.lag * w) - G) ** 2 * phi_s + np.abs(G) ** 2 * phi_w

    def __repr__(self) -> str:
        return f"WienerFilter(lag={self.lag}, error_variance={self.error_variance:.6g})"


def _signal_and_noise(C, A, lam_v2, M, N, lam_e2):
    C_, A_ = monic("C", C), monic("A", A)
    M_ = monic("M", [1.0] if M is None else M)
    N_ = monic("N", [1.0] if N is None else N)
    if len(C_) != len(A_):
        raise KfastError(f"C: must have the degree of A ({len(A_) - 1}), got {len(C_) - 1}")
    if len(M_) != len(N_):
        raise KfastError(f"M: must have the degree of N ({len(N_) - 1}), got {len(M_) - 1}")
    for name, p in (("C", C_), ("A", A_), ("M", M_), ("N", N_)):
        require_stable(name, p)
    return C_, A_, positive_real("lam_v2", lam_v2), M_, N_, positive_real("lam_e2", lam_e2)


def _lag(m: object) -> int:
    """Söderström's lag m: an integer of any sign."""
    if isinstance(m, (bool, np.bool_)) or not isinstance(m, (int, np.integer)):
        raise KfastError(f"m: expected an integer lag (m > 0 smooths, m < 0 predicts), got {m!r}")
    if abs(int(m)) > 10_000:
        raise KfastError(f"m: the lag {m} is too large (|m| <= 10000)")
    return int(m)


def _innovations(C_, A_, lv, M_, N_, le):
    """(7.80): λε² B B* = λv² C C* N N* + λe² A A* M M*."""
    signal = lv * laurent(polymul(C_, N_), polymul(C_, N_))
    noise = le * laurent(polymul(A_, M_), polymul(A_, M_))
    f = spectral_factor(signal + noise)
    return f.B, f.lam2


def _variance_of(num: np.ndarray, den: np.ndarray) -> float:
    """(1/2π) ∫ |num(e^{iω})|² / |den(e^{iω})|² dω for den stable: num is shifted by powers of z
    (|z| = 1) until proper."""
    from kfast.control.polynomial import closed_loop_variance

    num = trim(np.asarray(num, float))
    extra = max(0, len(num) - len(den))
    return closed_loop_variance(num / den[0], np.r_[den, np.zeros(extra)] / den[0])


def wiener_causal(
    C: ArrayLike,
    A: ArrayLike,
    lam_v2: float,
    M: Optional[ArrayLike] = None,
    N: Optional[ArrayLike] = None,
    lam_e2: float = 1.0,
    m: int = 0,
    prefilter: Optional[tuple] = None,
) -> WienerFilter:
    """The causal (realizable) Wiener filter, the minimum-variance estimate of s(t - m) from y
    up to t (Söderström (7.76)-(7.89)): the spectral factor (7.80) λε² B B*, the two-sided
    Diophantine equation z^-m C C* N* = z^min(0,-m) B* R + z^max(0,-m) A L* (7.84) and
    G = (λv²/λε²) z^min(0,-m) R N / B (7.86). Error variance from (7.89):
    (λv² λe²/λε²) E|C M/B e|² + (λv⁴/λε²) E|L*/B* e|².

    ``prefilter=(Fp, Hp)`` minimises E[P(q) s̃(t)]² instead, P = Fp/Hp monic of equal degree with
    zeros strictly inside (7.94)-(7.104): z^-m Fp C C* N* = z^min(0,-m) B* R̃ + z^max(0,-m) Hp A L0*
    (7.103) and G = (λv²/λε²) z^min(0,-m) R̃ N / (B Fp) (7.104); ``error_variance`` is then still
    E s̃² (not the weighted criterion), from the error spectrum.

    Examples
    --------
    AR(1) signal in white noise, filtering (m = 0):

    >>> g = kfast.poly.wiener_causal([1, 0], [1, -0.8], 1.0, lam_e2=1.0)
    >>> g.num.shape, g.den.shape  # G(q) = g0 q / (q + d1)
    ((2,), (2,))
    >>> print(round(g.num[0], 6), round(g.den[1], 6), round(g.error_variance, 6))  # P(t|t) of the Kalman filter
    0.578051 -0.33756 0.578051
    """
    C_, A_, lv, M_, N_, le = _signal_and_noise(C, A, lam_v2, M, N, lam_e2)
    lag = _lag(m)
    n, r = len(A_) - 1, len(N_) - 1
    Fp, Hp = _prefilter(prefilter)
    dp = len(Fp) - 1
    B, lam_eps = _innovations(C_, A_, lv, M_, N_, le)
    alpha, beta = min(0, -lag), max(0, -lag)
    # lhs = z^-m Fp(z) C(z) C(z^-1) N(z^-1): top power n + dp - m. P* = P(z^-1) as powers
    # z^0 .. z^-deg P is the reversed array (kfast.poly.reciprocal).
    lhs = polymul(polymul(Fp, laurent(C_, C_)), reciprocal(N_))
    lhs_top = n + dp - lag
    deg_R = n + dp - alpha
    deg_L = n + r - 1 + beta
    R, L_star = two_sided(lhs, lhs_top, reciprocal(B), alpha, deg_R, polymul(Hp, A_), beta, deg_L)
    # G = gain z^alpha R N / (B Fp): as num/den in q, z^alpha moves to the denominator.
    num = trim(lv / lam_eps * polymul(R, N_))
    den = np.r_[polymul(B, Fp), np.zeros(-alpha)]
    model = (C_, A_, lv, M_, N_, le)
    if dp == 0:  # (7.89): the bound plus what causality costs
        variance = lv * le / lam_eps * _variance_of(polymul(C_, M_), B) + lv**2 / lam_eps * _variance_of(L_star, B)
    else:
        variance = _error_variance(num, den, lag, model)
    return WienerFilter(num=num, den=den, error_variance=variance, lag=lag, num_top=len(num) - 1, den_top=len(den) - 1, model=model)


def _prefilter(prefilter: Optional[tuple]) -> tuple[np.ndarray, np.ndarray]:
    if prefilter is None:
        return np.ones(1), np.ones(1)
    try:
        Fp, Hp = prefilter
    except (TypeError, ValueError):
        raise KfastError("prefilter: expected (Fp, Hp), the numerator and denominator of P(q)") from None
    Fp, Hp = monic("prefilter", Fp), monic("prefilter", Hp)
    if len(Fp) != len(Hp):
        raise KfastError(f"prefilter: Fp and Hp must have equal degree, got {len(Fp) - 1} and {len(Hp) - 1}")
    require_stable("prefilter", Fp)
    require_stable("prefilter", Hp)
    return Fp, Hp


def _error_variance(num: np.ndarray, den: np.ndarray, lag: int, model: tuple) -> float:
    """E s̃² for ŝ(t - m) = (num/den) y (den monic, causal): λv² E|(z^-m - G) C/A v|² + λe² E|G M/N e|²,
    each a rational filter made polynomial by powers of z (which keep the modulus on the circle)."""
    C, A, lv, M, N, le = model
    k = max(lag, 0)
    # (z^-m - num/den) = (z^(k-m) den - z^k num) / (z^k den)
    v_part = polymul(polysub(np.r_[den, np.zeros(k - lag)], np.r_[num, np.zeros(k)]), C)
    v_den = polymul(np.r_[den, np.zeros(k)], A)
    e_num, e_den = polymul(num, M), polymul(den, N)
    return lv * _variance_of(v_part, v_den) + le * _variance_of(e_num, e_den)


def wiener_noncausal(
    C: ArrayLike,
    A: ArrayLike,
    lam_v2: float,
    M: Optional[ArrayLike] = None,
    N: Optional[ArrayLike] = None,
    lam_e2: float = 1.0,
    m: int = 0,
) -> WienerFilter:
    """The non-causal (unrealizable) Wiener filter G = φ_sy/φ_y = z^-m (λv²/λε²) C C* N N*/(B B*)
    (Söderström (7.47)), as Laurent numerator and denominator; its error variance
    (λv² λe²/λε²) E|C M/B e|² is the lower bound of every causal filter's (7.93)."""
    C_, A_, lv, M_, N_, le = _signal_and_noise(C, A, lam_v2, M, N, lam_e2)
    lag = _lag(m)
    n, r = len(A_) - 1, len(N_) - 1
    B, lam_eps = _innovations(C_, A_, lv, M_, N_, le)
    num = lv / lam_eps * laurent(polymul(C_, N_), polymul(C_, N_))
    den = laurent(B, B)
    variance = lv * le / lam_eps * _variance_of(polymul(C_, M_), B)
    model = (C_, A_, lv, M_, N_, le)
    return WienerFilter(num=num, den=den, error_variance=variance, lag=lag, num_top=n + r - lag, den_top=n + r, model=model)


def wiener_fir(
    C: ArrayLike,
    A: ArrayLike,
    lam_v2: float,
    order: int,
    M: Optional[ArrayLike] = None,
    N: Optional[ArrayLike] = None,
    lam_e2: float = 1.0,
    m: int = 0,
) -> WienerFilter:
    """The FIR Wiener filter ŝ(t - m) = Σ_{j=0}^{order} g_j y(t - j): the normal equations
    Σ_j r_y(i - j) g_j = r_s(i - m), i = 0..order (orthogonality), error variance
    r_s(0) - g' r_s(· - m). Covariances from the state-space models of s and w (Lyapunov).

    The Toeplitz normal equations are solved by Levinson's recursion in O(order²), which
    passes through every smaller order: ``error_variance_by_order[k]`` is the error variance
    of the order-k filter (it decreases towards the causal Wiener filter's as k grows)."""
    from kfast.poly.arma import arma_to_ss

    C_, A_, lv, M_, N_, le = _signal_and_noise(C, A, lam_v2, M, N, lam_e2)
    p = index("order", order)
    lag = _lag(m)
    lags = np.arange(0, p + abs(lag) + 1)

    def cov(top: np.ndarray, bottom: np.ndarray, lam: float) -> np.ndarray:
        if len(bottom) == 1:  # white: r(0) = λ top0², MA terms none (monic, degree 0)
            out = np.zeros(len(lags))
            out[0] = lam
            return out
        return arma_to_ss(bottom, top, lam).autocovariance(lags)[:, 0, 0]

    r_s, r_w = cov(C_, A_, lv), cov(M_, N_, le)
    r_y = r_s + r_w
    r_sy = np.array([r_s[abs(i - lag)] for i in range(p + 1)])
    # r_y is positive definite (its one-step prediction error is at least λv² > 0).
    g, explained = _kfast.levinson(r_y[: p + 1], r_sy)
    by_order = r_s[0] - np.asarray(explained)
    model = (C_, A_, lv, M_, N_, le)
    return WienerFilter(num=np.asarray(g), den=np.ones(1), error_variance=float(by_order[-1]), lag=lag, num_top=0,
                        den_top=0, model=model, error_variance_by_order=by_order)
