"""The particle filter with the user's pieces: the book's r copies of each resampled particle
(``copies``), a likelihood p(y | x) written as a function of all particles (Python or numba
``@cfunc``), and a move after resampling (the resample-move filter). Each against the NumPy
reference on the same random numbers, and each doing what it is for."""

import numba
import numpy as np
import pytest
from numba import types
from test_particle_likelihoods import F, Q, R, f, h  # the same linear model, other noise

import kfast
from kfast.reference.particle import particle_filter

SCHEMES = ("multinomial", "systematic", "stratified", "residual")


def data(seed=0, T=25):
    rng = np.random.default_rng(seed)
    x, ys = np.zeros(2), []
    for _ in range(T):
        ys.append(h(x[None], 0, None)[0] + rng.laplace(scale=np.sqrt(np.diag(R) / 2)))
        x = F @ x + rng.multivariate_normal(np.zeros(2), Q)
    y = np.array(ys)
    y[7:8, 1] = np.nan
    y[11:12] = np.nan
    return y


def laplace(X, y, t, u):
    """log p(y | x) of independent Laplace noise of variances diag(R) on the observed outputs."""
    b = np.sqrt(np.diag(R) / 2)
    obs = ~np.isnan(y)
    E = np.abs(y[obs] - h(X, t, u)[:, obs]) / b[obs]
    return -E.sum(axis=1) - np.log(2 * b[obs]).sum()


def gaussian(X, y, t, u):
    """The default likelihood, N(y; h(x), R) on the observed outputs, written by hand."""
    obs = ~np.isnan(y)
    E = y[obs] - h(X, t, u)[:, obs]
    Ro = R[np.ix_(obs, obs)]
    maha = np.einsum("ij,ij->i", E, np.linalg.solve(Ro, E.T).T)
    return -0.5 * (obs.sum() * np.log(2 * np.pi) + np.linalg.slogdet(Ro)[1] + maha)


MODEL = kfast.NonlinearModel(f, h, Q, R, n=2)

# ----------------------------------------------------------------------------------------------
# copies: M = r N
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("copies", [2, 5])
def test_copies_equal_the_reference(scheme, copies):
    y = data()
    res = MODEL.particle_filter(y, np.zeros(2), np.eye(2), n_particles=3000, resample=scheme, seed=4, copies=copies)
    out = particle_filter(f, h, Q, R, y, np.zeros(2), np.eye(2), 3000, scheme, seed=4, copies=copies)
    np.testing.assert_allclose(res.x_filt, out["x_filt"], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(res.P_filt, out["P_filt"], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(res.loglik_t, out["loglik_t"], rtol=1e-9, atol=1e-10)


def test_each_ancestor_is_taken_by_r_particles_in_a_row():
    """Without process noise the r copies of an ancestor stay equal: rows i r .. i r + r - 1."""
    model = kfast.NonlinearModel(f, h, np.zeros((2, 2)), R, n=2)
    y = data(T=3)
    for copies in (1, 4):
        res = model.particle_filter(y, np.zeros(2), np.eye(2), n_particles=400, seed=1, copies=copies, keep="all")
        groups = res.particles[1].reshape(400 // copies, copies, 2)
        assert np.all(groups == groups[:, :1]), copies
        # and only the book's N = M / r ancestors at most, not M
        assert len(np.unique(res.particles[1][:, 0])) <= 400 // copies


def test_copies_still_estimate_p_y_without_bias():
    """The exact log-likelihood of a linear Gaussian model: the mean over seeds of
    exp(loglik - exact) is 1 within its standard error with r = 4 copies too."""
    lg = kfast.LinearGaussian(F, np.eye(2), Q, R)
    model = kfast.NonlinearModel(f, lambda X, t, u: X, Q, R, n=2)
    rng = np.random.default_rng(2)
    y = lg.simulate(12, np.zeros(2), np.eye(2), seed=3).y
    exact = lg.loglik(y, np.zeros(2), np.eye(2))
    ratios = np.array([
        np.exp(model.particle_filter(y, np.zeros(2), np.eye(2), n_particles=400, seed=int(s), copies=4).loglik - exact)
        for s in rng.integers(0, 2**32, 300)
    ])
    se = ratios.std(ddof=1) / np.sqrt(len(ratios))
    assert abs(ratios.mean() - 1.0) < 3 * se + 1e-3, (ratios.mean(), se)


@pytest.mark.parametrize("copies, match", [(0, "copies: must be at least 1"), (7, "copies: must be at least 1 and divide n_particles = 100, got 7"),
                                           (1.5, "copies: expected an integer"), (True, "copies: expected an integer")])
def test_bad_copies_are_named(copies, match):
    with pytest.raises(kfast.KfastError, match=match):
        MODEL.particle_filter(data(), np.zeros(2), np.eye(2), n_particles=100, copies=copies)
    with pytest.raises(kfast.KfastError, match=match):
        kfast.ParticleFilter(MODEL, np.zeros(2), np.eye(2), n_particles=100, copies=copies)


# ----------------------------------------------------------------------------------------------
# The user's likelihood
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("threshold", [None, 0.5])
def test_a_user_likelihood_equals_the_reference(threshold):
    y = data()
    res = MODEL.particle_filter(y, np.zeros(2), np.eye(2), n_particles=3000, ess_threshold=threshold, seed=5, likelihood=laplace)
    out = particle_filter(f, h, Q, R, y, np.zeros(2), np.eye(2), 3000, ess_threshold=threshold, seed=5, likelihood=laplace)
    np.testing.assert_allclose(res.x_filt, out["x_filt"], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(res.loglik_t, out["loglik_t"], rtol=1e-9, atol=1e-10)
    np.testing.assert_array_equal(res.resampled, out["resampled"])
    assert res.loglik_t[11] == 0.0  # nothing observed: the function is not called


def test_the_gaussian_written_by_hand_is_the_default():
    y = data(1)
    default = MODEL.particle_filter(y, np.zeros(2), np.eye(2), n_particles=2000, seed=2)
    by_hand = MODEL.particle_filter(y, np.zeros(2), np.eye(2), n_particles=2000, seed=2, likelihood=gaussian)
    np.testing.assert_allclose(by_hand.loglik_t, default.loglik_t, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(by_hand.x_filt, default.x_filt, rtol=1e-9, atol=1e-10)


def test_the_likelihood_sees_y_t_and_u():
    seen = []

    def spy(X, y, t, u):
        seen.append((t, y.copy(), None if u is None else u.copy(), X.shape))
        return np.zeros(len(X))

    y, u = data(T=4), np.arange(8.0).reshape(4, 2)
    MODEL.particle_filter(y, np.zeros(2), np.eye(2), n_particles=10, u=u, likelihood=spy)
    assert [s[0] for s in seen] == [0, 1, 2, 3]
    for t, y_t, u_t, shape in seen:
        np.testing.assert_array_equal(y_t, y[t])
        np.testing.assert_array_equal(u_t, u[t])
        assert shape == (10, 2)


@numba.cfunc(types.void(types.CPointer(types.double), types.intp, types.intp, types.CPointer(types.double), types.intp,
                        types.int64, types.CPointer(types.double), types.CPointer(types.double)))
def laplace_c(X, k, n, y, m, t, u, out):
    """``laplace`` compiled: the PARTICLE_C_SIGNATURE of kfast."""
    x, obs, o = numba.carray(X, (k, n)), numba.carray(y, (m,)), numba.carray(out, (k,))
    b0, b1 = np.sqrt(R[0, 0] / 2), np.sqrt(R[1, 1] / 2)
    for i in range(k):
        s = 0.0
        if not np.isnan(obs[0]):
            s -= abs(obs[0] - x[i, 0]) / b0 + np.log(2 * b0)
        if not np.isnan(obs[1]):
            s -= abs(obs[1] - x[i, 0] - x[i, 1]) / b1 + np.log(2 * b1)
        o[i] = s


@pytest.mark.parametrize("threads", [1, 2])
def test_a_compiled_likelihood_equals_the_python_one_on_any_threads(threads):
    """20,000 particles: five blocks, so the compiled function runs per block on both cores."""
    y = data()
    builtin = kfast.NonlinearModel.from_linear(kfast.LinearGaussian(F, np.array([[1.0, 0.0], [1.0, 1.0]]), Q, R))
    python = builtin.particle_filter(y, np.zeros(2), np.eye(2), n_particles=20_000, seed=7, likelihood=laplace)
    compiled = builtin.particle_filter(y, np.zeros(2), np.eye(2), n_particles=20_000, seed=7, likelihood=laplace_c, threads=threads)
    np.testing.assert_allclose(compiled.loglik_t, python.loglik_t, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(compiled.x_filt, python.x_filt, rtol=1e-10, atol=1e-12)
    one = builtin.particle_filter(y, np.zeros(2), np.eye(2), n_particles=20_000, seed=7, likelihood=laplace_c, threads=1)
    np.testing.assert_array_equal(compiled.x_filt, one.x_filt)


def test_a_compiled_function_of_the_model_signature_is_refused():
    @numba.cfunc(types.void(types.CPointer(types.double), types.intp, types.intp, types.int64, types.CPointer(types.double),
                            types.CPointer(types.double)))
    def like_h(X, k, n, t, u, out):
        pass

    with pytest.raises(kfast.KfastError, match=r"^likelihood: the compiled function's signature .* is not 'void \(const double \*X, intptr_t k, intptr_t n, const double \*y"):
        MODEL.particle_filter(data(), np.zeros(2), np.eye(2), n_particles=10, likelihood=like_h)
    with pytest.raises(kfast.KfastError, match=r"^move: the compiled function's signature"):
        MODEL.particle_filter(data(), np.zeros(2), np.eye(2), n_particles=10, move=like_h)


@pytest.mark.parametrize(
    "likelihood, match",
    [
        (lambda X, y, t, u: np.zeros((len(X), 1)), r"^likelihood at step 0: it returned shape \(100, 1\) for points X of shape \(100, 2\), expected \(100,\)"),
        (lambda X, y, t, u: np.full(len(X), np.nan if t == 3 else 0.0), r"^likelihood at step 3: returned NaN for a particle"),
        (lambda X, y, t, u: np.full(len(X), np.inf), r"^likelihood at step 0: returned inf for a particle"),
        (lambda X, y, t, u: np.full(len(X), -np.inf), r"^y at step 0: has no particle that explains it"),
        (lambda X, y, t, u: 1 / 0, r"^likelihood at step 0: it raised ZeroDivisionError: division by zero"),
        (lambda X, y, t, u: "text", r"^likelihood at step 0: it did not return an array of numbers"),
        ("gaussian", r"^likelihood: expected None \(Gaussian\), kfast.StudentT, kfast.UniformNoise, kfast.Quantized or a function"),
    ],
)
def test_a_bad_likelihood_is_named_with_its_step(likelihood, match):
    with pytest.raises(kfast.KfastError, match=match):
        MODEL.particle_filter(data(), np.zeros(2), np.eye(2), n_particles=100, likelihood=likelihood)


def test_a_failed_user_update_leaves_the_streaming_filter_unchanged():
    bad = {"now": False}

    def sometimes(X, y, t, u):
        return np.full(len(X), np.nan) if bad["now"] else laplace(X, y, t, u)

    pf = kfast.ParticleFilter(MODEL, np.zeros(2), np.eye(2), n_particles=500, seed=3, likelihood=sometimes)
    y = data()
    pf.update(y[0])
    pf.predict()
    before = (pf.particles, pf.log_weights, pf.x, pf.loglik)
    bad["now"] = True
    with pytest.raises(kfast.KfastError, match="likelihood at step 1"):
        pf.update(y[1])
    np.testing.assert_array_equal(pf.log_weights, before[1])
    bad["now"] = False
    pf.update(y[1])
    assert np.isfinite(pf.loglik)


# ----------------------------------------------------------------------------------------------
# The move after resampling
# ----------------------------------------------------------------------------------------------


def shift(X, y, t, u):
    """A deterministic move, enough to compare with the reference."""
    return X + 0.01 * np.nan_to_num(y[0]) * np.array([1.0, -0.5])


@pytest.mark.parametrize("regularize", [False, 0.5])
@pytest.mark.parametrize("threshold", [None, 0.6])
def test_a_move_equals_the_reference(regularize, threshold):
    y = data()
    res = MODEL.particle_filter(y, np.zeros(2), np.eye(2), n_particles=2000, ess_threshold=threshold, seed=6, move=shift,
                                regularize=regularize, copies=2)
    out = particle_filter(f, h, Q, R, y, np.zeros(2), np.eye(2), 2000, ess_threshold=threshold, seed=6, move=shift,
                          regularize=regularize or None, copies=2)
    np.testing.assert_allclose(res.x_filt, out["x_filt"], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(res.loglik_t, out["loglik_t"], rtol=1e-9, atol=1e-10)


def test_the_move_gets_the_updates_y_and_runs_only_after_resampling():
    calls = []

    def spy(X, y, t, u):
        calls.append((t, y.copy()))
        return X

    y = data(T=10)
    res = MODEL.particle_filter(y, np.zeros(2), np.eye(2), n_particles=200, seed=1, ess_threshold=0.3, move=spy)
    assert [c[0] for c in calls] == list(np.flatnonzero(res.resampled))
    for t, y_t in calls:
        np.testing.assert_array_equal(y_t, y[t])


class RandomWalkMetropolis:
    """A Metropolis step for a constant state x (Q = 0) observed as y(t) = x + v, v ~ N(0, r):
    its target is the exact posterior p(x | y(0..t)) ∝ N(x; x0, p0) prod_s N(y(s); x, r), so it
    leaves the filter's target invariant (the resample-move filter)."""

    def __init__(self, y, x0, p0, r, step, seed):
        self.y, self.x0, self.p0, self.r, self.step, self.seed = y, x0, p0, r, step, seed

    def log_target(self, x, t):
        ys = self.y[: t + 1, 0]
        return -0.5 * (x - self.x0) ** 2 / self.p0 - 0.5 * ((ys[None, :] - x[:, None]) ** 2).sum(axis=1) / self.r

    def __call__(self, X, y, t, u):
        rng = np.random.default_rng([self.seed, t])
        x = X[:, 0]
        for _ in range(3):
            proposal = x + self.step / np.sqrt(t + 1) * rng.standard_normal(len(x))
            accept = np.log(rng.uniform(size=len(x))) < self.log_target(proposal, t) - self.log_target(x, t)
            x = np.where(accept, proposal, x)
        return x[:, None]


def test_resample_move_keeps_a_static_state_diverse_and_on_the_exact_posterior():
    """x constant (Q = 0), 60 measurements: the bootstrap filter's particles collapse onto a few
    values (all copies of the prior's draws), while an MCMC move on the exact posterior keeps
    them distinct and their moments on the Kalman filter's."""
    rng = np.random.default_rng(8)
    T, r, x0, p0 = 60, 1.0, 0.0, 4.0
    y = (1.3 + np.sqrt(r) * rng.standard_normal(T))[:, None]
    model = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X, Q=0.0, R=r, n=1)
    exact = kfast.LinearGaussian(np.eye(1), np.eye(1), np.zeros((1, 1)), [[r]]).filter(y, [x0], [[p0]])
    move = RandomWalkMetropolis(y, x0, p0, r, step=2.0, seed=1)
    plain = model.particle_filter(y, x0, p0, n_particles=2000, seed=2, resample="systematic", keep="last")
    moved = model.particle_filter(y, x0, p0, n_particles=2000, seed=2, resample="systematic", keep="last", move=move)
    assert len(np.unique(plain.particles)) < 60
    assert len(np.unique(moved.particles)) > 1000
    sd = np.sqrt(exact.P_filt[-1, 0, 0])
    assert abs(moved.x_filt[-1, 0] - exact.x_filt[-1, 0]) < 0.15 * sd
    assert abs(moved.P_filt[-1, 0, 0] / exact.P_filt[-1, 0, 0] - 1) < 0.2


@pytest.mark.parametrize(
    "move, match",
    [
        (lambda X, y, t, u: X[:, :1], r"^move at step 0: it returned shape \(100, 1\) for points X of shape \(100, 2\), expected \(100, 2\)"),
        (lambda X, y, t, u: X + (np.nan if t == 2 else 0.0), r"^move at step 2: returned a non-finite value \(NaN\)"),
        (lambda X, y, t, u: X[0], r"^move at step 0: it returned shape \(2,\)"),
        (3.0, r"^move: expected a callable move\(X, y, t, u\), got float"),
    ],
)
def test_a_bad_move_is_named_with_its_step(move, match):
    with pytest.raises(kfast.KfastError, match=match):
        MODEL.particle_filter(data(), np.zeros(2), np.eye(2), n_particles=100, move=move)


# ----------------------------------------------------------------------------------------------
# Streaming
# ----------------------------------------------------------------------------------------------


def test_the_streaming_filter_gives_the_bits_of_the_batch_filter_with_every_option():
    y = data()
    options = dict(n_particles=1000, seed=9, ess_threshold=0.7, copies=4, likelihood=laplace, move=shift, regularize=0.3)
    batch = MODEL.particle_filter(y, np.zeros(2), np.eye(2), **options)
    pf = kfast.ParticleFilter(MODEL, np.zeros(2), np.eye(2), **options)
    for t in range(len(y)):
        assert pf.update(y[t]) == batch.loglik_t[t]
        np.testing.assert_array_equal(pf.x, batch.x_filt[t])
        if t + 1 < len(y):
            assert pf.predict() == batch.resampled[t]
