"""Properties that hold for every model (hypothesis, derandomized so runs are reproducible):
covariances symmetric PSD, P_filt <= P_pred, scaling invariance, streaming equals batch."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import kfast
from modelgen import random_case

cases = st.builds(
    random_case,
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(1, 6),
    m=st.integers(1, 4),
    T=st.integers(1, 25),
    inputs=st.booleans(),
    correlated=st.booleans(),
    time_varying=st.booleans(),
    missing=st.sampled_from(["none", "rows", "partial"]),
)
forms = st.sampled_from(["joseph", "standard"])
SETTINGS = settings(max_examples=60, deadline=None, derandomize=True)


def min_eig_ratio(P):
    """Smallest eigenvalue relative to the largest (per matrix of a stack)."""
    eig = np.linalg.eigvalsh(P)
    return eig[..., 0] / np.maximum(np.abs(eig).max(axis=-1), 1e-300)


def run(case, form="joseph"):
    model = kfast.LinearGaussian(**case.model)
    return model.filter(case.y, case.x0, case.P0, u=case.u, form=form)


@SETTINGS
@given(case=cases, form=forms)
def test_covariances_are_symmetric_psd(case, form):
    res = run(case, form)
    for P in (res.P_pred, res.P_filt, res.S):
        np.testing.assert_array_equal(P, np.swapaxes(P, -1, -2))
        assert (min_eig_ratio(P) > -1e-10).all()


@SETTINGS
@given(case=cases, form=forms)
def test_filtering_never_increases_the_covariance(case, form):
    res = run(case, form)
    diff = res.P_pred - res.P_filt
    scale = np.abs(res.P_pred).max(axis=(1, 2))
    assert (np.linalg.eigvalsh(diff)[:, 0] >= -1e-10 * scale).all()


@SETTINGS
@given(case=cases, alpha=st.floats(1e-3, 1e3))
def test_scaling_q_r_n_p0_scales_p_and_keeps_gains(case, alpha):
    """(alpha Q, alpha R, alpha N, alpha P0) gives alpha P and the same K, K_pred, estimates."""
    res = run(case)
    scaled = dict(case.model)
    for k in ("Q", "R", "N"):
        if k in scaled:
            scaled[k] = alpha * scaled[k]
    model = kfast.LinearGaussian(**scaled)
    res_a = model.filter(case.y, case.x0, alpha * case.P0, u=case.u)
    for name in ("P_pred", "P_filt", "S"):
        np.testing.assert_allclose(getattr(res_a, name), alpha * getattr(res, name), rtol=1e-8, atol=1e-12 * alpha)
    for name in ("K", "K_pred", "x_filt", "x_pred"):
        a, b = getattr(res_a, name), getattr(res, name)
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-8 * max(1.0, np.abs(b).max()))


@SETTINGS
@given(case=cases, form=forms)
def test_streaming_equals_batch(case, form):
    res = run(case, form)
    kf = kfast.KalmanFilter(kfast.LinearGaussian(**case.model), case.x0, case.P0, form=form)
    for t in range(len(case.y)):
        u = None if case.u is None else case.u[t]
        np.testing.assert_array_equal(kf.x, res.x_pred[t])
        np.testing.assert_array_equal(kf.P, res.P_pred[t])
        kf.update(case.y[t], u)
        np.testing.assert_array_equal(kf.x, res.x_filt[t])
        np.testing.assert_array_equal(kf.P, res.P_filt[t])
        kf.predict(u)
    np.testing.assert_array_equal(kf.x, res.x_next)
    np.testing.assert_array_equal(kf.P, res.P_next)
    assert kf.loglik == pytest.approx(res.loglik, rel=1e-12, abs=1e-12)


def test_innovations_are_white_under_the_true_model():
    """Under the true model e(t) is white with covariance S(t) (Söderström ex. 6.16)."""
    case = random_case(11, n=3, m=2, T=4000)
    res = run(case)
    white = np.array([np.linalg.solve(np.linalg.cholesky(S), e) for S, e in zip(res.S, res.innov)])
    lag0 = white.T @ white / len(white)
    lag1 = white[1:].T @ white[:-1] / len(white)
    np.testing.assert_allclose(lag0, np.eye(2), atol=0.1)
    np.testing.assert_allclose(lag1, 0, atol=0.1)
