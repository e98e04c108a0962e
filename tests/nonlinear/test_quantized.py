"""Quantized measurements (Söderström section 9.6): the quantizer (9.101), Sheppard's correction,
the exact moments by the characteristic-function series against the direct sum over cells, and
the quantized Gaussian likelihood against mpmath."""

import mpmath
import numpy as np
import pytest

import kfast
from kfast.reference.quantized import moments_by_series, moments_over_cells, quantized_loglik, quantize


def test_quantize_rounds_half_up_not_to_even():
    x = np.array([-2.5, -1.5, -0.5, 0.5, 1.5, 2.5, 0.49, -0.51, np.nan])
    q = kfast.quantize(x, 1.0)
    np.testing.assert_array_equal(q[:-1], [-2.0, -1.0, 0.0, 1.0, 2.0, 3.0, 0.0, -1.0])
    assert np.isnan(q[-1])
    assert not np.array_equal(q[:6], np.round(x[:6]))  # NumPy rounds the ties to even
    np.testing.assert_array_equal(q, quantize(x, 1.0))


def test_quantize_per_component_steps_and_leaves_the_input():
    rng = np.random.default_rng(0)
    x = rng.normal(scale=3.0, size=(50, 2))
    before = x.copy()
    q = kfast.quantize(x, [0.25, 2.0])
    np.testing.assert_array_equal(x, before)
    np.testing.assert_array_equal(q, np.column_stack([quantize(x[:, 0], 0.25), quantize(x[:, 1], 2.0)]))
    assert np.all(np.abs(q - x) <= np.array([0.125, 1.0]))
    assert kfast.quantize(0.74, 0.5) == 0.5 and kfast.quantize(0.75, 0.5) == 1.0


@pytest.mark.parametrize(
    "x, delta, arg",
    [(1.0, 0.0, "delta"), (1.0, -1.0, "delta"), (1.0, np.nan, "delta"), (np.ones((3, 2)), [1.0, 2.0, 3.0], "x"),
     (1e300, 1e-300, "x")],
)
def test_quantize_bad_input_is_named(x, delta, arg):
    with pytest.raises(ValueError, match=arg):
        kfast.quantize(x, delta)


def test_sheppard_adds_the_uniform_variance():
    R = np.array([[1.0, 0.2], [0.2, 0.5]])
    out = kfast.sheppard(R, [0.6, 0.0])
    np.testing.assert_allclose(out, R + np.diag([0.03, 0.0]), rtol=0, atol=1e-16)
    assert R[0, 0] == 1.0
    assert kfast.sheppard(2.0, 1.0).shape == (1, 1)
    with pytest.raises(ValueError, match="delta"):
        kfast.sheppard(R, [0.5, -0.1])


def test_sheppard_makes_the_kalman_filter_consistent_on_quantized_data():
    """A random walk seen through a coarse quantizer (delta^2/12 = 2 R): with Sheppard's R the
    normalized innovations have variance 1; with the plain R they are too large."""
    rng = np.random.default_rng(1)
    T, delta, R = 20_000, 1.0, 0.04
    x = np.cumsum(rng.normal(size=T))
    y = kfast.quantize(x + np.sqrt(R) * rng.normal(size=T), delta)
    ratios = []
    for r_model in (kfast.sheppard(R, delta), R):
        res = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=r_model).filter(y, 0.0, 10.0)
        ratios.append(np.mean(res.innov[100:, 0] ** 2 / res.S[100:, 0, 0]))
    assert abs(ratios[0] - 1.0) < 0.03, ratios
    assert ratios[1] > 1.05, ratios


MOMENT_CASES = [(m, s) for m in (0.0, 0.13, 0.5, -0.37, 7.25, -1234.6) for s in (1e-7, 0.01, 0.1, 0.2, 0.3, 0.5, 1.0, 3.0)]


@pytest.mark.parametrize("distribution", ["gaussian", "uniform"])
@pytest.mark.parametrize("mean, std", MOMENT_CASES)
def test_moments_equal_the_sum_over_cells(distribution, mean, std):
    delta = 0.8
    got = kfast.quantized_moments(delta, mean * delta, std * delta, distribution)
    first, second, var = moments_over_cells(delta, mean * delta, std * delta, distribution)
    assert got.mean == pytest.approx(first, rel=1e-13, abs=1e-13 * delta)
    assert got.var == pytest.approx(var, rel=1e-9, abs=1e-11 * delta**2)
    assert got.second_moment == pytest.approx(second, rel=1e-12, abs=1e-12 * delta**2)


@pytest.mark.parametrize("mean, std", [(0.0, 0.2), (0.3, 0.25), (-0.2, 0.4)])
def test_gaussian_moments_are_the_books_series(mean, std):
    got = kfast.quantized_moments(1.0, mean, std)
    first, second = moments_by_series(1.0, mean, std, "gaussian", K=50)
    assert (got.mean, got.second_moment) == pytest.approx((first, second), abs=1e-14)


def test_uniform_series_converges_to_the_closed_form_and_needs_every_k():
    """The uniform's terms fall as 1/k^2: the partial sums approach the closed form at the
    rate 1/K; summing k > 0 only, as (9.131) is printed, misses half of the correction."""
    mean, std = 0.3, 0.35
    got = kfast.quantized_moments(1.0, mean, std, "uniform")
    errors = [abs(moments_by_series(1.0, mean, std, "uniform", K=K)[1] - got.second_moment) for K in (100, 1000, 10_000)]
    assert errors[2] < 1e-4 and errors[2] < errors[1] < errors[0]
    half = moments_by_series(1.0, mean, std, "uniform", K=10_000, positive_k_only=True)[1]
    assert abs(half - got.second_moment) > 100 * errors[2]


def test_sheppard_is_exact_for_a_wide_gaussian_and_not_for_a_narrow_one():
    wide = kfast.quantized_moments(1.0, 0.3, 1.5)  # the terms ~ exp(-2 pi^2 std^2/delta^2) < 1e-19
    assert wide.var == pytest.approx(wide.sheppard_var, rel=1e-15)
    assert 1e-10 < abs(kfast.quantized_moments(1.0, 0.3, 1.0).var - 13 / 12) < 1e-7
    narrow = kfast.quantized_moments(1.0, 0.3, 0.2)
    assert abs(narrow.var - narrow.sheppard_var) > 1e-2
    # a cell-wide uniform centred on a level quantizes to that level; off centre it splits
    assert kfast.quantized_moments(2.0, 4.0, 2.0 / np.sqrt(12), "uniform").var == pytest.approx(0.0, abs=1e-14)
    split = kfast.quantized_moments(2.0, 5.0, 2.0 / np.sqrt(12), "uniform")
    assert (split.mean, split.var) == pytest.approx((5.0, 1.0), abs=1e-13)


def test_a_variable_without_spread_is_its_level():
    got = kfast.quantized_moments(0.5, 1.25, 0.0)
    assert (got.mean, got.var, got.second_moment) == (1.5, 0.0, 2.25)


@pytest.mark.parametrize("change, arg", [(dict(delta=0.0), "delta"), (dict(std=-1.0), "std"), (dict(mean=np.inf), "mean"),
                                         (dict(distribution="cauchy"), "distribution"), (dict(mean=1e300, delta=1e-300), "mean")])
def test_moments_bad_input_is_named(change, arg):
    kw = dict(delta=1.0, mean=0.0, std=1.0, distribution="gaussian") | change
    with pytest.raises(ValueError, match=arg):
        kfast.quantized_moments(**kw)


def _exact_log_cell(y, y_hat, std, delta):
    mpmath.mp.dps = 50
    lo, hi = (mpmath.mpf(y) - mpmath.mpf(delta) / 2 - y_hat) / std, (mpmath.mpf(y) + mpmath.mpf(delta) / 2 - y_hat) / std
    if lo > 0:  # the upper tail mirrored, so that 50 digits hold it
        lo, hi = -hi, -lo
    return float(mpmath.log(mpmath.ncdf(hi) - mpmath.ncdf(lo)))


@pytest.mark.parametrize(
    "y, y_hat, std, delta",
    [(1.0, 0.9, 0.3, 0.5), (1.0, 1.25, 0.3, 0.5), (0.0, 0.0, 1.0, 1e-7), (3.0, 0.0, 0.1, 1.0), (-3.0, 0.0, 0.1, 1.0),
     (50.0, 0.0, 1.0, 1.0), (2.0, 1.0, 1e-3, 1.0), (1e3, 0.0, 1.0, 2.0), (7.5, 1.0, 2.0, 0.5), (1.0, 40.0, 1.0, 1e-4)],
)
def test_loglik_matches_mpmath_in_the_tails_and_narrow_cells(y, y_hat, std, delta):
    got = kfast.quantized_loglik(y, [y_hat], std**2, delta)[0]
    assert got == pytest.approx(_exact_log_cell(y, y_hat, std, delta), rel=1e-12)


def test_loglik_sums_components_and_skips_missing_ones():
    rng = np.random.default_rng(2)
    y_hat = rng.normal(size=(200, 2))
    y, R, delta = np.array([0.5, -1.0]), np.diag([0.3, 0.6]), np.array([0.5, 1.0])
    got = kfast.quantized_loglik(y, y_hat, R, delta)
    np.testing.assert_allclose(got, quantized_loglik(y, y_hat, np.sqrt(np.diag(R)), delta), rtol=1e-12)
    missing = kfast.quantized_loglik([np.nan, -1.0], y_hat, R, delta)
    np.testing.assert_allclose(missing, quantized_loglik([np.nan, -1.0], y_hat, np.sqrt(np.diag(R)), delta), rtol=1e-12)


def test_loglik_saturating_ends_and_noise_free_cells():
    y_hat = np.array([[-10.0], [-2.1], [0.0], [10.0]])
    low = kfast.quantized_loglik(-2.0, y_hat, 0.25, 1.0, bounds=(-2.0, 2.0))
    assert low[0] == pytest.approx(0.0, abs=1e-15)  # far below the lowest level: certain
    assert low[3] == -np.inf or low[3] < -100
    high = kfast.quantized_loglik(2.0, y_hat, 0.25, 1.0, bounds=(-2.0, 2.0))
    assert high[3] == pytest.approx(0.0, abs=1e-15)
    indicator = kfast.quantized_loglik(0.0, [[-0.5], [0.0], [0.49], [0.5]], 0.0, 1.0)
    np.testing.assert_array_equal(indicator, [0.0, 0.0, 0.0, -np.inf])


@pytest.mark.parametrize(
    "kw, arg",
    [(dict(y=0.3), "y"), (dict(y=np.inf), "y"), (dict(R=-1.0), "R"), (dict(R=[[1.0, 0.1], [0.1, 1.0]]), "R"),
     (dict(y_hat=[[np.nan]]), "y_hat"), (dict(delta=0.0), "delta"), (dict(y_hat=np.ones((3, 2))), "y_hat"),
     (dict(bounds=(1.0, -1.0)), "bounds"), (dict(y=5.0, bounds=(-1.0, 1.0)), "y")],
)
def test_loglik_bad_input_is_named(kw, arg):
    args = dict(y=0.5, y_hat=[[0.4]], R=1.0, delta=0.5) | kw
    with pytest.raises(ValueError, match=arg):
        kfast.quantized_loglik(**args)


def _random_walk(seed, T=40, q=0.1, r=0.01, delta=1.0):
    rng = np.random.default_rng(seed)
    x = np.cumsum(np.sqrt(q) * rng.normal(size=T))
    return x, kfast.quantize(x + np.sqrt(r) * rng.normal(size=T), delta)


def test_particle_filter_with_the_quantized_likelihood_equals_the_reference():
    from kfast.reference.particle import particle_filter

    f, h = (lambda X, t, u: X), (lambda X, t, u: X)
    model = kfast.NonlinearModel(f, h, Q=0.1, R=0.04, n=1)
    _, y = _random_walk(3, r=0.04)
    y[[5, 17]] = np.nan
    res = model.particle_filter(y, 0.0, 1.0, n_particles=2000, resample="systematic", ess_threshold=0.5, seed=4,
                                likelihood=kfast.Quantized(1.0))
    ref = particle_filter(f, h, np.array([[0.1]]), np.array([[0.04]]), y, np.array([0.0]), np.array([[1.0]]), 2000,
                          "systematic", 0.5, seed=4, quantized=np.array([1.0]))
    np.testing.assert_allclose(res.x_filt, ref["x_filt"], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(res.loglik_t, ref["loglik_t"], rtol=1e-9, atol=1e-12)
    streaming = kfast.ParticleFilter(model, 0.0, 1.0, n_particles=2000, resample="systematic", ess_threshold=0.5, seed=4,
                                     likelihood=kfast.Quantized(1.0))
    for t, value in enumerate(y):
        assert streaming.update([value]) == res.loglik_t[t]
        np.testing.assert_array_equal(streaming.x, res.x_filt[t])
        streaming.predict()


def test_the_exact_likelihood_tracks_a_coarsely_quantized_signal_better_than_sheppard():
    """A slow random walk (q = 0.01) seen through a quantizer of step 1 with little noise
    (r = 0.0025): the state sits inside a cell for many steps, where the posterior is far from
    Gaussian. The particle filter with the cell probabilities beats the Kalman filter with
    Sheppard's R over 20 seeds (mean squared errors 0.036 and 0.046 when this was written; the
    advantage fades as q grows against delta^2/12)."""
    model = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X, Q=0.01, R=0.0025, n=1)
    kf = kfast.LinearGaussian(F=1.0, H=1.0, Q=0.01, R=kfast.sheppard(0.0025, 1.0))
    err_pf, err_kf = [], []
    for seed in range(20):
        x, y = _random_walk(seed, T=100, q=0.01, r=0.0025)
        pf = model.particle_filter(y, 0.0, 0.1, n_particles=2000, resample="systematic", seed=seed,
                                   likelihood=kfast.Quantized(1.0))
        err_pf.append(np.mean((pf.x_filt[:, 0] - x) ** 2))
        err_kf.append(np.mean((kf.filter(y, 0.0, 0.1).x_filt[:, 0] - x) ** 2))
    assert np.mean(err_pf) < 0.85 * np.mean(err_kf), (np.mean(err_pf), np.mean(err_kf))


@pytest.mark.parametrize(
    "likelihood, y, R, arg",
    [(kfast.Quantized([1.0, 1.0]), [1.0], 0.04, "delta"), ("gaussian", [1.0], 0.04, "likelihood"),
     (kfast.Quantized(1.0), [0.3], 0.04, "y"), (kfast.Quantized(0.0), [1.0], 0.04, "delta")],
)
def test_particle_filter_quantized_bad_input_is_named(likelihood, y, R, arg):
    model = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X, Q=0.1, R=R, n=1)
    with pytest.raises(ValueError, match=arg):
        model.particle_filter(np.array(y), 0.0, 1.0, n_particles=10, likelihood=likelihood)


def test_particle_filter_quantized_needs_a_diagonal_R():
    model = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X[:, [0, 0]], Q=0.1, R=[[0.1, 0.05], [0.05, 0.1]], n=1)
    with pytest.raises(ValueError, match="R at step 0.*diagonal"):
        model.particle_filter(np.array([[1.0, 1.0]]), 0.0, 1.0, n_particles=10, likelihood=kfast.Quantized(1.0))


def test_a_quantized_angle_is_compared_within_a_turn():
    """An angle near pi whose h wraps to (-pi, pi]: the likelihood moves h(x) by whole turns to
    y's cell, so the filter equals that of the unwrapped h."""
    wrapped = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: np.angle(np.exp(1j * X)), Q=1e-4, R=1e-4, n=1, angles=[0])
    plain = kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X, Q=1e-4, R=1e-4, n=1)
    y = kfast.quantize(np.array([3.13, 3.12, 3.14, 3.15]), 0.05)
    runs = [m.particle_filter(y, 3.12, 1e-3, n_particles=500, seed=7, likelihood=kfast.Quantized(0.05)) for m in (wrapped, plain)]
    np.testing.assert_allclose(runs[0].x_filt, runs[1].x_filt, rtol=1e-12)
    np.testing.assert_allclose(runs[0].loglik_t, runs[1].loglik_t, rtol=1e-9)


def test_the_second_moment_in_the_issues_form():
    """kfast.quantized_second_moment(delta, dist="normal", std=) or dist="uniform", low=, high="""
    delta = 0.5
    normal = kfast.quantized_second_moment(delta, "normal", std=0.2, mean=0.1)
    assert normal == pytest.approx(moments_over_cells(delta, 0.1, 0.2, "gaussian")[1], rel=1e-12)
    uniform = kfast.quantized_second_moment(delta, "uniform", low=-0.3, high=0.9)
    assert uniform == pytest.approx(moments_over_cells(delta, 0.3, 1.2 / np.sqrt(12), "uniform")[1], rel=1e-12)
    for kw, arg in [(dict(dist="normal"), "std"), (dict(dist="uniform", low=1.0, high=0.0), "low"),
                    (dict(dist="cauchy", std=1.0), "dist"), (dict(dist="uniform", std=1.0), "low")]:
        with pytest.raises(ValueError, match=arg):
            kfast.quantized_second_moment(delta, **kw)
