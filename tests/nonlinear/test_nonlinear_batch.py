"""kfast.ekf_batch and kfast.ukf_batch: many series through one nonlinear model. Each series'
results are those of filtering it alone, bit for bit, whatever the threads; errors name the
series; and Söderström's Table 9.1 (10,000 Monte-Carlo trials) runs as one batch through Rust."""

import json
from pathlib import Path

import numpy as np
import pytest
from tracking import DT, ct, ct_problem, range_bearing

import kfast

CASES = json.loads((Path(__file__).parent.parent / "data" / "textbook_cases.json").read_text())


def tracks(B=6, T=30):
    """B range-bearing series of the coordinated-turn target (each its own simulation), some
    values missing, and one prior per series."""
    Q, R, _, x0, P0 = ct_problem(T=T)
    Y = np.stack([ct_problem(T=T, seed=100 + b)[2] for b in range(B)])
    Y[1, 5, 0] = np.nan
    Y[2, 7:9, :] = np.nan
    rng = np.random.default_rng(5)
    X0 = x0 + rng.normal(0.0, 1.0, (B, 5)) * [3, 3, 0.5, 0.5, 0.01]
    P0s = np.stack([P0 * s for s in rng.uniform(0.5, 2.0, B)])
    return Q, R, Y, X0, P0s


def builtin_model(Q, R):
    return kfast.NonlinearModel(
        kfast.models.coordinated_turn(DT, q=1.0, sigma_omega=0.05), kfast.models.range_bearing((0.0, 0.0)), Q, R, n=5
    )


RUNS = {
    "ekf": (lambda m, y, x0, P0, **kw: m.ekf(y, x0, P0, **kw), kfast.ekf_batch, {}),
    "iterated ekf": (
        lambda m, y, x0, P0, **kw: m.ekf(y, x0, P0, **kw),
        kfast.ekf_batch,
        dict(iterations=2, iteration="gauss-newton", form="standard"),
    ),
    "ukf": (
        lambda m, y, x0, P0, **kw: m.ukf(y, x0, P0, **kw),
        kfast.ukf_batch,
        dict(points=kfast.sigma.merwe(alpha=0.5)),
    ),
    "ckf": (lambda m, y, x0, P0, **kw: m.ukf(y, x0, P0, **kw), kfast.ukf_batch, dict(points=kfast.sigma.cubature())),
}


@pytest.mark.parametrize("run", list(RUNS))
@pytest.mark.parametrize("threads", [1, 2, None])
def test_each_series_is_filtered_as_alone_bit_for_bit(run, threads):
    Q, R, Y, X0, P0s = tracks()
    model = builtin_model(Q, R)
    single, batch, kw = RUNS[run]
    res = batch(model, Y, X0, P0s, threads=threads, **kw)
    assert res.x_filt.shape == (6, 30, 5) and res.P_filt.shape == (6, 30, 5, 5) and res.loglik.shape == (6,)
    assert not res.shared_covariance
    for b in range(len(Y)):
        one = single(model, Y[b], X0[b], P0s[b], **kw)
        np.testing.assert_array_equal(res.x_filt[b], one.x_filt)
        np.testing.assert_array_equal(res.P_filt[b], one.P_filt)
        assert res.loglik[b] == one.loglik


def test_shared_prior_without_covariances_and_a_python_model():
    """A shared prior broadcasts; return_covs=False returns no P; a model with Python callables
    (which run one series after another: they hold the GIL) gives the same as alone."""
    Q, R, Y, X0, _ = tracks(B=3, T=15)
    P0 = np.diag([100.0, 100.0, 4.0, 4.0, 0.01])
    python = kfast.NonlinearModel(ct, range_bearing, Q, R, n=5, angles=[1])
    for model in (builtin_model(Q, R), python):
        res = kfast.ukf_batch(model, Y, X0[0], P0, return_covs=False, points=kfast.sigma.merwe(alpha=0.5))
        assert res.P_filt is None
        for b in range(3):
            one = model.ukf(Y[b], X0[0], P0, points=kfast.sigma.merwe(alpha=0.5))
            np.testing.assert_array_equal(res.x_filt[b], one.x_filt)
            assert res.loglik[b] == one.loglik


@pytest.mark.parametrize("shared", [True, False])
def test_inputs_shared_or_per_series_reach_f_and_h(shared):
    rng = np.random.default_rng(3)
    F = np.array([[1.0, 0.1], [0.0, 0.9]])

    def f(X, t, u):
        return X @ F.T + u

    def h(X, t, u):
        return np.sin(X[:, :1]) + 0.1 * u[:1]

    model = kfast.NonlinearModel(f, h, 0.01 * np.eye(2), [[0.1]], n=2)
    B, T = 4, 12
    Y = rng.normal(size=(B, T, 1))
    U = rng.normal(size=(T, 2)) if shared else rng.normal(size=(B, T, 2))
    res = kfast.ekf_batch(model, Y, [0.0, 0.0], np.eye(2), u=U)
    for b in range(B):
        one = model.ekf(Y[b], [0.0, 0.0], np.eye(2), u=U if shared else U[b])
        np.testing.assert_array_equal(res.x_filt[b], one.x_filt)
        assert res.loglik[b] == one.loglik
    # the inputs matter: without them the states differ
    zero = kfast.ekf_batch(model, Y, [0.0, 0.0], np.eye(2), u=np.zeros_like(U))
    assert np.abs(zero.x_filt - res.x_filt).max() > 1e-3


def test_g1_table_9_1_through_rust_in_one_batch():
    """Söderström section 9.2.4, Table 9.1 (a = 1, 10,000 trials): each trial is a series of
    two steps (y(0) observed, y(1) missing, so x(1|1) = x(1|0) = z) in one ekf_batch call, by
    the EKF and the second-order EKF (Hessian given); the MSEs of x(0|0) and z within
    Monte-Carlo error (four standard errors, or half a unit of the last printed digit)."""
    c = CASES["G1"]
    a, N, table = c["a"], c["trials"], c["table_9_1"]
    rng = np.random.default_rng(20021)
    for j, b in enumerate(c["b"]):
        x = rng.uniform(-a, a, N)
        Y = np.stack([x + rng.uniform(-b, b, N), np.full(N, np.nan)], axis=1)[:, :, None]
        model = kfast.NonlinearModel(
            lambda X, t, u: X**2,
            lambda X, t, u: X,
            [[0.0]],
            [[b**2 / 3]],
            n=1,
            hess_f=lambda X, t, u: np.full((len(X), 1, 1, 1), 2.0),
        )
        first = kfast.ekf_batch(model, Y, [0.0], [[a**2 / 3]], return_covs=False)
        second = kfast.ekf_batch(model, Y, [0.0], [[a**2 / 3]], order=2, return_covs=False)
        rows = {
            "EKF MSE(x)": (first.x_filt[:, 0, 0] - x) ** 2,
            "EKF MSE(z)": (first.x_filt[:, 1, 0] - x**2) ** 2,
            "second-order EKF MSE(z)": (second.x_filt[:, 1, 0] - x**2) ** 2,
        }
        for name, sq in rows.items():
            printed = table[name][j]
            digits = len(str(printed).split(".")[1])
            allowed = max(4 * sq.std() / np.sqrt(N), 0.5 * 10.0**-digits)
            assert abs(sq.mean() - printed) <= allowed, (name, b, sq.mean(), printed)


def test_errors_name_the_argument_and_the_series():
    Q, R, Y, X0, P0s = tracks(B=3, T=10)
    model = builtin_model(Q, R)
    with pytest.raises(kfast.KfastError, match=r"Y: expected a 3-D array"):
        kfast.ekf_batch(model, Y[0], X0[0], P0s[0])
    with pytest.raises(kfast.KfastError, match=r"Y: expected shape \(B, T, 2\)"):
        kfast.ekf_batch(model, Y[:, :, :1], X0[0], P0s[0])
    with pytest.raises(kfast.KfastError, match=r"x0: expected shape \(5,\) .*\(3, 5\)"):
        kfast.ekf_batch(model, Y, X0[:2], P0s[0])
    with pytest.raises(kfast.KfastError, match=r"u: expected shape \(10, k\)"):
        kfast.ukf_batch(model, Y, X0[0], P0s[0], u=np.zeros((3, 9, 1)))
    with pytest.raises(kfast.KfastError, match=r"threads: must be >= 1"):
        kfast.ukf_batch(model, Y, X0[0], P0s[0], threads=0)
    with pytest.raises(kfast.KfastError, match=r"model: expected a kfast.NonlinearModel"):
        kfast.ekf_batch(kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=1.0), Y, X0[0], P0s[0])
    bad = Y.copy()
    bad[2, 4, 1] = np.inf
    with pytest.raises(kfast.KfastError, match=r"Y.*series 2"):
        kfast.ekf_batch(model, bad, X0[0], P0s[0])
    P_bad = P0s.copy()
    P_bad[1, 0, 0] = -1.0
    with pytest.raises(kfast.KfastError, match=r"P0.*series 1"):
        kfast.ukf_batch(model, Y, X0, P_bad)


def test_a_failure_during_the_run_names_the_lowest_failing_series_and_the_step():
    """Series 3 and 5 start with the target on the radar (the range-bearing Jacobian is undefined
    there): the EKF fails at their step 0; the error names series 3 whatever the threads."""
    Q, R, Y, X0, P0s = tracks(B=6, T=10)
    X0[[3, 5], :2] = 0.0
    for threads in (1, 2):
        with pytest.raises(kfast.KfastError, match=r"h at step 0: \(series 3\) the range-bearing Jacobian is undefined"):
            kfast.ekf_batch(builtin_model(Q, R), Y, X0, P0s, threads=threads)


def test_the_inputs_are_not_modified():
    Q, R, Y, X0, P0s = tracks(B=3, T=10)
    copies = [a.copy() for a in (Y, X0, P0s)]
    kfast.ukf_batch(builtin_model(Q, R), Y, X0, P0s)
    for a, c in zip((Y, X0, P0s), copies):
        np.testing.assert_array_equal(a, c)
