"""kfast.poly against the NumPy references of python/kfast/reference/poly.py, each computed by
another route: the predictor identity by the triangular system (7.21), the spectral factor as the
limit of the Toeplitz covariance's Cholesky factor, and the causal Wiener filter by the causal
projection (7.57) on an FFT grid with a cepstral spectral factor."""

from __future__ import annotations

import numpy as np
import pytest

import kfast
from modelgen import stable_monic as _stable_monic
from kfast.reference.poly import predictor_triangular, spectral_factor_toeplitz, wiener_causal_fft


def stable_monic(rng, degree, radius=0.85):
    return _stable_monic(rng, degree, radius)


@pytest.mark.parametrize("seed", range(8))
def test_predictor_identity_by_the_triangular_system(seed):
    rng = np.random.default_rng(seed)
    n, k = int(rng.integers(1, 6)), int(rng.integers(1, 6))
    A, C = stable_monic(rng, n, 1.2), stable_monic(rng, n)
    F, L = kfast.poly.predictor_identity(A, C, k)
    F_ref, L_ref = predictor_triangular(A, C, k)
    np.testing.assert_allclose(F, F_ref, atol=1e-10)
    np.testing.assert_allclose(L, L_ref, atol=1e-10)


@pytest.mark.parametrize("seed", range(6))
def test_spectral_factor_by_the_toeplitz_cholesky_limit(seed):
    rng = np.random.default_rng(50 + seed)
    C = stable_monic(rng, int(rng.integers(1, 6)))
    r = rng.uniform(0.5, 2.0) * kfast.poly.laurent(C, C)
    f = kfast.poly.spectral_factor(r)
    B_ref, lam2_ref = spectral_factor_toeplitz(r)
    np.testing.assert_allclose(f.B, B_ref, atol=1e-8)
    assert f.lam2 == pytest.approx(lam2_ref, rel=1e-8)


@pytest.mark.parametrize("m", [0, 2, -1])
@pytest.mark.parametrize("seed", range(4))
def test_causal_wiener_by_the_fft_causal_projection(seed, m):
    rng = np.random.default_rng(80 + seed)
    n, r = int(rng.integers(1, 4)), int(rng.integers(0, 3))
    spec = dict(C=stable_monic(rng, n), A=stable_monic(rng, n), lam_v2=rng.uniform(0.5, 2.0),
                M=stable_monic(rng, r), N=stable_monic(rng, r), lam_e2=rng.uniform(0.2, 2.0))
    g = kfast.poly.wiener_causal(**spec, m=m)
    h_ref, error_ref = wiener_causal_fft(spec["C"], spec["A"], spec["lam_v2"], spec["M"], spec["N"], spec["lam_e2"], m=m)
    # Impulse response of num/den (descending powers of q, den monic): h = num/den in q^-1.
    num = np.r_[np.zeros(len(g.den) - len(g.num)), g.num]
    h = np.zeros(60)
    for t in range(60):
        h[t] = (num[t] if t < len(num) else 0.0) - sum(g.den[i] * h[t - i] for i in range(1, len(g.den)) if t - i >= 0)
    np.testing.assert_allclose(h, h_ref[:60], atol=1e-7)
    assert g.error_variance == pytest.approx(error_ref, rel=1e-7)


def causal_part_fft(G, top, D, P, grid=1 << 14):
    """[G / (D P*)]_+ by the FFT: the coefficients of z^0, z^-1, ... of the expansion on the circle."""
    w = 2 * np.pi * np.arange(grid) / grid
    z = np.exp(1j * w)
    Gz = np.polyval(G, z) * z ** (top - (len(G) - 1))
    Pstar = np.polyval(P, 1 / z)
    x = np.fft.ifft(Gz / (np.polyval(D, z) * Pstar))  # x[k] = coefficient of z^-k
    x[grid // 2:] = 0.0
    return np.fft.ifft(np.fft.fft(x)).real  # the causal impulse response


@pytest.mark.parametrize("seed", range(8))
def test_causal_part_by_the_fft_projection(seed):
    rng = np.random.default_rng(300 + seed)
    G = rng.standard_normal(int(rng.integers(1, 7)))
    top = int(rng.integers(-2, 5))
    D, P = stable_monic(rng, int(rng.integers(1, 4))), stable_monic(rng, int(rng.integers(0, 3)))
    num, den = kfast.poly.causal_part(G, top, D, P)
    h = np.zeros(40)
    lead = np.r_[np.zeros(max(0, len(den) - len(num))), num]
    for t in range(40):
        h[t] = (lead[t] if t < len(lead) else 0.0) - sum(den[i] * h[t - i] for i in range(1, len(den)) if t - i >= 0)
    np.testing.assert_allclose(h, causal_part_fft(G, top, D, P)[:40], atol=1e-9)
