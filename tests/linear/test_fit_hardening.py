"""Hardening of ``kfast.fit`` (issue #10): a clear ``KfastError`` naming the argument for a
``build`` that is not callable or gives an invalid prior, a ``theta0`` that is not a non-empty
finite 1-D array, and observations too large for the log-likelihood; valid fits unchanged."""

import re
import warnings

import numpy as np
import pytest

import kfast

Y = np.sin(np.arange(6.0))


def white_noise(theta):
    return kfast.LinearGaussian(F=0.8, H=1.0, Q=np.exp(np.sum(theta)), R=1.0), 0.0, 1.0


def assert_names(exc_info, name):
    head = str(exc_info.value).split(": ", 1)[0]
    assert re.search(rf"(?<!\w){re.escape(name)}(?!\w)", head), str(exc_info.value)


@pytest.mark.parametrize("build", [None, 5, "white_noise"])
def test_build_must_be_callable(build):
    with pytest.raises(kfast.KfastError) as exc_info:
        kfast.fit(build, [0.0], Y)
    assert_names(exc_info, "build")


@pytest.mark.parametrize(
    "prior",
    [([np.nan], 1.0), (0.0, np.nan), (0.0, np.inf), ([0.0, 0.0], 1.0), (0.0, -1.0)],
    ids=["x0-nan", "P0-nan", "P0-inf", "x0-size", "P0-negative"],
)
def test_an_invalid_prior_from_build_names_build(prior):
    def build(theta):
        return (kfast.LinearGaussian(F=0.8, H=1.0, Q=np.exp(theta[0]), R=1.0), *prior)

    with pytest.raises(kfast.KfastError) as exc_info:
        kfast.fit(build, [0.0], Y)
    assert_names(exc_info, "build")
    assert "theta0" in str(exc_info.value)


@pytest.mark.parametrize("theta0", [np.zeros(0), np.zeros((1, 2)), np.zeros((2, 1)), [np.nan], [0.0, np.inf], "0", None])
def test_theta0_must_be_a_non_empty_finite_vector(theta0):
    with pytest.raises(kfast.KfastError) as exc_info:
        kfast.fit(white_noise, theta0, Y)
    assert_names(exc_info, "theta0")


def test_a_scalar_theta0_is_one_parameter():
    np.testing.assert_array_equal(kfast.fit(white_noise, 0.3, Y).theta, kfast.fit(white_noise, [0.3], Y).theta)


@pytest.mark.parametrize("big", [1e155, -1e155, 1e300, -1e300])
def test_observations_too_large_for_the_loglik_name_y(big):
    y = Y.copy()
    y[2] = big
    with pytest.raises(kfast.KfastError) as exc_info:
        kfast.fit(white_noise, [0.0], y)
    assert_names(exc_info, "y")


def test_an_optimizer_that_diverges_is_a_clear_error():
    # y ~ 1e100: the log-likelihood at theta0 is finite (-2.6e199) but its gradient sends
    # L-BFGS-B out of the finite numbers
    y = Y.copy()
    y[2] = 1e100
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with pytest.raises(kfast.KfastError) as exc_info:
            kfast.fit(white_noise, [0.0], y)
    assert_names(exc_info, "build")
    assert "rescale y" in str(exc_info.value)


def test_a_state_that_overflows_at_theta0_names_y_and_the_step():
    def build(theta):
        return kfast.LinearGaussian(F=0.8, H=1.0, Q=0.0, R=1e-300), 0.0, 0.0  # y^2 / R overflows

    with pytest.raises(kfast.KfastError, match=r"at step \d+: the state estimate overflowed") as exc_info:
        kfast.fit(build, [0.0], Y * 1e150)
    assert_names(exc_info, "y")


def test_valid_fit_is_unchanged_and_missing_values_still_work():
    """The MLE of a white-noise variance (F = 0, Q = 0): the mean of y^2 (closed form)."""
    y = np.array([1.0, -2.0, 3.0, 0.5, np.nan, 1.5])

    def build(theta):
        return kfast.LinearGaussian(F=0.0, H=1.0, Q=0.0, R=np.exp(theta[0])), 0.0, 0.0

    res = kfast.fit(build, [0.0], y)
    assert np.exp(res.theta[0]) == pytest.approx(np.nanmean(y**2), rel=1e-5)
