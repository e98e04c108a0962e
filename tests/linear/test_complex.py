"""Complex-valued models (LinearGaussian with complex matrices, Qc/Rc): with proper noise the
result equals the complex Kalman filter and RTS smoother with Hermitian transposes; with improper
noise it equals the augmented (widely linear) filter on [x; x̄] — both NumPy references
(python/kfast/reference/complex.py) independent of the real composite form kfast uses."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import kfast
from kfast.linear.complex import ComplexLinearGaussian, complex_covariance
from kfast.reference.complex import augmented_kalman_filter, complex_kalman_filter, complex_rts


def crandn(rng, *shape):
    return rng.standard_normal(shape) + 1j * rng.standard_normal(shape)


def hermitian_pd(rng, n, jitter=0.2):
    A = crandn(rng, n, n)
    return A @ A.conj().T / n + jitter * np.eye(n)


def case(seed, improper=False):
    rng = np.random.default_rng(1200 + seed)
    n, m, T = int(rng.integers(1, 5)), int(rng.integers(1, 4)), 25
    F = crandn(rng, n, n)
    F *= 0.9 / np.abs(np.linalg.eigvals(F)).max()
    H = crandn(rng, m, n)
    Q, R = hermitian_pd(rng, n), hermitian_pd(rng, m)
    y = crandn(rng, T, m)
    x0, P0 = crandn(rng, n), hermitian_pd(rng, n)
    extra = {}
    if improper:
        # A complementary covariance with the augmented matrix [[Γ, Γ̃], [Γ̃*, Γ*]] still PSD.
        for name, G, k in (("Qc", Q, n), ("Rc", R, m)):
            S = crandn(rng, k, k)
            S = (S + S.T) / 2
            lam = np.linalg.eigvalsh(G)[0]
            extra[name] = 0.8 * lam * S / np.linalg.norm(S, 2)
    return F, H, Q, R, y, x0, P0, extra


@pytest.mark.parametrize("seed", range(10))
def test_proper_noise_is_the_complex_kalman_filter(seed):
    F, H, Q, R, y, x0, P0, _ = case(seed)
    if seed % 3 == 0:
        y[3, 0] = np.nan + 0j
        y[7] = np.nan
    model = kfast.LinearGaussian(F, H, Q, R)
    assert isinstance(model, ComplexLinearGaussian)
    res = model.filter(y, x0, P0)
    ref = complex_kalman_filter(F, H, Q, R, y, x0, P0)
    for name in ("x_pred", "P_pred", "x_filt", "P_filt", "loglik_t"):
        np.testing.assert_allclose(getattr(res, name), ref[name], rtol=1e-9, atol=1e-10, err_msg=name)
    assert res.loglik == pytest.approx(ref["loglik"], rel=1e-10)
    np.testing.assert_allclose(res.P_filt_c, 0.0, atol=1e-12)
    # Proper results are converted from half the composite covariance (2 (C_RR + i C_IR)): the
    # composite run keeps the proper structure to rounding, so the full conversion agrees.
    n = F.shape[0]
    for name in ("P_pred", "P_filt", "P_next"):
        C = getattr(res.real, name)
        full = complex_covariance(C, n)
        np.testing.assert_allclose(getattr(res, name), full, rtol=1e-12, atol=1e-13 * np.abs(full).max(), err_msg=name)
        np.testing.assert_allclose(complex_covariance(C, n, complementary=True), 0.0, atol=1e-13 * np.abs(full).max())
    assert model.loglik(y, x0, P0) == res.loglik
    sm = model.smooth(y, x0, P0)
    ref_s = complex_rts(F, H, Q, R, np.where(np.isnan(y), np.nan, y), x0, P0)
    if seed % 3:
        np.testing.assert_allclose(sm.x_smooth, ref_s["x_smooth"], rtol=1e-8, atol=1e-9)
        np.testing.assert_allclose(sm.P_smooth, ref_s["P_smooth"], rtol=1e-8, atol=1e-9)


@pytest.mark.parametrize("seed", range(8))
def test_improper_noise_is_the_widely_linear_filter(seed):
    F, H, Q, R, y, x0, P0, extra = case(seed, improper=True)
    n = len(x0)
    P0c = 0.3 * np.linalg.eigvalsh(P0)[0] * np.eye(n)
    model = kfast.LinearGaussian(F, H, Q, R, **extra)
    res = model.filter(y, x0, P0, P0c=P0c)
    ref = augmented_kalman_filter(F, H, Q, R, extra["Qc"], extra["Rc"], y, x0, P0, P0c)
    np.testing.assert_allclose(res.x_filt, ref["x_filt"], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(res.P_filt, ref["P_filt"], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(res.P_filt_c, ref["P_filt_c"], rtol=1e-9, atol=1e-10)
    assert res.loglik == pytest.approx(ref["loglik"], rel=1e-10)
    # The strictly linear filter ignores Qc, Rc: it is a different (suboptimal) estimate.
    plain = complex_kalman_filter(F, H, Q, R, y, x0, P0)
    assert np.abs(plain["x_filt"] - res.x_filt).max() > 1e-6


def test_pickling_and_bad_input():
    F, H, Q, R, y, x0, P0, extra = case(1, improper=True)
    model = kfast.LinearGaussian(F, H, Q, R, **extra)
    again = pickle.loads(pickle.dumps(model))
    assert again.filter(y, x0, P0).loglik == model.filter(y, x0, P0).loglik
    with pytest.raises(ValueError, match="Q: must be Hermitian"):
        kfast.LinearGaussian(F, H, Q + 1j * np.triu(np.ones_like(Q.real), 1), R)
    with pytest.raises(ValueError, match="Rc: a complementary covariance E z z\\^T must be symmetric"):
        kfast.LinearGaussian(F, H, Q, R, Rc=np.triu(np.ones_like(R.real), 1) + 0.1 * np.eye(len(R)) if len(R) > 1 else [[1.0, 2.0]])
    with pytest.raises(ValueError, match="y: expected shape"):
        model.filter(y[:, :0] if y.shape[1] > 1 else np.zeros((3, 2)), x0, P0)
    with pytest.raises(ValueError, match="x0: expected"):
        model.filter(y, np.zeros(len(x0) + 1), P0)
