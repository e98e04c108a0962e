"""Median and mean filters (Söderström section 9.7): against brute force, the step response of
(9.107), the frequency response of the mean filter (9.111), NaN windows and bad input."""

import numpy as np
import pytest
from scipy.signal import medfilt

import kfast
from kfast.reference import mean_filter, median_filter


@pytest.mark.parametrize("n", [1, 3, 5, 9, 31])
@pytest.mark.parametrize("mode", ["valid", "grow"])
def test_equal_brute_force_on_random_data(n, mode):
    rng = np.random.default_rng(n)
    u = rng.standard_normal((300, 3)) * [1.0, 1e6, 1e-6]
    u[::7, 1] = 2.5  # repeated values
    np.testing.assert_array_equal(kfast.median_filter(u, n, mode=mode), median_filter(u, n, mode))
    np.testing.assert_allclose(kfast.mean_filter(u, n, mode=mode), mean_filter(u, n, mode), rtol=1e-12, atol=1e-300)
    one = u[:, 0]
    got = kfast.median_filter(one, n, mode=mode)
    assert got.shape == (300,)
    np.testing.assert_array_equal(got, median_filter(one, n, mode))


def test_causal_median_is_scipys_centred_median_shifted():
    u = np.random.default_rng(1).standard_normal(200)
    n, m = 7, 3
    # scipy.signal.medfilt is centred and zero-padded: away from the edges it is ours, m later
    np.testing.assert_array_equal(kfast.median_filter(u, n)[n - 1:], medfilt(u, n)[m:-m])


def test_the_step_is_kept_with_a_lag_of_m_and_the_mean_ramps():
    u = np.r_[np.zeros(20), np.ones(20)]
    for n in (3, 5, 11):
        m = (n - 1) // 2
        y = kfast.median_filter(u, n, mode="grow")
        # (9.107): the output jumps from 0 to 1 at once, m samples after the input
        assert np.all(y[: 20 + m] == 0) and np.all(y[20 + m:] == 1)
        ramp = kfast.mean_filter(u, n)[20: 20 + n]
        np.testing.assert_allclose(ramp, np.arange(1, n + 1) / n, rtol=1e-15)


def test_mean_filter_frequency_response():
    # (9.111): a cosine through the mean filter has gain |sin(w n/2) / (n sin(w/2))|
    n, w = 9, 0.3
    t = np.arange(400)
    y = kfast.mean_filter(np.cos(w * t), n)
    gain = abs(np.sin(w * n / 2) / (n * np.sin(w / 2)))
    np.testing.assert_allclose(y[n:], gain * np.cos(w * (t[n:] - (n - 1) / 2)), atol=1e-12)


def test_windows_with_nan_give_nan_and_the_rest_is_exact():
    u = np.arange(30.0)
    u[10] = np.nan
    y = kfast.median_filter(u, 5)
    assert np.all(np.isnan(y[:4])) and np.all(np.isnan(y[10:15]))
    np.testing.assert_array_equal(y[4:10], np.arange(4, 10) - 2.0)
    np.testing.assert_array_equal(y[15:], np.arange(15, 30) - 2.0)
    np.testing.assert_array_equal(np.isnan(kfast.mean_filter(u, 5)), np.isnan(y))
    before = u.copy()
    kfast.median_filter(u, 3)
    np.testing.assert_array_equal(u, before)


def test_bad_input_is_refused():
    for n in (0, 2, -1, 1.5, True, 10**19):
        with pytest.raises(ValueError, match="n"):
            kfast.median_filter(np.ones(5), n)
    with pytest.raises(ValueError, match="mode"):
        kfast.mean_filter(np.ones(5), 3, mode="same")
    with pytest.raises(ValueError, match="u"):
        kfast.median_filter(np.ones((2, 2, 2)), 3)
    with pytest.raises(ValueError, match="u"):
        kfast.median_filter([1.0, np.inf], 3)
    assert kfast.median_filter(np.ones((0, 2)), 3).shape == (0, 2)


@pytest.mark.parametrize("which", ["min", "max", "median"])
@pytest.mark.parametrize("n", [0, 1, 3])
def test_order_statistic_densities_integrate_to_one_and_match_monte_carlo(which, n):
    from scipy import stats
    from scipy.integrate import quad

    dist = stats.gumbel_r(loc=0.5, scale=2.0)  # skewed, so min, max and median differ

    def density(z):
        return kfast.order_statistic_pdf(z, dist.pdf, dist.cdf, n, which=which)

    assert quad(lambda z: density(np.array([z]))[0], -30, 60, limit=200)[0] == pytest.approx(1.0, abs=1e-8)
    # a seeded Monte-Carlo histogram of the statistic of 2n + 1 draws
    draws = dist.rvs(size=(200_000, 2 * n + 1), random_state=np.random.default_rng(5))
    sample = {"min": draws.min(axis=1), "max": draws.max(axis=1), "median": np.median(draws, axis=1)}[which]
    edges = np.linspace(*np.quantile(sample, [0.01, 0.99]), 21)
    counts, _ = np.histogram(sample, bins=edges)
    expected = np.array([quad(lambda z: density(np.array([z]))[0], a, b)[0] for a, b in zip(edges[:-1], edges[1:])]) * len(sample)
    # Pearson's statistic on 20 bins: far below its 0.999 quantile (about 45) for a right density
    assert np.sum((counts - expected) ** 2 / expected) < 45


def test_order_statistic_special_cases_and_bad_input():
    from scipy import stats

    z = np.linspace(-3, 3, 7)
    np.testing.assert_allclose(kfast.order_statistic_pdf(z, stats.norm.pdf, stats.norm.cdf, 0), stats.norm.pdf(z), rtol=1e-14)
    # the maximum of 3 uniforms has density 3 z^2 on (0, 1)
    u = np.linspace(0.05, 0.95, 5)
    np.testing.assert_allclose(kfast.order_statistic_pdf(u, stats.uniform.pdf, stats.uniform.cdf, 1, "max"), 3 * u**2, rtol=1e-14)
    assert kfast.order_statistic_pdf(np.array([-40.0]), stats.norm.pdf, stats.norm.cdf, 3)[0] == 0.0
    with pytest.raises(ValueError, match="which"):
        kfast.order_statistic_pdf(z, stats.norm.pdf, stats.norm.cdf, 1, which="mode")
    with pytest.raises(ValueError, match="n"):
        kfast.order_statistic_pdf(z, stats.norm.pdf, stats.norm.cdf, -1)
    with pytest.raises(ValueError, match="cdf"):
        kfast.order_statistic_pdf(z, stats.norm.pdf, lambda z: 2 * stats.norm.cdf(z), 1)
    with pytest.raises(ValueError, match="pdf"):
        kfast.order_statistic_pdf(z, lambda z: np.ones(3), stats.norm.cdf, 1)
