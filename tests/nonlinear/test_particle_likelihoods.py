"""The particle filter's measurement likelihoods (``likelihood=``): Student-t and uniform noise
against the NumPy reference on the same random numbers, and what each is for."""

import numpy as np
import pytest

import kfast
from kfast.reference.particle import particle_filter

F = np.array([[1.0, 1.0], [0.0, 1.0]])
Q = np.diag([0.01, 0.04])
R = np.diag([0.5, 0.8])


def f(X, t, u):
    return X @ F.T


def h(X, t, u):
    return np.column_stack([X[:, 0], X[:, 0] + X[:, 1]])


def data(seed=0, T=25):
    rng = np.random.default_rng(seed)
    x, ys = np.zeros(2), []
    for _ in range(T):
        ys.append(h(x[None], 0, None)[0] + rng.standard_t(4, size=2) * np.sqrt(np.diag(R)))
        x = F @ x + rng.multivariate_normal(np.zeros(2), Q)
    y = np.array(ys)
    y[7, 1] = np.nan
    return y


@pytest.mark.parametrize("likelihood, ref", [(kfast.StudentT(4.0), dict(student_t=4.0)), (kfast.StudentT(0.5), dict(student_t=0.5)),
                                             (kfast.UniformNoise(), dict(uniform=True))])
def test_the_likelihoods_equal_the_reference(likelihood, ref):
    y = data()
    R_model = R * (4.0 if isinstance(likelihood, kfast.UniformNoise) else 1.0)  # a box wide enough for the data
    model = kfast.NonlinearModel(f, h, Q, R_model, n=2)
    res = model.particle_filter(y, np.zeros(2), np.eye(2), n_particles=3000, resample="systematic", ess_threshold=0.5,
                                seed=5, likelihood=likelihood)
    out = particle_filter(f, h, Q, R_model, y, np.zeros(2), np.eye(2), 3000, "systematic", 0.5, seed=5, **ref)
    np.testing.assert_allclose(res.x_filt, out["x_filt"], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(res.loglik_t, out["loglik_t"], rtol=1e-9, atol=1e-10)
    np.testing.assert_array_equal(res.resampled, out["resampled"])


def test_many_degrees_of_freedom_are_the_gaussian():
    y = data(1)
    model = kfast.NonlinearModel(f, h, Q, R, n=2)
    gauss = model.particle_filter(y, np.zeros(2), np.eye(2), n_particles=2000, seed=2)
    student = model.particle_filter(y, np.zeros(2), np.eye(2), n_particles=2000, seed=2, likelihood=kfast.StudentT(1e9))
    np.testing.assert_allclose(student.loglik_t, gauss.loglik_t, rtol=1e-6)
    np.testing.assert_allclose(student.x_filt, gauss.x_filt, rtol=1e-6, atol=1e-6)


def test_student_t_shrugs_off_an_outlier_the_gaussian_follows():
    """A random walk measured with one gross outlier (+20 at step 30): under the Gaussian the
    whole weight falls on the few particles nearest to it (ESS ~ 2 of 5000) and the estimate is
    pulled off; under the Student-t the weights hardly change (ESS ~ 4990)."""
    rng = np.random.default_rng(3)
    T = 40
    x = np.cumsum(0.1 * rng.standard_normal(T))
    y = x + 0.3 * rng.standard_normal(T)
    y[30] += 20.0
    model = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X, Q=0.01, R=0.09, n=1)
    jumps, ess = [], []
    for likelihood in (None, kfast.StudentT(3.0)):
        res = model.particle_filter(y, 0.0, 1.0, n_particles=5000, resample="systematic", seed=1, likelihood=likelihood)
        jumps.append(abs(res.x_filt[30, 0] - x[30]))
        ess.append(res.ess[30])
    assert ess[0] < 50 and ess[1] > 4000, ess
    assert jumps[1] < 0.5 * jumps[0], jumps


@pytest.mark.parametrize(
    "likelihood, R_model, arg",
    [(kfast.UniformNoise(), [[0.5, 0.1], [0.1, 0.8]], "R at step 0"), (kfast.UniformNoise(), np.diag([1e-8, 1e-8]), "y at step 0"),
     (kfast.UniformNoise(), np.diag([0.0, 0.5]), "R at step 0")],
)
def test_uniform_noise_bad_input_is_named(likelihood, R_model, arg):
    model = kfast.NonlinearModel(f, h, Q, R_model, n=2)
    with pytest.raises(ValueError, match=arg):
        model.particle_filter(np.array([[3.0, 3.0]]), np.zeros(2), np.eye(2) * 1e-6, n_particles=50, likelihood=likelihood)


@pytest.mark.parametrize("nu", [0.0, -1.0, np.nan, np.inf, True])
def test_student_t_needs_positive_degrees_of_freedom(nu):
    with pytest.raises(ValueError, match="nu"):
        kfast.StudentT(nu)


@pytest.mark.parametrize("c, ess_threshold", [(1.0, None), (0.5, 0.5)])
def test_the_regularized_filter_equals_the_reference(c, ess_threshold):
    y = data(2)
    model = kfast.NonlinearModel(f, h, Q, R, n=2)
    res = model.particle_filter(y, np.zeros(2), np.eye(2), n_particles=3000, resample="stratified", ess_threshold=ess_threshold,
                                seed=9, regularize=c)
    out = particle_filter(f, h, Q, R, y, np.zeros(2), np.eye(2), 3000, "stratified", ess_threshold, seed=9, regularize=c)
    np.testing.assert_allclose(res.x_filt, out["x_filt"], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(res.P_filt, out["P_filt"], rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(res.loglik_t, out["loglik_t"], rtol=1e-9, atol=1e-10)
    plain = model.particle_filter(y, np.zeros(2), np.eye(2), n_particles=3000, resample="stratified", ess_threshold=ess_threshold, seed=9)
    assert not np.allclose(plain.x_filt, res.x_filt, rtol=1e-6)
    streaming = kfast.ParticleFilter(model, np.zeros(2), np.eye(2), n_particles=3000, resample="stratified",
                                     ess_threshold=ess_threshold, seed=9, regularize=c)
    for t, value in enumerate(y[:6]):
        assert streaming.update(value) == res.loglik_t[t]
        streaming.predict()
        if res.resampled[t]:
            break


def test_regularization_keeps_the_copies_apart():
    """Without process noise the resampled copies of a particle stay together: few distinct
    values remain. The kernel jitter keeps every particle distinct."""
    model = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X, Q=0.0, R=0.1, n=1)
    y = np.full(20, 0.3)
    distinct = []
    for regularize in (False, True):
        res = model.particle_filter(y, 0.0, 1.0, n_particles=2000, resample="systematic", seed=0, keep="last", regularize=regularize)
        distinct.append(len(np.unique(res.particles[:, 0])))
    assert distinct[0] < 400 and distinct[1] == 2000, distinct  # 275 of 2000 without, when written


@pytest.mark.parametrize("value", [0.0, -1.0, np.nan, np.inf, "yes"])
def test_regularize_bad_values_are_named(value):
    model = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X, Q=0.1, R=0.1, n=1)
    with pytest.raises(ValueError, match="regularize"):
        model.particle_filter(np.zeros(3), 0.0, 1.0, n_particles=10, regularize=value)
