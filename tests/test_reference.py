"""kfast's Rust filter against the NumPy reference (python/kfast/reference) on 240 seeded
random models: n 1-10, m 1-5, with and without B, D and N, constant and per-step matrices,
no / whole-row / partial missing data, both update forms."""

import itertools

import numpy as np
import pytest

import kfast
from kfast.reference import kalman_filter
from modelgen import random_case

FIELDS = ["x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "K_pred", "loglik_t", "x_next", "P_next"]

# Every combination of the options, cycled over the seeds.
OPTIONS = list(itertools.product([False, True], [False, True], [False, True], ["none", "rows", "partial"]))


def case_for(seed):
    inputs, correlated, time_varying, missing = OPTIONS[seed % len(OPTIONS)]
    rng = np.random.default_rng(1000 + seed)
    n, m = int(rng.integers(1, 11)), int(rng.integers(1, 6))
    return random_case(seed, n, m, inputs=inputs, correlated=correlated, time_varying=time_varying, missing=missing)


def assert_close(got, want, name, rtol=1e-10):
    got, want = np.asarray(got), np.asarray(want)
    scale = max(1.0, float(np.nanmax(np.abs(want)))) if want.size else 1.0
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale, err_msg=name)


@pytest.mark.parametrize("seed", range(240))
def test_filter_matches_reference(seed):
    case = case_for(seed)
    form = "joseph" if seed % 2 == 0 else "standard"
    model = kfast.LinearGaussian(**case.model)
    res = model.filter(case.y, case.x0, case.P0, u=case.u, form=form)
    ref = kalman_filter(**case.model, y=case.y, x0=case.x0, P0=case.P0, u=case.u, form=form)
    for name in FIELDS:
        assert_close(getattr(res, name), ref[name], f"{name} {case.info}")
    assert res.loglik == pytest.approx(ref["loglik"], rel=1e-10)
    assert model.loglik(case.y, case.x0, case.P0, u=case.u, form=form) == pytest.approx(res.loglik, rel=1e-12)


def test_reference_covers_every_option():
    seen = {tuple(OPTIONS[s % len(OPTIONS)]) for s in range(240)}
    assert seen == set(OPTIONS)
    dims = {(case_for(s).info["n"], case_for(s).info["m"]) for s in range(240)}
    assert {n for n, _ in dims} == set(range(1, 11)) and {m for _, m in dims} == set(range(1, 6))


def test_loglik_matches_dense_gaussian_density():
    """Söderström ex. 6.18: the filter factorizes cov(Y); check against the stacked density."""
    from scipy.stats import multivariate_normal

    case = random_case(7, n=3, m=2, T=12, inputs=True, correlated=True)
    F, H, Q, R, N, B, D = (case.model[k] for k in ["F", "H", "Q", "R", "N", "B", "D"])
    T, n, m = 12, 3, 2
    # Stacked z = [x0, w0, v0, w1, v1, ...]: y[t] = H x[t] + D u[t] + v[t].
    mean = np.zeros(T * m)
    cov_xx = [case.P0]
    mx = [case.x0]
    for t in range(T):
        mean[t * m : (t + 1) * m] = H @ mx[t] + D @ case.u[t]
        mx.append(F @ mx[t] + B @ case.u[t])
    # Cov(x[s], x[t]), Cov(x[t], v[t']) built from the recursion x[t+1] = F x[t] + w[t].
    Jw = np.block([[Q, N], [N.T, R]])
    dim = n + T * (n + m)
    L = np.zeros((T, n, dim))  # x[t] as a linear map of z
    L[0][:, :n] = np.eye(n)
    Vsel = np.zeros((T, m, dim))
    for t in range(T):
        Vsel[t][:, n + t * (n + m) + n : n + (t + 1) * (n + m)] = np.eye(m)
        if t + 1 < T:
            L[t + 1] = F @ L[t]
            L[t + 1][:, n + t * (n + m) : n + t * (n + m) + n] += np.eye(n)
    covz = np.zeros((dim, dim))
    covz[:n, :n] = case.P0
    for t in range(T):
        s = n + t * (n + m)
        covz[s : s + n + m, s : s + n + m] = Jw
    Y = np.concatenate([H @ L[t] + Vsel[t] for t in range(T)])
    dense = multivariate_normal(mean, Y @ covz @ Y.T).logpdf(case.y.ravel())
    res = kfast.LinearGaussian(**case.model).filter(case.y, case.x0, case.P0, u=case.u)
    assert res.loglik == pytest.approx(dense, rel=1e-10)
