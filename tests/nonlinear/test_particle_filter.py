"""The particle filter (NonlinearModel.particle_filter): against its NumPy reference (which draws
the same random numbers), against the Kalman filter on linear Gaussian models as the number of
particles grows, the unbiasedness of its likelihood estimate, and bad input."""

import numpy as np
import pytest
from modelgen import random_case
from scipy.special import ndtri

import kfast
from kfast.reference import kalman_filter
from kfast.reference import particle as ref

SCHEMES = ("multinomial", "systematic", "stratified", "residual")


def ungm_f(X, t, u):
    return X / 2 + 25 * X / (1 + X**2) + 8 * np.cos(1.2 * t)


def ungm_h(X, t, u):
    return X**2 / 20


def simulate_ungm(T, seed, q=10.0, r=1.0):
    rng = np.random.default_rng(seed)
    x, y = np.zeros(T), np.zeros(T)
    x[0] = rng.normal(0, np.sqrt(5.0))
    for t in range(T):
        y[t] = x[t] ** 2 / 20 + rng.normal(0, np.sqrt(r))
        if t + 1 < T:
            x[t + 1] = ungm_f(x[t], t, None) + rng.normal(0, np.sqrt(q))
    return x, y


def assert_same(got, want, rtol=1e-10, atol=1e-10):
    for k in ("x_filt", "P_filt", "ess", "loglik_t"):
        np.testing.assert_allclose(getattr(got, k), want[k], rtol=rtol, atol=atol, err_msg=k)
    np.testing.assert_array_equal(got.resampled, want["resampled"])
    assert got.loglik == pytest.approx(want["loglik"], rel=1e-10)


def test_the_generator_normals_are_the_normal_quantile():
    # AS 241 against scipy's ndtri in each of its three regions
    p = np.concatenate([np.linspace(0.001, 0.999, 2001), np.logspace(-300, -3, 300), 1 - np.logspace(-15, -3, 50)])
    np.testing.assert_allclose(ref.normal_quantile(p), ndtri(p), rtol=2e-15, atol=0)
    u = ref.Stream(7, 3, ref.PROCESS_NOISE).uniform(np.arange(200_000))
    assert 0 < u.min() and u.max() < 1
    z = ref.Stream(7, 3, ref.PROCESS_NOISE).normal(np.arange(200_000))
    assert abs(z.mean()) < 0.01 and abs(z.var() - 1) < 0.01


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("threshold", [None, 0.5])
def test_equals_the_reference_on_ungm(scheme, threshold):
    _, y = simulate_ungm(30, seed=1)
    y[[4, 11]] = np.nan
    nm = kfast.NonlinearModel(ungm_f, ungm_h, [[10.0]], [[1.0]], n=1)
    got = nm.particle_filter(y, [0.0], [[5.0]], 500, resample=scheme, ess_threshold=threshold, seed=3)
    want = ref.particle_filter(ungm_f, ungm_h, [[10.0]], [[1.0]], y, [0.0], [[5.0]], 500, scheme, threshold, seed=3)
    assert_same(got, want)
    assert got.resampled.dtype == bool and got.loglik == pytest.approx(got.loglik_t.sum())
    assert np.all((got.ess >= 1 - 1e-9) & (got.ess <= 500 * (1 + 1e-12)))
    if threshold is not None:
        assert 0 < got.resampled[:-1].sum() < 29  # triggered at some steps, not all


def test_builtin_ungm_equals_the_callable_and_the_reference():
    _, y = simulate_ungm(25, seed=2)
    builtin = kfast.models.ungm(q=10.0, r=1.0)
    got = builtin.particle_filter(y, [0.0], [[5.0]], 300, resample="systematic", seed=9)
    want = ref.particle_filter(ungm_f, ungm_h, [[10.0]], [[1.0]], y, [0.0], [[5.0]], 300, "systematic", seed=9)
    assert_same(got, want, rtol=1e-9, atol=1e-9)


def test_range_bearing_with_angles_noise_gain_and_noise_input_equal_the_reference():
    rng = np.random.default_rng(4)
    F = np.array([[1, 0, 1, 0], [0, 1, 0, 1], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    Q, R = 0.1 * np.eye(4), np.diag([0.5, 0.01])

    def f(X, t, u):
        return X @ F.T

    def h(X, t, u):
        return np.stack([np.hypot(X[:, 0], X[:, 1]), np.arctan2(X[:, 1], X[:, 0])], axis=1)

    x0, P0 = np.array([-20.0, 0.5, 1.0, 0.0]), np.diag([1.0, 1.0, 0.1, 0.1])
    x, ys = x0.copy(), []
    for t in range(20):  # the target crosses the bearing's +-pi cut behind the sensor
        ys.append(h(x[None], t, None)[0] + rng.normal(0, np.sqrt(np.diag(R))))
        x = F @ x + rng.normal(0, 0.3, 4)
    y = np.array(ys)
    y[5, 0] = np.nan
    nm = kfast.NonlinearModel(f, h, Q, R, n=4, angles=[1])
    got = nm.particle_filter(y, x0, P0, 400, resample="stratified", ess_threshold=0.7, seed=5)
    want = ref.particle_filter(f, h, Q, R, y, x0, P0, 400, "stratified", 0.7, seed=5, angles=(1,))
    assert_same(got, want)
    G = np.array([[0.5, 0], [0, 0.5], [1, 0], [0, 1.0]])
    gained = kfast.NonlinearModel(f, h, 0.2 * np.eye(2), R, n=4, angles=[1], g=lambda X, t, u: np.broadcast_to(G, (len(X), 4, 2)))
    got = gained.particle_filter(y, x0, P0, 400, seed=6)
    want = ref.particle_filter(f, h, 0.2 * np.eye(2), R, y, x0, P0, 400, seed=6, angles=(1,), g=lambda X, t, u: np.broadcast_to(G, (len(X), 4, 2)))
    assert_same(got, want)

    def f_noise(X, W, t, u):
        return X @ F.T + W @ G.T

    as_input = kfast.NonlinearModel(f_noise, h, 0.2 * np.eye(2), R, n=4, angles=[1], noise_input=True)
    got = as_input.particle_filter(y, x0, P0, 400, seed=6)
    assert_same(got, want)  # the same noise enters the same way


@pytest.mark.parametrize("scheme", SCHEMES)
def test_converges_to_the_kalman_filter_on_a_linear_model(scheme):
    c = random_case(11, 2, 1, T=15, missing="none")
    F, H, Q, R = (c.model[k] for k in "FHQR")
    kf = kalman_filter(F, H, Q, R, c.y, c.x0, c.P0)
    nm = kfast.NonlinearModel.from_linear(kfast.LinearGaussian(F, H, Q, R))
    errors = []
    for M in (200, 20_000):
        pf = nm.particle_filter(c.y, c.x0, c.P0, M, resample=scheme, ess_threshold=0.5, seed=1)
        # the error of a weighted mean is about sqrt(P / ESS) -- up to 3 times that after
        # resampling, whose duplicates make the ESS of the weights overstate the independent
        # particles (measured over 40 seeds on the Rust test's model): allow 5 times 3
        se = np.sqrt(np.einsum("tii->ti", kf["P_filt"]) / pf.ess[:, None])
        assert np.all(np.abs(pf.x_filt - kf["x_filt"]) < 15 * se)
        errors.append(np.abs(pf.x_filt - kf["x_filt"]).max())
        np.testing.assert_allclose(pf.P_filt, kf["P_filt"], rtol=5 / np.sqrt(M) * 10, atol=1e-3)
    assert errors[1] < errors[0]
    # its standard deviation over seeds is 0.06-0.08 here (M = 20,000, every scheme)
    assert pf.loglik == pytest.approx(kf["loglik"], abs=0.3)


@pytest.mark.parametrize("threshold", [None, 0.5, 1e-9])
def test_the_likelihood_estimate_is_unbiased_in_p_not_log_p(threshold):
    # scalar linear Gaussian model: p(y) exactly from the Kalman filter
    F, H, Q, R = np.array([[0.9]]), np.array([[1.0]]), np.array([[1.0]]), np.array([[0.5]])
    lin = kfast.LinearGaussian(F, H, Q, R)
    y = lin.simulate(12, [0.0], [[1.0]], seed=3).y
    exact = kalman_filter(F, H, Q, R, y, np.zeros(1), np.eye(1))["loglik"]
    nm = kfast.NonlinearModel.from_linear(lin)
    ratios = np.array([
        np.exp(nm.particle_filter(y, [0.0], [[1.0]], 40, resample="systematic", ess_threshold=threshold, seed=s).loglik - exact)
        for s in range(600)
    ])
    se = ratios.std(ddof=1) / np.sqrt(len(ratios))
    assert abs(ratios.mean() - 1) < 4 * se, (ratios.mean(), se)
    # and log p-hat is biased low (Jensen): its mean is below the exact log-likelihood
    assert np.mean(np.log(ratios)) < 0


def test_the_plain_mean_of_likelihoods_would_be_biased():
    # the estimator that ignores the carried weights at steps without resampling (the peers' bug)
    # is detectably off on the same problem: the test above can fail
    F, H, Q, R = np.array([[0.9]]), np.array([[1.0]]), np.array([[1.0]]), np.array([[0.5]])
    lin = kfast.LinearGaussian(F, H, Q, R)
    y = lin.simulate(12, [0.0], [[1.0]], seed=3).y
    exact = kalman_filter(F, H, Q, R, y, np.zeros(1), np.eye(1))["loglik"]
    nm = kfast.NonlinearModel.from_linear(lin)
    wrong = []
    for s in range(300):
        res = nm.particle_filter(y, [0.0], [[1.0]], 40, resample="systematic", ess_threshold=1e-9, seed=s, keep="all")
        # log mean_i p(y(t) | x_i) with equal weights, recomputed from the kept particles
        total = 0.0
        for t in range(12):
            X = res.particles[t, :, 0]
            total += np.log(np.mean(np.exp(-0.5 * (np.log(2 * np.pi * 0.5) + (y[t, 0] - X) ** 2 / 0.5))))
        wrong.append(np.exp(total - exact))
    wrong = np.array(wrong)
    assert abs(wrong.mean() - 1) > 4 * wrong.std(ddof=1) / np.sqrt(len(wrong))


def test_keep_returns_the_weighted_particles():
    _, y = simulate_ungm(10, seed=3)
    nm = kfast.models.ungm()
    last = nm.particle_filter(y, [0.0], [[5.0]], 200, keep="last", seed=2)
    every = nm.particle_filter(y, [0.0], [[5.0]], 200, keep="all", seed=2)
    assert last.particles.shape == (200, 1) and last.log_weights.shape == (200,)
    assert every.particles.shape == (10, 200, 1) and every.log_weights.shape == (10, 200)
    np.testing.assert_array_equal(every.particles[-1], last.particles)
    for t in range(10):
        W = np.exp(every.log_weights[t])
        assert W.sum() == pytest.approx(1.0)
        assert W @ every.particles[t, :, 0] == pytest.approx(every.x_filt[t, 0], rel=1e-12, abs=1e-12)
    assert nm.particle_filter(y, [0.0], [[5.0]], 200).particles is None


def test_same_seed_same_bits_other_seed_other_numbers():
    _, y = simulate_ungm(20, seed=4)
    nm = kfast.models.ungm()
    a, b = (nm.particle_filter(y, [0.0], [[5.0]], 1000, seed=11) for _ in range(2))
    np.testing.assert_array_equal(a.x_filt, b.x_filt)
    assert a.loglik == b.loglik
    c = nm.particle_filter(y, [0.0], [[5.0]], 1000, seed=12)
    assert not np.array_equal(a.x_filt, c.x_filt)
    assert repr(a).startswith("ParticleResult(T=20, n=1")


def test_bad_input_is_refused_with_the_argument_named():
    nm = kfast.models.ungm()
    y = np.ones(5)
    for kw, arg in (
        ({"n_particles": 0}, "n_particles"), ({"n_particles": -3}, "n_particles"), ({"n_particles": True}, "n_particles"),
        ({"n_particles": 10**18}, "n_particles"), ({"resample": "best"}, "resample"), ({"ess_threshold": 0}, "ess_threshold"),
        ({"ess_threshold": 1.5}, "ess_threshold"), ({"ess_threshold": float("nan")}, "ess_threshold"),
        ({"ess_threshold": "half"}, "ess_threshold"), ({"seed": -1}, "seed"), ({"seed": 2**64}, "seed"),
        ({"seed": 1.5}, "seed"), ({"keep": "first"}, "keep"),
    ):
        args = {"n_particles": 10, **kw}
        with pytest.raises(ValueError, match=arg):
            nm.particle_filter(y, [0.0], [[1.0]], **args)


def test_errors_during_the_run_name_the_function_and_step():
    def f(X, t, u):
        return X * (np.nan if t == 3 else 1.0)

    nm = kfast.NonlinearModel(f, ungm_h, [[1.0]], [[1.0]], n=1)
    with pytest.raises(ValueError, match=r"f.*step 3|step 3.*f"):
        nm.particle_filter(np.ones(6), [0.0], [[1.0]], 50)
    tight = kfast.NonlinearModel(ungm_f, ungm_h, [[1.0]], [[1e-300]], n=1)
    with pytest.raises(ValueError, match=r"y.*step 0|step 0.*y"):
        tight.particle_filter(np.full(3, 1e6), [0.0], [[1.0]], 50)
    data = np.array([1.0, 2.0])
    before = data.copy()
    nm.particle_filter(data, [0.0], [[1.0]], 10)
    np.testing.assert_array_equal(data, before)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_the_same_bits_for_any_thread_count(scheme):
    # 10,007 particles: several blocks, the last one short
    _, y = simulate_ungm(15, seed=5)
    nm = kfast.models.ungm()
    runs = [nm.particle_filter(y, [0.0], [[5.0]], 10_007, resample=scheme, ess_threshold=0.6, seed=4, threads=k) for k in (1, 2, 3, None)]
    for other in runs[1:]:
        for k in ("x_filt", "P_filt", "ess", "loglik_t", "resampled"):
            np.testing.assert_array_equal(getattr(other, k), getattr(runs[0], k), err_msg=k)


def test_a_compiled_model_equals_the_python_callable():
    import numba  # a test extra (kfast[test])
    from numba import types

    sig = types.void(types.CPointer(types.float64), types.intp, types.intp, types.int64, types.CPointer(types.float64), types.CPointer(types.float64))

    @numba.cfunc(sig)
    def f(X, k, n, t, u, out):
        for i in range(k):
            x = X[i]
            out[i] = x / 2 + 25 * x / (1 + x * x) + 8 * np.cos(1.2 * t)

    @numba.cfunc(sig)
    def h(X, k, n, t, u, out):
        for i in range(k):
            out[i] = X[i] * X[i] / 20

    _, y = simulate_ungm(20, seed=6)
    compiled = kfast.NonlinearModel(f, h, [[10.0]], [[1.0]], n=1)
    python = kfast.NonlinearModel(ungm_f, ungm_h, [[10.0]], [[1.0]], n=1)
    got = compiled.particle_filter(y, [0.0], [[5.0]], 9000, resample="residual", seed=1)
    want = python.particle_filter(y, [0.0], [[5.0]], 9000, resample="residual", seed=1)
    np.testing.assert_allclose(got.x_filt, want.x_filt, rtol=1e-9, atol=1e-9)
    assert got.loglik == pytest.approx(want.loglik, rel=1e-10)


@pytest.mark.parametrize("threshold", [None, 0.5])
def test_the_streaming_filter_gives_the_bits_of_the_batch_filter(threshold):
    _, y = simulate_ungm(25, seed=7)
    y[[3, 9]] = np.nan
    nm = kfast.models.ungm()
    batch = nm.particle_filter(y, [0.0], [[5.0]], 5000, resample="stratified", ess_threshold=threshold, seed=8, keep="all")
    pf = kfast.ParticleFilter(nm, [0.0], [[5.0]], 5000, resample="stratified", ess_threshold=threshold, seed=8)
    assert pf.t == 0 and pf.particles.shape == (5000, 1)
    for t in range(25):
        loglik_t = pf.update(y[t])
        assert loglik_t == batch.loglik_t[t]
        np.testing.assert_array_equal(pf.x, batch.x_filt[t])
        np.testing.assert_array_equal(pf.P, batch.P_filt[t])
        np.testing.assert_array_equal(pf.particles, batch.particles[t])
        np.testing.assert_array_equal(pf.log_weights, batch.log_weights[t])
        assert pf.ess == batch.ess[t]
        if t + 1 < 25:
            assert pf.predict() == batch.resampled[t]
            assert pf.t == t + 1
    assert pf.loglik == pytest.approx(batch.loglik, rel=1e-14)
    assert repr(pf) == "ParticleFilter(t=24, n=1, particles=5000)"


def test_a_failed_streaming_update_leaves_the_particles_unchanged():
    calls = {"n": 0}

    def h(X, t, u):
        calls["n"] += 1
        return X**2 / 20 * (np.nan if calls["n"] == 2 else 1.0)

    nm = kfast.NonlinearModel(ungm_f, h, [[10.0]], [[1.0]], n=1)
    pf = kfast.ParticleFilter(nm, [0.0], [[5.0]], 300, seed=2)
    pf.update([0.3])
    pf.predict()
    before = (pf.particles, pf.log_weights, pf.x, pf.ess)
    with pytest.raises(ValueError, match=r"h.*step 1|step 1.*h"):
        pf.update([0.5])
    after = (pf.particles, pf.log_weights, pf.x, pf.ess)
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a, b)
    tight = kfast.NonlinearModel(ungm_f, ungm_h, [[1.0]], [[1e-300]], n=1)
    pf = kfast.ParticleFilter(tight, [0.0], [[1.0]], 100, seed=1)
    weights = pf.log_weights
    with pytest.raises(ValueError, match="y"):
        pf.update([1e6])
    np.testing.assert_array_equal(pf.log_weights, weights)
    pf.update([0.01])  # and it goes on
    assert pf.t == 0


def test_streaming_bad_input():
    nm = kfast.models.ungm()
    for kw, arg in (({"n_particles": 0}, "n_particles"), ({"resample": "x"}, "resample"), ({"seed": -2}, "seed"),
                    ({"ess_threshold": 2.0}, "ess_threshold"), ({"threads": 0}, "threads")):
        args = {"n_particles": 10, **kw}
        with pytest.raises(ValueError, match=arg):
            kfast.ParticleFilter(nm, [0.0], [[1.0]], **args)
    pf = kfast.ParticleFilter(nm, [0.0], [[1.0]], 10)
    with pytest.raises(ValueError, match="y"):
        pf.update([1.0, 2.0])
    with pytest.raises(ValueError, match="y"):
        pf.update([np.inf])
    with pytest.raises(ValueError, match="model"):
        kfast.ParticleFilter("ungm", [0.0], [[1.0]], 10)
