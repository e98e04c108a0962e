"""The general multivariable k-step predictor (kfast.poly.varmax_predictor, Söderström
(7.24)-(7.31)) against the scalar ARMA predictor, the Kalman k-step predictor of the same
VARMAX model in block observer form, the identity y(t+k) - ŷ(t+k|t) = Σ_{j<k} h_j e(t+k-j),
and the error covariance by simulation (seeded)."""

import numpy as np
import pytest
from scipy.signal import lfilter

import kfast


def stable_matrix_poly(rng, degree, p, radius=0.8):
    """I + M1 q^-1 + .. with the block companion's spectral radius at most ``radius``."""
    while True:
        M = np.concatenate([np.eye(p)[None], rng.normal(scale=0.4, size=(degree, p, p))])
        comp = np.zeros((degree * p, degree * p))
        comp[:p] = -np.concatenate(M[1:], axis=1)
        comp[p:, :-p] = np.eye((degree - 1) * p)
        if np.max(np.abs(np.linalg.eigvals(comp))) < radius:
            return M


def varmax(seed, p=2, na=2, nu=1):
    rng = np.random.default_rng(4200 + seed)
    A = stable_matrix_poly(rng, na, p, radius=1.05 if seed % 3 == 2 else 0.9)  # one seed: A unstable allowed
    C = stable_matrix_poly(rng, na, p)
    B = rng.normal(size=(na, p, nu))  # descending powers, degree na - 1 < deg A
    Lam = np.cov(rng.normal(size=(p, 3 * p))) + 0.1 * np.eye(p)
    return A, B, C, Lam, rng


def observer_form(A, B, C, Lam):
    """x(t+1) = F x + G u + K e, y = H x + e (block observer form of A y = B u + C e)."""
    na, p = len(A) - 1, A.shape[1]
    n = na * p
    F = np.zeros((n, n))
    F[:, :p] = -np.concatenate(A[1:], axis=0)
    F[:-p, p:] = np.eye(n - p)
    K = np.concatenate([C[i] - A[i] for i in range(1, na + 1)], axis=0)
    G = np.concatenate(list(np.concatenate([np.zeros((1,) + B.shape[1:]), B])[1:]), axis=0)
    H = np.eye(p, n)
    return kfast.LinearGaussian(F, H, K @ Lam @ K.T, Lam, B=G, N=K @ Lam), F, G, H


def simulate(A, B, C, Lam, u, rng):
    T, p, na = len(u), A.shape[1], len(A) - 1
    e = rng.multivariate_normal(np.zeros(p), Lam, size=T)
    Bf = np.concatenate([np.zeros((1,) + B.shape[1:]), B])
    y = np.zeros((T, p))
    for t in range(T):
        acc = e[t].copy()
        for i in range(1, min(t, na) + 1):
            acc += -A[i] @ y[t - i] + C[i] @ e[t - i] + Bf[i] @ u[t - i]
        y[t] = acc
    return y, e


@pytest.mark.parametrize("k", [1, 3])
@pytest.mark.parametrize("seed", range(4))
def test_scalar_case_is_the_arma_predictor(seed, k):
    rng = np.random.default_rng(seed)
    A = np.poly(rng.uniform(-0.8, 0.8, 2))
    C = np.poly(rng.uniform(-0.8, 0.8, 2))
    B = rng.normal(size=2)
    scalar = kfast.poly.arma_predictor(A, C, k, lam2=1.7, B=B)
    general = kfast.poly.varmax_predictor(A, C, k, Lambda=[[1.7]], B=B)
    np.testing.assert_allclose(general.F[:, 0, 0], scalar.F, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(general.L[:, 0, 0], scalar.L, rtol=1e-12, atol=1e-14)
    assert general.error_cov[0, 0] == pytest.approx(scalar.error_variance, rel=1e-12)
    y, u = rng.normal(size=200), rng.normal(size=200)
    # The transfer functions with zero initial conditions: ŷ(t+k|t) = qL/C y(t) + qBF/C u(t),
    # where qBF/C = q^(k-1) (qBF q^-(na+k-1)) / (C q^-na) reaches u(t+k-1).
    num_u = np.pad(scalar.num_u, (len(C) + k - 1 - len(scalar.num_u), 0))
    T = len(y)
    want = lfilter(scalar.num, scalar.den, y)[: T - k] + lfilter(num_u, scalar.den, u)[k - 1: T - 1]
    got = general.predict(y, u)[:, 0]
    assert np.all(np.isnan(got[:k]))
    np.testing.assert_allclose(got[k:], want, rtol=1e-9, atol=1e-11)


@pytest.mark.parametrize("k", [1, 2, 5])
@pytest.mark.parametrize("seed", range(6))
def test_equals_the_kalman_k_step_predictor(seed, k):
    A, B, C, Lam, rng = varmax(seed)
    pred = kfast.poly.varmax_predictor(A, C, k, Lambda=Lam, B=B)
    T = 120
    u = rng.normal(size=(T, B.shape[2]))
    y, _ = simulate(A, B, C, Lam, u, rng)
    got = pred.predict(y, u)
    model, F, G, H = observer_form(A, B, C, Lam)
    n = F.shape[0]
    # Zero initial conditions = x(0) = 0 known: with P0 = 0 the Kalman gain is K from the start.
    res = model.filter(y, x0=np.zeros(n), P0=np.zeros((n, n)), u=u, outputs=("x_pred",))
    x1 = res.x_pred  # x̂(t|t-1)
    for t in range(T - k):
        x = x1[t + 1]  # x̂(t+1|t)
        for j in range(t + 1, t + k):
            x = F @ x + G @ u[j]
        np.testing.assert_allclose(got[t + k], H @ x, rtol=1e-8, atol=1e-9)


@pytest.mark.parametrize("k", [1, 4])
def test_error_is_the_moving_average_of_future_innovations_and_has_the_covariance(k):
    A, B, C, Lam, rng = varmax(1)
    pred = kfast.poly.varmax_predictor(A, C, k, Lambda=Lam, B=B)
    T = 40_000
    u = rng.normal(size=(T, 1))
    y, e = simulate(A, B, C, Lam, u, rng)
    err = y - pred.predict(y, u)
    want = sum(np.vstack([np.zeros((j, 2)), e[: T - j] @ pred.F[j].T]) for j in range(k))
    np.testing.assert_allclose(err[k:], want[k:], rtol=1e-7, atol=1e-8)
    sample = np.cov(err[k:].T)
    # Seeded: the sample covariance of 40,000 draws within 5% of (7.30).
    np.testing.assert_allclose(sample, pred.error_cov, rtol=0.05, atol=0.05 * np.abs(pred.error_cov).max())
    assert np.trace(pred.error_cov @ np.diag([1.0, 2.0])) == pytest.approx(
        sum(np.trace(np.diag([1.0, 2.0]) @ h @ Lam @ h.T) for h in pred.F), rel=1e-12)  # (7.31)


def test_bad_input():
    A = [np.eye(2), 0.5 * np.eye(2)]
    C = [np.eye(2), 0.2 * np.eye(2)]
    with pytest.raises(ValueError, match="A: the leading coefficient"):
        kfast.poly.varmax_predictor([2 * np.eye(2), 0.5 * np.eye(2)], C, 1)
    with pytest.raises(ValueError, match="C: must have the degree and size of A"):
        kfast.poly.varmax_predictor(A, [np.eye(2)], 1)
    with pytest.raises(ValueError, match="C: det C"):
        kfast.poly.varmax_predictor(A, [np.eye(2), [[2.0, 0], [0, 0.1]]], 1)
    with pytest.raises(ValueError, match="k: the prediction horizon"):
        kfast.poly.varmax_predictor(A, C, 0)
    with pytest.raises(ValueError, match="Lambda: must be symmetric"):
        kfast.poly.varmax_predictor(A, C, 1, Lambda=[[1.0, 2.0], [2.0, 1.0]])
    with pytest.raises(ValueError, match="B: degree 1 must be below"):
        kfast.poly.varmax_predictor(A, C, 1, B=np.ones((2, 2, 1)))
    pred = kfast.poly.varmax_predictor(A, C, 1, B=np.ones((1, 2, 1)))
    with pytest.raises(ValueError, match="u: the model has an input"):
        pred.predict(np.zeros((5, 2)))
    with pytest.raises(ValueError, match="y: non-finite value at time step 3"):
        pred.predict(np.r_[np.zeros((3, 2)), np.full((1, 2), np.nan)], np.zeros((4, 1)))
    y = np.zeros((4, 2))
    y_before = y.copy()
    pred.predict(y, np.zeros((4, 1)))
    np.testing.assert_array_equal(y, y_before)
