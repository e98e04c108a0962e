"""Polynomial methods in plain NumPy by routes independent of kfast.poly's (Söderström ch. 7):
the predictor identity by the triangular system (7.21), the spectral factor as the limit of the
Cholesky (innovations) factorization of the Toeplitz covariance matrix, and the causal Wiener
filter by the causal projection (7.57) on an FFT grid."""

from __future__ import annotations

import numpy as np

__all__ = ["predictor_triangular", "spectral_factor_toeplitz", "wiener_causal_fft"]


def predictor_triangular(A, C, k):
    """F and L of z^(k-1) C = A F + L by forward substitution (Söderström (7.21)):
    f_j = c_j - Σ_{i=1}^{j} a_i f_(j-i) (j < k), ℓ_(j-k) = c_j - Σ a_i f_(j-i) (j = k .. n+k-1)."""
    A, C = np.asarray(A, float), np.asarray(C, float)
    n = len(A) - 1
    a = np.r_[A, np.zeros(k + n)]
    c = np.r_[C, np.zeros(k + n)]
    f = np.zeros(k)
    f[0] = 1.0
    for j in range(1, k):
        f[j] = c[j] - sum(a[i] * f[j - i] for i in range(1, j + 1))
    L = np.array([c[j] - sum(a[i] * f[j - i] for i in range(j - k + 1, min(j, n) + 1)) for j in range(k, n + k)])
    return f, L


def spectral_factor_toeplitz(r, size=400):
    """B and λ² of φ = λ² B B* for symmetric Laurent coefficients r (highest power first): the
    Cholesky factor of the (size x size) Toeplitz covariance matrix R = L D L' is the innovations
    representation of the MA process, and its last row converges to B's coefficients, its last
    pivot to λ² (the Bauer / innovations algorithm)."""
    r = np.asarray(r, float)
    d = (len(r) - 1) // 2
    col = np.zeros(size)
    col[: d + 1] = r[d:]
    R = col[np.abs(np.subtract.outer(np.arange(size), np.arange(size)))]
    Lc = np.linalg.cholesky(R)
    lam2 = Lc[-1, -1] ** 2
    row = Lc[-1, -(d + 1):] / Lc[-1, -1]  # coefficients of y(t - d) .. y(t) in the innovation
    return row[::-1], float(lam2)


def wiener_causal_fft(C, A, lam_v2, M, N, lam_e2, m=0, grid=1 << 14):
    """The causal Wiener filter's impulse response by (7.57) on an FFT grid: with the innovations
    model y = H e, φ_y = λε² H H*, G = [φ_sy H*^-1 / λε²]_+ H^-1, φ_sy = z^-m λv² |C/A|²;
    the causal part keeps the coefficients of z^0, z^-1, ... Returns (impulse response of G,
    error variance ∫ φ_s - |G|² φ_y)."""
    w = 2 * np.pi * np.arange(grid) / grid
    z = np.exp(1j * w)
    phi_s = lam_v2 * np.abs(np.polyval(C, z) / np.polyval(A, z)) ** 2
    phi_w = lam_e2 * np.abs(np.polyval(M, z) / np.polyval(N, z)) ** 2
    phi_y = phi_s + phi_w
    # Minimum-phase H with H(∞) = 1 from the cepstrum of φ_y.
    cep = np.fft.ifft(np.log(phi_y)).real
    lam_eps = np.exp(cep[0])
    fold = np.zeros(grid)
    fold[1: grid // 2] = cep[1: grid // 2]  # causal part of log H (coefficients of z^-k, k >= 1)
    Hz = np.exp(np.fft.fft(fold))  # H(e^{iω}) as Σ h_k e^{-ikω}
    phi_sy = phi_s * np.exp(-1j * w * m)  # s(t - m): z^-m φ_s (w is independent of s)
    # [φ_sy / (λε² H*)]_+ : back to lags, keep k >= 0 (coefficients of z^-k).
    X = phi_sy / (lam_eps * np.conj(Hz))
    x = np.fft.ifft(X)  # x[k] = coefficient of e^{-ikω}
    x[grid // 2:] = 0.0
    G = np.fft.fft(x) / Hz
    g = np.fft.ifft(G).real
    error = np.mean(phi_s - np.abs(G) ** 2 * phi_y)
    return g, float(error)
