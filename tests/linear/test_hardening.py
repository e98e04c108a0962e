"""The reproducers of the hardening campaign (issue #10) for the linear family: sizes from user
integers, thread counts, masked arrays, the prior of ``simulate``, ``filter_batch`` shapes and
the argument named by each error. Each case that once crashed, panicked, hung or returned a
wrong answer is pinned here; the broad search is the fuzz campaign."""

from __future__ import annotations

import subprocess
import sys
import threading

import numpy as np
import pytest

import kfast


@pytest.fixture
def cv():
    return kfast.models.constant_velocity(2, dt=0.1)


z, I = np.zeros(4), np.eye(4)


# --- sizes and thread counts from user integers: an error naming the argument, not a crash ----


@pytest.mark.parametrize("steps", [10**10, 2**62, 2**63 - 1])
def test_forecast_refuses_steps_that_cannot_fit_in_memory(cv, steps):
    with pytest.raises(kfast.KfastError, match=r"^steps: is too large"):
        cv.forecast(z, I, steps)


def test_forecast_refuses_steps_beyond_64_bits(cv):
    with pytest.raises(kfast.KfastError, match=r"^steps: is too large"):
        cv.forecast(z, I, 2**63)
    with pytest.raises(kfast.KfastError, match=r"^steps: is too large"):
        cv.forecast(z, I, 2**100)


@pytest.mark.parametrize("lag", [10**10, 2**62])
def test_online_fixed_lag_smoother_takes_a_lag_beyond_the_data(cv, lag):
    # The window grows with the data; a lag longer than the stream is the RTS smoother so far.
    rng = np.random.default_rng(3)
    y = rng.standard_normal((12, 2))
    fl = kfast.FixedLagSmoother(cv, z, I, lag)
    for row in y:
        fl.step(row)
    fl.update(rng.standard_normal(2))
    assert fl.x_lagged is None and fl.x_window.shape == (13, 4)


def test_online_fixed_lag_window_equals_the_rts_smoother(cv):
    rng = np.random.default_rng(4)
    y = rng.standard_normal((9, 2))
    fl = kfast.FixedLagSmoother(cv, z, I, 2**62)
    for t, row in enumerate(y):
        fl.update(row)
        if t + 1 < len(y):
            fl.predict()
    sm = cv.smooth(y, z, I)
    np.testing.assert_allclose(fl.x_window[::-1], sm.x_smooth, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(fl.P_window[::-1], sm.P_smooth, rtol=1e-10, atol=1e-12)


def test_batch_fixed_lag_with_a_huge_lag_is_the_rts_smoother(cv):
    y = np.random.default_rng(5).standard_normal((15, 2))
    res = cv.smooth_fixed_lag(y, z, I, lag=2**62)
    np.testing.assert_allclose(res.x_smooth, cv.smooth(y, z, I).x_smooth, rtol=1e-10, atol=1e-12)


def test_simulate_refuses_T_that_cannot_fit_in_memory(cv):
    with pytest.raises(kfast.KfastError, match=r"^T: is too large"):
        cv.simulate(10**12, z, I, seed=0)


@pytest.mark.parametrize("threads", [2000, 2**62])
def test_filter_batch_uses_no_more_threads_than_series(cv, threads):
    # Run in a child process with a timeout: unbounded thread creation used to hang.
    code = (
        "import numpy as np, kfast, threading\n"
        "cv = kfast.models.constant_velocity(2, dt=0.1)\n"
        f"res = kfast.filter_batch(cv, np.zeros((3, 50, 2)), np.zeros(4), np.eye(4), threads={threads})\n"
        "ref = kfast.filter_batch(cv, np.zeros((3, 50, 2)), np.zeros(4), np.eye(4), threads=1)\n"
        "assert np.array_equal(res.loglik, ref.loglik)\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


@pytest.mark.parametrize("threads", [0, -1, 2**64, 1.5, True, "2"])
def test_filter_batch_refuses_bad_thread_counts(cv, threads):
    with pytest.raises(kfast.KfastError, match=r"^threads: "):
        kfast.filter_batch(cv, np.zeros((3, 5, 2)), z, I, threads=threads)


# --- propagate (the core of simulate) checks its noise --------------------------------------


@pytest.mark.parametrize(
    "w, v, arg",
    [
        (np.zeros((5, 3)), np.zeros((5, 2)), "w"),
        (np.zeros((5, 5)), np.zeros((5, 2)), "w"),
        (np.zeros((5, 4)), np.zeros((5, 1)), "v"),
        (np.zeros((5, 4)), np.zeros((5, 3)), "v"),
        (np.zeros((5, 4)), np.zeros((4, 2)), "v"),
        (np.zeros((0, 4)), np.zeros((0, 2)), "w"),
        (np.full((5, 4), np.nan), np.zeros((5, 2)), "w"),
        (np.zeros((5, 4)), np.full((5, 2), np.inf), "v"),
    ],
)
def test_propagate_checks_the_noise_widths_and_values(cv, w, v, arg):
    with pytest.raises(kfast.KfastError, match=rf"^{arg}\b"):
        cv._core.propagate(z, w, v)


# --- simulate validates its prior as filter does ---------------------------------------------


@pytest.mark.parametrize(
    "x0, P0, arg",
    [
        (np.full(4, np.nan), I, "x0"),
        (np.array([0, 0, np.inf, 0]), I, "x0"),
        (z, np.full((4, 4), np.nan), "P0"),
        (z, np.where(I > 0, np.inf, 0.0), "P0"),
        (z, -I, "P0"),
        (z, np.triu(np.ones((4, 4))), "P0"),
        (np.zeros(3), I, "x0"),
        (z, np.eye(3), "P0"),
    ],
)
def test_simulate_rejects_what_filter_rejects(cv, x0, P0, arg):
    with pytest.raises(kfast.KfastError, match=rf"^{arg}\b") as sim:
        cv.simulate(10, x0, P0, seed=0)
    with pytest.raises(kfast.KfastError, match=rf"^{arg}\b"):
        cv.filter(np.zeros((10, 2)), x0, P0)
    assert "Traceback" not in str(sim.value)


@pytest.mark.parametrize("seed", [-1, 1.5, "abc", [1, -2]])
def test_simulate_names_a_bad_seed(cv, seed):
    with pytest.raises(kfast.KfastError, match=r"^seed: "):
        cv.simulate(10, z, I, seed=seed)


# --- masked arrays: masked observations are missing, masked anything else is refused ---------


def masked_rows(y, rows):
    mask = np.zeros(y.shape, dtype=bool)
    mask[rows] = True
    return np.ma.masked_array(y, mask=mask)


def test_masked_observations_are_missing_values_everywhere(cv):
    rng = np.random.default_rng(1)
    y = rng.standard_normal((30, 2))
    y[7] = 1e3  # a masked outlier must not enter the likelihood
    y[12, 1] = -1e3
    masked = np.ma.masked_array(y, mask=np.zeros_like(y, dtype=bool))
    masked[7] = np.ma.masked
    masked[12, 1] = np.ma.masked
    nan = y.copy()
    nan[7] = np.nan
    nan[12, 1] = np.nan
    assert cv.loglik(masked, z, I) == cv.loglik(nan, z, I)
    assert np.isclose(cv.loglik(masked, z, I), cv.loglik(nan, z, I))
    np.testing.assert_array_equal(cv.filter(masked, z, I).x_filt, cv.filter(nan, z, I).x_filt)
    np.testing.assert_array_equal(cv.smooth(masked, z, I).x_smooth, cv.smooth(nan, z, I).x_smooth)
    np.testing.assert_array_equal(
        cv.smooth_fixed_lag(masked, z, I, lag=3).x_smooth, cv.smooth_fixed_lag(nan, z, I, lag=3).x_smooth
    )
    np.testing.assert_array_equal(
        cv.smooth_fixed_point(masked, z, I, t_point=5).x, cv.smooth_fixed_point(nan, z, I, t_point=5).x
    )
    Y_masked = np.ma.stack([masked, masked])
    Y_nan = np.stack([nan, nan])
    np.testing.assert_array_equal(kfast.filter_batch(cv, Y_masked, z, I).loglik, kfast.filter_batch(cv, Y_nan, z, I).loglik)
    np.testing.assert_array_equal(
        cv.em(masked, z, I, n_iter=2, fit=("Q", "R")).loglik, cv.em(nan, z, I, n_iter=2, fit=("Q", "R")).loglik
    )
    assert not np.ma.is_masked(masked[0]) and masked.data[7, 0] == 1e3  # the input is untouched


def test_the_issue_reproducer_gives_the_missing_data_loglik(cv):
    y = np.zeros((50, 2))
    y[20] = 1e3
    masked = masked_rows(y, [20])
    nan = y.copy()
    nan[20] = np.nan
    ll = cv.loglik(masked, z, I)
    assert ll == cv.loglik(nan, z, I) and ll > -1e3


def test_masked_observations_in_streaming_updates(cv):
    kf_masked, kf_nan = kfast.KalmanFilter(cv, z, I), kfast.KalmanFilter(cv, z, I)
    kf_masked.update(np.ma.masked_array([1e3, 2.0], mask=[True, False]))
    kf_nan.update(np.array([np.nan, 2.0]))
    np.testing.assert_array_equal(kf_masked.x, kf_nan.x)
    fl_masked, fl_nan = kfast.FixedLagSmoother(cv, z, I, 2), kfast.FixedLagSmoother(cv, z, I, 2)
    fl_masked.update(np.ma.masked_array([1e3, 2.0], mask=[True, False]))
    fl_nan.update(np.array([np.nan, 2.0]))
    np.testing.assert_array_equal(fl_masked.x_window, fl_nan.x_window)


def test_fit_reads_masked_observations_as_missing():
    y = np.ma.masked_array([0.3, 1e3, -0.2, 0.5, 0.1], mask=[0, 1, 0, 0, 0])

    def build(theta):
        return kfast.LinearGaussian(F=0.0, H=1.0, Q=0.0, R=np.exp(theta[0])), 0.0, 0.0

    res = kfast.fit(build, [0.0], y)
    assert np.isclose(np.exp(res.theta[0]), np.mean(np.array([0.3, -0.2, 0.5, 0.1]) ** 2), rtol=1e-4)


def test_an_unmasked_masked_array_is_its_data(cv):
    y = np.random.default_rng(2).standard_normal((10, 2))
    assert cv.loglik(np.ma.masked_array(y), z, I) == cv.loglik(y, z, I)
    assert cv.loglik(y, np.ma.masked_array(z), np.ma.masked_array(I)) == cv.loglik(y, z, I)


@pytest.mark.parametrize("arg", ["x0", "P0", "u"])
def test_masked_entries_outside_the_observations_are_refused(arg):
    model = kfast.LinearGaussian(F=np.eye(2), H=[[1.0, 0.0]], Q=np.eye(2), R=1.0, B=np.eye(2))
    kwargs = {"x0": np.zeros(2), "P0": np.eye(2), "u": np.zeros((5, 2))}
    kwargs[arg] = np.ma.masked_array(kwargs[arg], mask=np.ones(kwargs[arg].shape, dtype=bool))
    with pytest.raises(kfast.KfastError, match=rf"^{arg}: has masked entries \(\d+\)"):
        model.filter(np.zeros(5), **kwargs)


def test_a_masked_model_matrix_is_refused():
    with pytest.raises(kfast.KfastError, match=r"^Q: has masked entries \(1\)"):
        kfast.LinearGaussian(F=1.0, H=1.0, Q=np.ma.masked_array([[1.0]], mask=[[True]]), R=1.0)


# --- filter_batch checks shapes, not only element counts -------------------------------------


def test_filter_batch_refuses_transposed_priors_and_inputs():
    model = kfast.LinearGaussian(F=0.9 * np.eye(3), H=np.ones((1, 3)), Q=np.eye(3), R=1.0, B=np.ones((3, 3)))
    Y = np.zeros((3, 6))  # B = 3 series = n states = k inputs: element counts cannot tell
    x0s, P0s, u = np.zeros((3, 3)), np.stack([np.eye(3)] * 3), np.zeros((3, 6, 3))
    kfast.filter_batch(model, Y, x0s, P0s, u=u)  # the right shapes work
    with pytest.raises(kfast.KfastError, match=r"^u: has 3 steps but Y has 6"):
        kfast.filter_batch(model, Y, x0s, P0s, u=np.zeros((6, 3, 3)))
    with pytest.raises(kfast.KfastError, match=r"^u: expected shape \(6, 3\) \(shared\) or \(3, 6, 3\)"):
        kfast.filter_batch(model, Y, x0s, P0s, u=np.zeros((2, 6, 3)))
    with pytest.raises(kfast.KfastError, match=r"^x0: expected shape \(3,\) \(shared\) or \(3, 3\)"):
        kfast.filter_batch(model, Y, np.zeros(9), P0s, u=u)


def test_filter_batch_refuses_x0_as_n_by_B(cv):
    Y = np.zeros((3, 10, 2))
    with pytest.raises(kfast.KfastError, match=r"^x0: expected shape \(4,\) \(shared\) or \(3, 4\)"):
        kfast.filter_batch(cv, Y, np.zeros((4, 3)), I)
    with pytest.raises(kfast.KfastError, match=r"^P0: expected shape"):
        kfast.filter_batch(cv, Y, z, np.zeros((4, 4, 3)))


@pytest.mark.parametrize("model", [None, "cv", np.eye(2)])
def test_filter_batch_names_a_model_of_the_wrong_type(model):
    with pytest.raises(kfast.KfastError, match=r"^model: expected a kfast.LinearGaussian"):
        kfast.filter_batch(model, np.zeros((3, 5, 2)), z, I)


@pytest.mark.parametrize("value", ["no", 0, None, np.array([True])])
def test_filter_batch_return_covs_is_a_bool(cv, value):
    with pytest.raises(kfast.KfastError, match=r"^return_covs: expected True or False"):
        kfast.filter_batch(cv, np.zeros((3, 5, 2)), z, I, return_covs=value)


# --- arguments named in the errors ------------------------------------------------------------


@pytest.mark.parametrize(
    "call, arg",
    [
        (lambda m: m.filter(np.zeros((5, 2)), z, I, form=b"joseph"), "form"),
        (lambda m: m.filter(np.zeros((5, 2)), z, I, form=None), "form"),
        (lambda m: m.filter(np.zeros((5, 2)), z, I, steady_state="no"), "steady_state"),
        (lambda m: m.filter(np.zeros((5, 2)), z, I, converge_tol="1e-9"), "converge_tol"),
        (lambda m: m.filter(np.zeros((5, 2)), z, I, converge_tol=np.nan), "converge_tol"),
        (lambda m: m.filter(np.zeros((5, 2)), z, I, converge_tol=1 + 1j), "converge_tol"),
        (lambda m: m.filter(np.zeros((5, 2)), z, I, converge_tol=10**400), "converge_tol"),
        (lambda m: m.em(np.zeros((5, 2)), z, I, tol=10**400), "tol"),
        (lambda m: m.filter(np.zeros((5, 2)), z, I, outputs=5), "outputs"),
        (lambda m: m.smooth_fixed_lag(np.zeros((5, 2)), z, I, lag=1.5), "lag"),
        (lambda m: m.smooth_fixed_point(np.zeros((5, 2)), z, I, t_point=2**70), "t_point"),
        (lambda m: m.forecast(z, I, steps=2**63), "steps"),
        (lambda m: m.simulate(1.0, z, I), "T"),
        (lambda m: m.em(np.zeros((5, 2)), z, I, fit=None), "fit"),
        (lambda m: m.em(np.zeros((5, 2)), z, I, fit=["Q", "S"]), "fit"),
        (lambda m: m.em(np.zeros((5, 2)), z, I, tol="small"), "tol"),
        (lambda m: m.em(np.zeros((5, 2)), z, I, progress="yes"), "progress"),
        (lambda m: m.em(5.0, z, I), "y"),
        (lambda m: m.em(np.zeros((5, 2)), np.zeros(3), I), "x0"),
        (lambda m: m.em(np.zeros((5, 2)), z, np.eye(3)), "P0"),
    ],
)
def test_errors_name_the_argument(cv, call, arg):
    with pytest.raises(kfast.KfastError, match=rf"^{arg}\b"):
        call(cv)


def test_em_with_inputs_but_no_u_names_u():
    model = kfast.LinearGaussian(F=0.5, H=1.0, Q=1.0, R=1.0, B=1.0)
    with pytest.raises(kfast.KfastError, match=r"^u\b"):
        model.em(np.zeros(5), 0.0, 1.0)


def test_em_on_a_single_step(cv):
    res = cv.em(np.ones((1, 2)), z, I, n_iter=2, fit=("x0",))
    assert res.n_iter == 2 and np.all(np.isfinite(res.loglik))


# --- streaming objects from several threads -----------------------------------------------------


def test_one_filter_per_thread_gives_the_sequential_results(cv):
    rng = np.random.default_rng(8)
    ys = rng.standard_normal((8, 200, 2))
    expected = [cv.filter(y, z, I).x_filt[-1] for y in ys]
    got = [None] * 8

    def run(i):
        kf = kfast.KalmanFilter(cv, z, I)
        for row in ys[i][:-1]:
            kf.step(row)
        kf.update(ys[i][-1])
        got[i] = kf.x

    threads = [threading.Thread(target=run, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for g, e in zip(got, expected):
        np.testing.assert_array_equal(g, e)


def test_a_filter_shared_by_threads_stays_consistent(cv):
    # Every call runs whole: 8 threads x 250 step() calls with the same observation leave the
    # filter exactly where 2000 sequential steps do (the order of identical steps is irrelevant).
    y = np.array([0.5, -0.25])
    shared = kfast.KalmanFilter(cv, z, I)
    errors = []

    def run():
        try:
            for _ in range(250):
                shared.step(y)
        except BaseException as exc:  # noqa: BLE001 - any failure fails the test
            errors.append(exc)

    threads = [threading.Thread(target=run) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    sequential = kfast.KalmanFilter(cv, z, I)
    for _ in range(2000):
        sequential.step(y)
    assert not errors
    assert shared.t == 2000
    np.testing.assert_array_equal(shared.x, sequential.x)
    np.testing.assert_array_equal(shared.P, sequential.P)


# --- numerical failures are errors naming the step ---------------------------------------------


def test_a_singular_innovation_covariance_is_an_error_naming_the_step():
    # Q = 0 and a rank-one R: after two updates one combination of y is known exactly and S is
    # singular; the factorization used to accept a pivot of 1e-15 relative and the smoothed
    # covariance reached 4e15 (exact: 2.4e-14).
    rng = np.random.default_rng(155)
    F = 0.5 * rng.standard_normal((4, 4))
    H = rng.standard_normal((2, 4))
    b = rng.standard_normal((2, 1))
    C = rng.standard_normal((4, 4))
    y = rng.standard_normal((30, 2))
    model = kfast.LinearGaussian(F, H, 0 * I, b @ b.T)
    for call in (model.smooth, model.filter, model.loglik):
        with pytest.raises(kfast.InnovationCovarianceError, match=r"at step 4 .*not positive definite to working precision"):
            call(y, z, C @ C.T)


def test_components_in_very_different_units_are_not_singular():
    # The pivot test is relative to each component's own variance: S = diag(1e8, 1e-8) is fine.
    model = kfast.LinearGaussian(F=np.eye(2), H=np.eye(2), Q=np.diag([1e8, 1e-8]), R=np.diag([1e8, 1e-8]))
    y = np.column_stack([1e4 * np.sin(np.arange(20.0)), 1e-4 * np.cos(np.arange(20.0))])
    res = model.filter(y, np.zeros(2), np.diag([1e8, 1e-8]))
    scaled = kfast.LinearGaussian(F=np.eye(2), H=np.eye(2), Q=np.eye(2), R=np.eye(2))
    ref = scaled.filter(y / [1e4, 1e-4], np.zeros(2), np.eye(2))
    np.testing.assert_allclose(res.x_filt / [1e4, 1e-4], ref.x_filt, rtol=1e-12)
    assert np.isclose(res.loglik - ref.loglik, -20 * (np.log(1e8) + np.log(1e-8)) / 2, atol=1e-9)


def test_a_state_that_overflows_is_an_error_naming_the_step():
    # A known (P = 0) state multiplied by 1e100 per step leaves float64's range at step 3.
    model = kfast.LinearGaussian(F=1e100, H=1.0, Q=0.0, R=1.0)
    for call in (model.filter, model.loglik, model.smooth):
        with pytest.raises(kfast.KfastError, match=r"^y at step \d+: the state estimate overflowed"):
            call(np.ones(10), 1.0, 0.0)
