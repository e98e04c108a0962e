"""Smoothers: RTS, fixed-lag, fixed-point against the NumPy reference, the MAP batch solve,
the augmented-state filter, statsmodels and pykalman; textbook case C."""

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from pykalman import KalmanFilter as PKKalmanFilter
from statsmodels.tsa.statespace.kalman_smoother import KalmanSmoother

import kfast
from kfast.reference import fixed_lag_augmented, fixed_point_augmented, map_smoother, rts_smoother
from modelgen import random_case

OPTIONS = list(itertools.product([False, True], [False, True], [False, True], ["none", "rows", "partial"]))
CASES = json.loads((Path(__file__).parent.parent / "data" / "textbook_cases.json").read_text())


def case_for(seed, T=25):
    inputs, correlated, time_varying, missing = OPTIONS[seed % len(OPTIONS)]
    rng = np.random.default_rng(2000 + seed)
    n, m = int(rng.integers(1, 7)), int(rng.integers(1, 4))
    return random_case(seed, n, m, T=T, inputs=inputs, correlated=correlated, time_varying=time_varying, missing=missing)


def close(got, want, what, rtol=1e-10):
    scale = max(1.0, float(np.nanmax(np.abs(want))))
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale, err_msg=what)


def smooth(case, **kw):
    return kfast.LinearGaussian(**case.model).smooth(case.y, case.x0, case.P0, u=case.u, **kw)


@pytest.mark.parametrize("seed", range(96))
def test_rts_matches_reference_and_map_solve(seed):
    case = case_for(seed)
    form = ("joseph", "standard")[seed % 2]
    res = smooth(case, form=form)
    xs, Ps, Pl, f = rts_smoother(**case.model, y=case.y, x0=case.x0, P0=case.P0, u=case.u, form=form)
    close(res.x_smooth, xs, f"x_smooth {case.info}")
    close(res.P_smooth, Ps, f"P_smooth {case.info}")
    close(res.P_lag1, Pl, f"P_lag1 {case.info}")
    close(res.filter.x_filt, f["x_filt"], "filter inside smooth")
    # Independent oracle: the MAP criterion (6.80) solved as one linear system.
    xm, Pm, Plm = map_smoother(**case.model, y=case.y, x0=case.x0, P0=case.P0, u=case.u)
    close(res.x_smooth, xm, f"x_smooth vs MAP {case.info}", rtol=1e-8)
    close(res.P_smooth, Pm, f"P_smooth vs MAP {case.info}", rtol=1e-8)
    close(res.P_lag1, Plm, f"P_lag1 vs MAP {case.info}", rtol=1e-8)


def test_rts_with_singular_predicted_covariance():
    """Q = 0 and a singular F make P(t+1|t) singular: the pseudo-inverse branch."""
    F = np.array([[0.9, 0.0], [0.0, 0.0]])
    model = kfast.LinearGaussian(F, np.array([[1.0, 1.0]]), np.zeros((2, 2)), np.array([[0.5]]))
    y = np.random.default_rng(5).standard_normal((10, 1))
    res = model.smooth(y, np.zeros(2), np.eye(2))
    xs, Ps, Pl, _ = rts_smoother(model.F, model.H, model.Q, model.R, y, np.zeros(2), np.eye(2))
    close(res.x_smooth, xs, "x_smooth")
    close(res.P_smooth, Ps, "P_smooth")
    assert np.isfinite(res.P_lag1).all()


def _statsmodels_smoother(case):
    F, H, Q, R = (case.model[k] for k in "FHQR")
    n, m = F.shape[-1], H.shape[-2]
    T = len(case.y)
    last = lambda A: np.moveaxis(A, 0, -1) if A.ndim == 3 else A  # noqa: E731
    ssm = KalmanSmoother(k_endog=m, k_states=n, k_posdef=n, tolerance=0)
    ssm.bind(np.ascontiguousarray(case.y))
    ssm["design"], ssm["obs_cov"], ssm["transition"], ssm["state_cov"] = last(H), last(R), last(F), last(Q)
    ssm["selection"] = np.eye(n)
    if case.u is not None:
        ssm["state_intercept"] = (case.u @ case.model["B"].T).T if case.model["B"].ndim == 2 else np.einsum(
            "tnk,tk->nt", case.model["B"], case.u
        )
        ssm["obs_intercept"] = (case.u @ case.model["D"].T).T if case.model["D"].ndim == 2 else np.einsum(
            "tmk,tk->mt", case.model["D"], case.u
        )
    ssm.initialize_known(case.x0, case.P0)
    out = ssm.smooth()
    assert not out.converged and out.smoothed_state.shape == (n, T)
    return out


@pytest.mark.parametrize("seed", [s for s in range(48) if not OPTIONS[s % len(OPTIONS)][1]])
def test_rts_matches_statsmodels(seed):
    """statsmodels: smoothed_state, smoothed_state_cov, and smoothed_state_autocov[..., t] =
    Cov(x[t+1], x[t]) = our P_lag1[t+1]. (statsmodels has no N, so N = 0 cases only.)"""
    case = case_for(seed)
    res = smooth(case)
    out = _statsmodels_smoother(case)
    close(res.x_smooth, out.smoothed_state.T, "x_smooth", rtol=1e-8)
    close(res.P_smooth, np.moveaxis(out.smoothed_state_cov, -1, 0), "P_smooth", rtol=1e-8)
    close(res.P_lag1[1:], np.moveaxis(out.smoothed_state_autocov, -1, 0)[:-1], "P_lag1", rtol=1e-8)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("missing", ["none", "rows"])
def test_rts_matches_pykalman(seed, missing):
    """pykalman's smooth(): same prior convention; masked rows are missing observations."""
    case = random_case(300 + seed, n=1 + seed % 4, m=1 + seed % 3, T=30, missing=missing)
    F, H, Q, R = (case.model[k] for k in "FHQR")
    pk = PKKalmanFilter(
        transition_matrices=F, observation_matrices=H, transition_covariance=Q, observation_covariance=R,
        initial_state_mean=case.x0, initial_state_covariance=case.P0,
    )
    means, covs = pk.smooth(np.ma.masked_invalid(case.y))
    res = smooth(case)
    close(res.x_smooth, means, "x_smooth", rtol=1e-8)
    close(res.P_smooth, covs, "P_smooth", rtol=1e-8)


@pytest.mark.parametrize("seed", range(48))
@pytest.mark.parametrize("lag", [0, 1, 4])
def test_fixed_lag_matches_the_augmented_filter(seed, lag):
    case = case_for(seed, T=15)
    model = kfast.LinearGaussian(**case.model)
    res = model.smooth_fixed_lag(case.y, case.x0, case.P0, lag, u=case.u)
    xa, Pa = fixed_lag_augmented(**case.model, y=case.y, x0=case.x0, P0=case.P0, lag=lag, u=case.u)
    close(res.x_smooth, xa, f"x lag {lag} {case.info}")
    close(res.P_smooth, Pa, f"P lag {lag} {case.info}")
    assert res.lag == lag


@pytest.mark.parametrize("seed", range(24))
def test_fixed_lag_ends_and_limits(seed):
    """lag = 0 is the filter; lag >= T-1 is RTS everywhere; the last lag+1 rows use all data."""
    case = case_for(seed, T=12)
    model = kfast.LinearGaussian(**case.model)
    rts = smooth(case)
    lag0 = model.smooth_fixed_lag(case.y, case.x0, case.P0, 0, u=case.u)
    close(lag0.x_smooth, rts.filter.x_filt, "lag 0 = filter")
    for lag in (11, 30):
        full = model.smooth_fixed_lag(case.y, case.x0, case.P0, lag, u=case.u)
        close(full.x_smooth, rts.x_smooth, "lag >= T-1 = RTS")
        close(full.P_smooth, rts.P_smooth, "lag >= T-1 = RTS")
    lag3 = model.smooth_fixed_lag(case.y, case.x0, case.P0, 3, u=case.u)
    close(lag3.x_smooth[-4:], rts.x_smooth[-4:], "end of data = RTS")


@pytest.mark.parametrize("seed", range(24))
def test_fixed_point_equals_rts_on_growing_data(seed):
    """Row j of the fixed-point result is the RTS estimate of x[s] from y(0..s+j)."""
    case = case_for(seed, T=12)
    model = kfast.LinearGaussian(**case.model)
    s = seed % 12
    res = model.smooth_fixed_point(case.y, case.x0, case.P0, s, u=case.u)
    assert res.x.shape == (12 - s, model.n_states)
    for j in range(12 - s):
        t = s + j
        u = None if case.u is None else case.u[: t + 1]
        sub = {k: (v[: t + 1] if v.ndim == 3 else v) for k, v in case.model.items()}
        part = kfast.LinearGaussian(**sub).smooth(case.y[: t + 1], case.x0, case.P0, u=u)
        close(res.x[j], part.x_smooth[s], f"x({s}|{t})")
        close(res.P[j], part.P_smooth[s], f"P({s}|{t})")


@pytest.mark.parametrize("seed", range(48))
def test_fixed_point_matches_the_augmented_filter(seed):
    """Söderström (6.45): the filter on [x(t); x(s)] with x(s) held constant."""
    case = case_for(seed, T=12)
    s = (3 * seed) % 12
    res = kfast.LinearGaussian(**case.model).smooth_fixed_point(case.y, case.x0, case.P0, s, u=case.u)
    xa, Pa = fixed_point_augmented(**case.model, y=case.y, x0=case.x0, P0=case.P0, t_point=s, u=case.u)
    close(res.x, xa, f"x s={s} {case.info}")
    close(res.P, Pa, f"P s={s} {case.info}")


def test_smoother_arguments_are_checked():
    case = case_for(3, T=8)
    model = kfast.LinearGaussian(**case.model)
    with pytest.raises(kfast.KfastError, match="^lag: must be >= 0, got -1"):
        model.smooth_fixed_lag(case.y, case.x0, case.P0, -1, u=case.u)
    with pytest.raises(kfast.KfastError, match="^lag: expected an integer"):
        model.smooth_fixed_lag(case.y, case.x0, case.P0, 1.5, u=case.u)
    with pytest.raises(kfast.KfastError, match=r"^t_point: must be a step of the data, 0 ≤ t_point < T = 8, got 8"):
        model.smooth_fixed_point(case.y, case.x0, case.P0, 8, u=case.u)
    with pytest.raises(kfast.KfastError, match="^t_point: must be >= 0, got -2"):
        model.smooth_fixed_point(case.y, case.x0, case.P0, -2, u=case.u)
    with pytest.raises(kfast.KfastError, match="^lag: must be >= 0, got -3"):
        kfast.FixedLagSmoother(model, case.x0, case.P0, -3)


@pytest.mark.parametrize("seed", range(16))
def test_online_fixed_lag_equals_batch(seed):
    case = case_for(seed, T=14)
    model = kfast.LinearGaussian(**case.model)
    lag = 1 + seed % 4
    batch = model.smooth_fixed_lag(case.y, case.x0, case.P0, lag, u=case.u)
    filt = model.filter(case.y, case.x0, case.P0, u=case.u)
    online = kfast.FixedLagSmoother(model, case.x0, case.P0, lag)
    for t in range(len(case.y)):
        u = None if case.u is None else case.u[t]
        online.update(case.y[t], u)
        if t < lag:
            assert online.x_lagged is None and online.P_lagged is None
        else:
            close(online.x_lagged, batch.x_smooth[t - lag], "x_lagged")
            close(online.P_lagged, batch.P_smooth[t - lag], "P_lagged")
        assert online.x_window.shape == (min(t, lag) + 1, model.n_states)
        close(online.x_window[0], filt.x_filt[t], "window[0] is x(t|t)")
        online.predict(u)
    # At the end the window is gone (after predict) and the step counter is T.
    assert online.x_window.shape == (0, model.n_states)
    assert online.t == len(case.y)


def test_case_c_random_walk_fixed_lag_and_rts_variances():
    """Söderström ch. 8 (case C): random walk in noise, Q = 1, R = beta (beta + 1). Started at
    the stationary P_pred = 1 + beta, the lag-m smoother variance is V_m, the filter's is V_0 = beta,
    prediction m < 0 gives V_m = beta - m, and mid-series RTS reaches V_inf = beta(beta+1)/(2 beta+1)."""
    c = CASES["C"]
    for beta_key, table in c["V"].items():
        beta = float(beta_key)
        model = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=beta * (beta + 1))
        y = np.zeros(600)  # variances do not depend on the data
        for m_str, v in table.items():
            m = int(m_str)
            if m <= 0:
                # m = 0: filter variance; m < 0: (1-m)-step prediction from x(t|t).
                P = model.filter(y[:5], 0.0, 1 + beta).P_filt[-1, 0, 0] + (-m)
            else:
                P = model.smooth_fixed_lag(y, 0.0, 1 + beta, m).P_smooth[50, 0, 0]
            assert P == pytest.approx(v, rel=c["rtol"]), (beta, m)
        mid = model.smooth(y, 0.0, 1 + beta).P_smooth[300, 0, 0]
        assert mid == pytest.approx(beta * (beta + 1) / (2 * beta + 1), rel=1e-9)
        # The closed form of V_m for m >= 0 agrees with the table too.
        for m_str, v in table.items():
            m = int(m_str)
            if m >= 0:
                closed = beta * (1 + beta) / (1 + 2 * beta) + (1 + beta) ** 2 / (1 + 2 * beta) * (beta / (1 + beta)) ** (
                    2 * m + 2
                )
                assert closed == pytest.approx(v, rel=c["rtol"])
