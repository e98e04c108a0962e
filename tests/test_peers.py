"""Cross-checks of kfast against established Kalman filter libraries.

Peers (all in the ``test`` extras; a missing peer is a test *failure*, not a skip):

* filterpy 2.x   ``filterpy.kalman.KalmanFilter`` (predict/update loop and ``batch_filter``)
* pykalman 0.11  ``pykalman.KalmanFilter`` plus its square-root variants
                 ``pykalman.sqrt.CholeskyKalmanFilter`` / ``BiermanKalmanFilter``
* statsmodels    ``statsmodels.tsa.statespace.kalman_filter.KalmanFilter`` (the
                 low-level state-space filter behind every ``MLEModel``)

Every case is a seeded random linear Gaussian model (``np.random.default_rng``):
(n, m) running over 1..5 states x 1..3 observations (see DIMS), F scaled to spectral radius 0.9,
Q = A A' + 0.1 I, R likewise, T = 50 steps simulated from the model.  The peers
use different algorithms (Joseph form, P - K H P with pinv, Cholesky, UDU',
Cholesky solves), so agreement is required to rtol 1e-8 rather than bitwise.

The convention mapping verified here is documented in docs/peers.md.
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np
import pytest

import filterpy
import pykalman
import statsmodels
from filterpy.kalman import KalmanFilter as FPKalmanFilter
from pykalman import KalmanFilter as PKKalmanFilter
from pykalman.sqrt import BiermanKalmanFilter, CholeskyKalmanFilter
from pykalman.standard import _filter as pk_filter_internal
from statsmodels.tsa.statespace import kalman_filter as sm_kf

import kfast

RTOL = 1e-8
ATOL = 1e-9
T_DEFAULT = 50
SEEDS = list(range(8))
# (n, m) used by seed s (when not forced): covers n = 1..5 and m = 1..3.
DIMS = [(1, 1), (2, 2), (3, 3), (4, 1), (5, 2), (1, 3), (2, 1), (3, 2)]


def close(actual, desired, what):
    np.testing.assert_allclose(
        np.asarray(actual, dtype=float),
        np.asarray(desired, dtype=float),
        rtol=RTOL,
        atol=ATOL,
        err_msg=what,
    )


# --------------------------------------------------------------------------
# Shared random cases
# --------------------------------------------------------------------------


@dataclass
class Case:
    F: np.ndarray  # (n, n) or (T, n, n)
    H: np.ndarray  # (m, n) or (T, m, n)
    Q: np.ndarray
    R: np.ndarray
    x0: np.ndarray  # prior mean x(0|-1)
    P0: np.ndarray  # prior cov  P(0|-1)
    y: np.ndarray  # (T, m), NaN = missing
    B: Optional[np.ndarray] = None
    D: Optional[np.ndarray] = None
    N: Optional[np.ndarray] = None
    u: Optional[np.ndarray] = None  # (T, k)

    @property
    def T(self):
        return self.y.shape[0]

    @property
    def n(self):
        return self.x0.shape[0]

    @property
    def m(self):
        return self.y.shape[1]

    def at(self, name, t):
        """Matrix `name` at step t (handles constant and per-step matrices)."""
        A = getattr(self, name)
        if A is None:
            return None
        return A[t] if A.ndim == 3 else A

    def model(self):
        return kfast.LinearGaussian(
            self.F, self.H, self.Q, self.R, B=self.B, D=self.D, N=self.N
        )

    def run(self, form="joseph"):
        return self.model().filter(self.y, self.x0, self.P0, u=self.u, form=form)


def _spd(rng, d, jitter=0.1):
    A = rng.standard_normal((d, d))
    return A @ A.T / d + jitter * np.eye(d)


def _stable(rng, n, rho=0.9):
    F = rng.standard_normal((n, n))
    return F * (rho / np.max(np.abs(np.linalg.eigvals(F))))


def make_case(
    seed,
    n=None,
    m=None,
    k=0,
    T=T_DEFAULT,
    time_varying=False,
    with_D=False,
    correlated=False,
    missing=None,
):
    """Seeded random model plus data simulated from it.

    missing: None, "rows" (some whole y[t] rows NaN) or "partial" (single
    components NaN plus a few whole rows).
    """
    rng = np.random.default_rng(seed)
    n = DIMS[seed % len(DIMS)][0] if n is None else n
    m = DIMS[seed % len(DIMS)][1] if m is None else m

    if time_varying:
        F = np.stack([_stable(rng, n) for _ in range(T)])
        H = rng.standard_normal((T, m, n))
        Q = np.stack([_spd(rng, n) for _ in range(T)])
        R = np.stack([_spd(rng, m) for _ in range(T)])
    else:
        F = _stable(rng, n)
        H = rng.standard_normal((m, n))
        Q = _spd(rng, n)
        R = _spd(rng, m)

    N = None
    if correlated:
        # Joint covariance of (w, v) = L L' + jitter: Q, R, N consistent and
        # Q - N R^-1 N' positive definite.
        L = rng.standard_normal((n + m, n + m)) / np.sqrt(n + m)
        J = L @ L.T + 0.1 * np.eye(n + m)
        Q, N, R = J[:n, :n], J[:n, n:], J[n:, n:]

    B = D = u = None
    if k:
        B = rng.standard_normal((n, k))
        u = rng.standard_normal((T, k))
        if with_D:
            D = rng.standard_normal((m, k))

    x0 = rng.standard_normal(n)
    P0 = _spd(rng, n, jitter=0.5)

    case = Case(F=F, H=H, Q=Q, R=R, x0=x0, P0=P0, y=np.zeros((T, m)), B=B, D=D, N=N, u=u)

    # simulate
    x = rng.multivariate_normal(x0, P0)
    y = np.empty((T, m))
    for t in range(T):
        Qt, Rt = case.at("Q", t), case.at("R", t)
        if N is not None:
            wv = rng.multivariate_normal(np.zeros(n + m), np.block([[Qt, N], [N.T, Rt]]))
            w, v = wv[:n], wv[n:]
        else:
            w = rng.multivariate_normal(np.zeros(n), Qt)
            v = rng.multivariate_normal(np.zeros(m), Rt)
        y[t] = case.at("H", t) @ x + v
        if D is not None:
            y[t] += D @ u[t]
        x = case.at("F", t) @ x + w
        if B is not None:
            x += B @ u[t]

    if missing is not None:
        rows = rng.choice(np.arange(1, T), size=4, replace=False)
        y[rows] = np.nan
        # even seeds also lose y[0] (missing first step right after the prior)
        if seed % 2 == 0:
            y[0] = np.nan
        if missing == "partial":
            mask = rng.random((T, m)) < 0.2
            y[mask] = np.nan
            if m > 1:
                # guarantee at least one genuinely partial row
                y[3] = case.at("H", 3) @ x0
                y[3, 0] = np.nan
    case.y = y
    return case


def check_kfast_shapes(res, case):
    T, n, m = case.T, case.n, case.m
    assert res.x_pred.shape == (T, n)
    assert res.P_pred.shape == (T, n, n)
    assert res.x_filt.shape == (T, n)
    assert res.P_filt.shape == (T, n, n)
    assert res.innov.shape == (T, m)
    assert res.S.shape == (T, m, m)
    assert res.K.shape == (T, n, m)
    assert res.K_pred.shape == (T, n, m)
    assert res.loglik_t.shape == (T,)
    assert res.x_next.shape == (n,)
    assert res.P_next.shape == (n, n)


def test_peer_versions():
    # The conventions checked below were read from these releases' source.
    assert filterpy.__version__.split(".")[0] in {"1", "2"}
    assert pykalman.__version__.startswith("0.")
    assert tuple(int(p) for p in statsmodels.__version__.split(".")[:2]) >= (0, 14)


# --------------------------------------------------------------------------
# filterpy
# --------------------------------------------------------------------------
#
# filterpy's KalmanFilter holds (x, P); before the first update they are our
# prior x(0|-1), P(0|-1), so a run is: update(y[0]); predict(); update(y[1]); ...
# Its update() is Joseph form; `K` is the filter gain P H' S^-1; `y` is the
# innovation; `log_likelihood` is the log-density of the *last* innovation
# (one step, not cumulative).  It has no feed-through D (we pass y - D u) and
# no NaN handling: update(None) skips a step; a partially observed y[t] is
# fed as update(y_obs, H=H[obs], R=R[obs, obs]).


def _filterpy(case):
    kf = FPKalmanFilter(dim_x=case.n, dim_z=case.m, dim_u=0 if case.u is None else case.u.shape[1])
    # 1-D state: keeps filterpy's z/u reshaping consistent for every n, m.
    kf.x = case.x0.copy()
    kf.P = case.P0.copy()
    kf.B = case.B
    if case.F.ndim == 2:  # constant matrices live on the filter object
        kf.F, kf.H, kf.Q, kf.R = case.F, case.H, case.Q, case.R
    return kf


def _filterpy_z(case, t):
    z = case.y[t].copy()
    if case.D is not None:
        z = z - case.D @ case.u[t]
    return z


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("variant", ["plain", "control", "missing"])
def test_filterpy_predict_update_loop(seed, variant):
    case = make_case(
        seed,
        k=2 if variant == "control" else 0,
        with_D=variant == "control",
        missing="partial" if variant == "missing" else None,
    )
    res = case.run()
    check_kfast_shapes(res, case)

    kf = _filterpy(case)
    loglik = 0.0
    for t in range(case.T):
        H, R = case.at("H", t), case.at("R", t)
        close(res.x_pred[t], kf.x, f"x_pred[{t}]")
        close(res.P_pred[t], kf.P, f"P_pred[{t}]")
        z = _filterpy_z(case, t)
        obs = ~np.isnan(z)
        if not obs.any():
            kf.update(None)
            close(res.loglik_t[t], 0.0, f"loglik_t[{t}] fully missing")
            assert np.all(np.isnan(res.innov[t]))
            close(res.K[t], np.zeros((case.n, case.m)), f"K[{t}] fully missing")
        elif obs.all():
            kf.update(z, H=H, R=R)
            close(res.innov[t], kf.y, f"innov[{t}]")
            close(res.S[t], kf.S, f"S[{t}]")
            close(res.K[t], kf.K, f"K[{t}]")
            close(res.loglik_t[t], kf.log_likelihood, f"loglik_t[{t}]")
            loglik += kf.log_likelihood
        else:
            idx = np.ix_(obs, obs)
            kf.update(z[obs], H=H[obs], R=R[idx])
            close(res.innov[t, obs], kf.y, f"innov[{t}] observed part")
            assert np.all(np.isnan(res.innov[t, ~obs]))
            close(res.S[t][idx], kf.S, f"S[{t}] observed block")
            close(res.K[t][:, obs], kf.K, f"K[{t}] observed columns")
            close(res.K[t][:, ~obs], 0.0, f"K[{t}] missing columns")
            close(res.loglik_t[t], kf.log_likelihood, f"loglik_t[{t}]")
            loglik += kf.log_likelihood
        close(res.x_filt[t], kf.x, f"x_filt[{t}]")
        close(res.P_filt[t], kf.P, f"P_filt[{t}]")
        kf.predict(u=None if case.u is None else case.u[t], F=case.at("F", t), Q=case.at("Q", t))
    close(res.x_next, kf.x, "x_next")
    close(res.P_next, kf.P, "P_next")
    close(res.loglik, loglik, "loglik = sum of filterpy per-step log_likelihood")
    close(case.model().loglik(case.y, case.x0, case.P0, u=case.u), loglik, "m.loglik()")


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("time_varying", [False, True])
def test_filterpy_batch_filter(seed, time_varying):
    case = make_case(seed, k=1, time_varying=time_varying, missing="rows")
    res = case.run()

    kf = _filterpy(case)
    T = case.T
    zs = [None if np.isnan(case.y[t]).all() else case.y[t] for t in range(T)]
    kw = {}
    if time_varying:
        kw = dict(
            Fs=list(case.F), Qs=list(case.Q), Hs=list(case.H), Rs=list(case.R)
        )
    means, covs, means_p, covs_p = kf.batch_filter(
        zs, Bs=[case.B] * T, us=list(case.u), update_first=True, **kw
    )
    # update_first=True: means/covs = x(t|t); means_p/covs_p = x(t+1|t).
    close(res.x_filt, means, "x_filt")
    close(res.P_filt, covs, "P_filt")
    close(res.x_pred[1:], means_p[:-1], "x_pred[1:]")
    close(res.P_pred[1:], covs_p[:-1], "P_pred[1:]")
    close(res.x_next, means_p[-1], "x_next")
    close(res.P_next, covs_p[-1], "P_next")


@pytest.mark.parametrize("seed", SEEDS[:4])
def test_filterpy_streaming(seed):
    """kfast.KalmanFilter.update/predict/step vs filterpy update/predict."""
    case = make_case(seed, k=2)
    kf = _filterpy(case)
    ours = kfast.KalmanFilter(case.model(), case.x0, case.P0)
    ours2 = kfast.KalmanFilter(case.model(), case.x0, case.P0)
    for t in range(case.T):
        kf.update(case.y[t])
        ours.update(case.y[t], u=case.u[t])
        close(ours.x, kf.x, f"streaming x(t|t) t={t}")
        close(ours.P, kf.P, f"streaming P(t|t) t={t}")
        kf.predict(u=case.u[t])
        ours.predict(u=case.u[t])
        close(ours.x, kf.x, f"streaming x(t+1|t) t={t}")
        close(ours.P, kf.P, f"streaming P(t+1|t) t={t}")
        ours2.step(case.y[t], u=case.u[t])
        close(ours2.x, kf.x, f"step() x t={t}")
        close(ours2.P, kf.P, f"step() P t={t}")


# --------------------------------------------------------------------------
# pykalman
# --------------------------------------------------------------------------
#
# pykalman's initial_state_mean/covariance is the distribution of x[0] before
# any observation, and its first operation is the correction with y[0]:
# exactly our prior x(0|-1), P(0|-1).  transition_matrices[t-1] /
# transition_offsets[t-1] take x[t-1] to x[t] (so pass F[:T-1], (B u)[:T-1]);
# observation_offsets[t] = D u[t].  Missing data are masked arrays, and a row
# with ANY masked component is skipped entirely.

PK_CLASSES = [PKKalmanFilter, CholeskyKalmanFilter, BiermanKalmanFilter]


def _pykalman(case, cls=PKKalmanFilter):
    T = case.T
    kw = {}
    if case.B is not None:
        kw["transition_offsets"] = (case.u @ case.B.T)[: T - 1]
    if case.D is not None:
        kw["observation_offsets"] = case.u @ case.D.T
    F = case.F[: T - 1] if case.F.ndim == 3 else case.F
    return cls(
        transition_matrices=F,
        observation_matrices=case.H,
        transition_covariance=case.Q,
        observation_covariance=case.R,
        initial_state_mean=case.x0,
        initial_state_covariance=case.P0,
        **kw,
    )


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("cls", PK_CLASSES, ids=lambda c: c.__name__)
def test_pykalman_filter_and_loglik(seed, cls):
    case = make_case(seed)
    res = case.run()
    pk = _pykalman(case, cls)
    xf, Pf = pk.filter(case.y)
    close(res.x_filt, xf, "x_filt")
    close(res.P_filt, Pf, "P_filt")
    close(res.loglik, pk.loglikelihood(case.y), "loglik")


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("form", ["joseph", "standard"])
def test_pykalman_predicted_and_gain(seed, form):
    # pykalman exposes predicted moments and gains only through its internal
    # _filter (same function .filter()/.loglikelihood() call).  pykalman's own
    # covariance update is the "standard" P - K H P.
    case = make_case(seed, missing="rows")
    res = case.run(form)
    x_pred, P_pred, K, x_filt, P_filt = pk_filter_internal(
        case.F, case.H, case.Q, case.R,
        np.zeros(case.n), np.zeros(case.m),
        case.x0, case.P0, np.ma.masked_invalid(case.y),
    )
    close(res.x_pred, x_pred, "x_pred")
    close(res.P_pred, P_pred, "P_pred")
    close(res.K, K, "K (filter gain, zero for skipped rows)")
    close(res.x_filt, x_filt, "x_filt")
    close(res.P_filt, P_filt, "P_filt")


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("constant_u", [True, False])
def test_pykalman_offsets(seed, constant_u):
    """transition_offsets / observation_offsets  <->  B u / D u."""
    case = make_case(seed, k=2, with_D=True)
    if constant_u:
        case.u = np.tile(case.u[0], (case.T, 1))
    res = case.run()
    if constant_u:
        pk = PKKalmanFilter(
            transition_matrices=case.F,
            observation_matrices=case.H,
            transition_covariance=case.Q,
            observation_covariance=case.R,
            transition_offsets=case.B @ case.u[0],
            observation_offsets=case.D @ case.u[0],
            initial_state_mean=case.x0,
            initial_state_covariance=case.P0,
        )
    else:
        pk = _pykalman(case)
    xf, Pf = pk.filter(case.y)
    close(res.x_filt, xf, "x_filt")
    close(res.P_filt, Pf, "P_filt")
    close(res.loglik, pk.loglikelihood(case.y), "loglik")


@pytest.mark.parametrize("seed", SEEDS)
def test_pykalman_missing(seed):
    case = make_case(seed, missing="partial")
    # pykalman drops a row with any masked entry: the kfast equivalent is a
    # fully-NaN row, so blank every row that has a NaN.
    y_rows = case.y.copy()
    y_rows[np.isnan(y_rows).any(axis=1)] = np.nan
    res = case.model().filter(y_rows, case.x0, case.P0)
    for cls in PK_CLASSES:
        pk = _pykalman(case, cls)
        ym = np.ma.masked_invalid(case.y)
        xf, Pf = pk.filter(ym)
        close(res.x_filt, xf, f"{cls.__name__} x_filt")
        close(res.P_filt, Pf, f"{cls.__name__} P_filt")
        close(res.loglik, pk.loglikelihood(ym), f"{cls.__name__} loglik")


@pytest.mark.parametrize("seed", SEEDS)
def test_pykalman_time_varying(seed):
    # pykalman allows per-step F, H and offsets (Q, R constant).
    case = make_case(seed, k=1, time_varying=True)
    case.Q = case.Q[0]
    case.R = case.R[0]
    res = case.run()
    pk = _pykalman(case)
    xf, Pf = pk.filter(case.y)
    close(res.x_filt, xf, "x_filt")
    close(res.P_filt, Pf, "P_filt")
    close(res.loglik, pk.loglikelihood(case.y), "loglik")


@pytest.mark.parametrize("seed", SEEDS[:4])
def test_pykalman_filter_update_streaming(seed):
    """pykalman.filter_update (predict then correct) vs kfast.KalmanFilter."""
    case = make_case(seed, missing="rows")
    case.y[0] = case.H @ case.x0  # start with an observed step
    pk = _pykalman(case)
    # (a single-row y would be transposed by pykalman's _parse_observations)
    xf, Pf = pk.filter(np.ma.masked_invalid(case.y))
    ours = kfast.KalmanFilter(case.model(), case.x0, case.P0)
    ours.update(case.y[0])
    close(ours.x, xf[0], "x(0|0)")
    close(ours.P, Pf[0], "P(0|0)")
    x, P = xf[0], Pf[0]
    for t in range(1, case.T):
        obs = None if np.isnan(case.y[t]).any() else case.y[t]
        x, P = pk.filter_update(x, P, observation=obs)
        ours.predict()
        if obs is not None:
            ours.update(case.y[t])
        close(ours.x, x, f"x({t}|{t})")
        close(ours.P, P, f"P({t}|{t})")


# --------------------------------------------------------------------------
# statsmodels
# --------------------------------------------------------------------------
#
# Durbin & Koopman form: y_t = d_t + Z_t a_t + e_t, a_{t+1} = c_t + T_t a_t + R_t h_t.
# design=H, obs_cov=R, transition=F, selection=I, state_cov=Q, obs_intercept = D u,
# state_intercept = B u; time-varying matrices carry time on the LAST axis.
# initialize_known(x0, P0) is a_0 ~ N(x0, P0) = our prior x(0|-1) (default
# "predicted" filter timing).  Outputs are (dim, ..., T) with predicted_state
# having T+1 columns (last = x(T|T-1)).  kalman_gain is the PREDICTOR gain
# T P Z' F^-1 = our K_pred.  Exact comparison needs conventional filtering and
# tolerance=0 (no steady-state switch).


def _tlast(A, T):
    """kfast per-step (T, ...) -> statsmodels (..., T); constant stays 2-D."""
    return np.moveaxis(A, 0, -1) if A.ndim == 3 else A


def _statsmodels(case, decorrelate=False):
    n, m, T = case.n, case.m, case.T
    ssm = sm_kf.KalmanFilter(k_endog=m, k_states=n, k_posdef=n, tolerance=0)
    ssm.bind(np.ascontiguousarray(case.y))
    ssm.set_filter_method(filter_method=sm_kf.FILTER_CONVENTIONAL)
    F, Q = case.F, case.Q
    c = np.zeros((n, T))
    d = np.zeros((m, T))
    if case.B is not None:
        c += (case.u @ case.B.T).T
    if case.D is not None:
        d += (case.u @ case.D.T).T
    if decorrelate:
        # E[w_t v_t'] = N has no statsmodels counterpart; substitute
        # w_t = N R^-1 v_t + w*_t with v_t = y_t - H x_t - D u_t:
        #   x_{t+1} = (F - N R^-1 H) x_t + N R^-1 (y_t - D u_t) + B u_t + w*_t,
        #   cov w* = Q - N R^-1 N'  (w* independent of v_t).
        assert F.ndim == 2 and case.H.ndim == 2 and case.R.ndim == 2
        G = case.N @ np.linalg.inv(case.R)
        F = F - G @ case.H
        Q = Q - G @ case.N.T
        c += G @ (case.y.T - d)
    ssm["design"] = _tlast(case.H, T)
    ssm["obs_cov"] = _tlast(case.R, T)
    ssm["transition"] = _tlast(F, T)
    ssm["selection"] = np.eye(n)
    ssm["state_cov"] = _tlast(Q, T)
    if case.B is not None or decorrelate:
        ssm["state_intercept"] = c
    if case.D is not None:
        ssm["obs_intercept"] = d
    ssm.initialize_known(case.x0, case.P0)
    return ssm


def _t0(A):
    """statsmodels (..., T) -> (T, ...)."""
    return np.moveaxis(A, -1, 0)


def _compare_statsmodels(res, out, case, gain=True):
    T = case.T
    assert out.filter_method & sm_kf.FILTER_CONVENTIONAL
    assert not out.filter_method & sm_kf.FILTER_UNIVARIATE
    assert not out.converged  # the steady-state shortcut never kicked in
    assert out.predicted_state.shape == (case.n, T + 1)
    close(res.x_pred, out.predicted_state[:, :T].T, "x_pred")
    close(res.x_next, out.predicted_state[:, T], "x_next")
    close(res.P_pred, _t0(out.predicted_state_cov)[:T], "P_pred")
    close(res.P_next, out.predicted_state_cov[:, :, T], "P_next")
    close(res.x_filt, out.filtered_state.T, "x_filt")
    close(res.P_filt, _t0(out.filtered_state_cov), "P_filt")
    close(res.S, _t0(out.forecasts_error_cov), "S (full, also for missing comps)")
    np.testing.assert_array_equal(np.isnan(res.innov), np.isnan(out.forecasts_error.T))
    close(res.innov, out.forecasts_error.T, "innov")  # NaN positions equal
    if gain:
        assert out.kalman_gain.shape == (case.n, case.m, T)
        close(res.K_pred, _t0(out.kalman_gain), "K_pred vs statsmodels kalman_gain")
    close(res.loglik_t, out.llf_obs, "loglik_t vs llf_obs")
    close(res.loglik, out.llf, "loglik vs llf")


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("missing", [None, "rows", "partial"])
@pytest.mark.parametrize("form", ["joseph", "standard"])
def test_statsmodels_constant(seed, missing, form):
    case = make_case(seed, missing=missing)
    res = case.run(form)
    check_kfast_shapes(res, case)
    out = _statsmodels(case).filter()
    _compare_statsmodels(res, out, case)
    close(case.model().loglik(case.y, case.x0, case.P0), out.llf, "m.loglik()")


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("missing", [None, "partial"])
def test_statsmodels_time_varying_with_inputs(seed, missing):
    case = make_case(seed, k=2, with_D=True, time_varying=True, missing=missing)
    res = case.run()
    check_kfast_shapes(res, case)
    out = _statsmodels(case).filter()
    _compare_statsmodels(res, out, case)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("inputs", [False, True])
def test_statsmodels_correlated_noise(seed, inputs):
    case = make_case(seed, correlated=True, k=2 if inputs else 0, with_D=inputs)
    res = case.run()
    out = _statsmodels(case, decorrelate=True).filter()
    # Same filtered/predicted moments, S and likelihood; the predictor gain of
    # the decorrelated model is K_pred - N R^-1 (the N R^-1 y_t part sits in
    # the state intercept).
    _compare_statsmodels(res, out, case, gain=False)
    G = case.N @ np.linalg.inv(case.R)
    close(res.K_pred, _t0(out.kalman_gain) + G, "K_pred = statsmodels gain + N R^-1")
    # and K_pred = (F P_pred H' + N) S^-1 by definition
    Kp = (case.F @ res.P_pred @ case.H.T + case.N) @ np.linalg.inv(res.S)
    close(res.K_pred, Kp, "K_pred definition")
