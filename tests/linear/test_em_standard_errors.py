"""EMResult.standard_errors(): the observed-information standard errors at EM's optimum equal
those of maximum likelihood by kfast.fit (same likelihood, same optimum), for full and
symmetric matrices, and are refused clearly without data."""

from __future__ import annotations

import numpy as np
import pytest

import kfast


def test_equal_the_standard_errors_of_direct_maximum_likelihood():
    model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.5, R=1.0)
    _, y = model.simulate(400, x0=0.0, P0=1.0, seed=2)
    res = model.em(y, x0=0.0, P0=1.0, n_iter=500, fit=("F", "Q", "R"), tol=1e-12)
    se = res.standard_errors()

    def build(t):
        return kfast.LinearGaussian(F=t[0], H=1.0, Q=t[1], R=t[2]), 0.0, 1.0

    mle = kfast.fit(build, [0.8, 0.5, 1.0], y, bounds=[(-0.99, 0.99), (1e-3, 5), (1e-3, 5)])
    np.testing.assert_allclose([res.model.F[0, 0], res.model.Q[0, 0], res.model.R[0, 0]], mle.theta, rtol=2e-3)
    np.testing.assert_allclose([se["F"][0, 0], se["Q"][0, 0], se["R"][0, 0]], mle.se, rtol=1e-2)


def test_symmetric_matrices_get_symmetric_standard_errors():
    F = np.array([[0.7, 0.2], [0.0, 0.5]])
    model = kfast.LinearGaussian(F, np.eye(2), np.array([[0.5, 0.1], [0.1, 0.3]]), 0.4 * np.eye(2))
    _, y = model.simulate(600, x0=np.zeros(2), P0=np.eye(2), seed=4)
    res = model.em(y, x0=np.zeros(2), P0=np.eye(2), n_iter=300, fit=("F", "Q"), tol=1e-12)
    se = res.standard_errors()
    assert se["F"].shape == (2, 2) and se["Q"].shape == (2, 2)
    assert np.array_equal(se["Q"], se["Q"].T)
    assert np.all(np.isfinite(se["F"])) and np.all(se["F"] > 0)
    # The truth lies within 4 standard errors of every estimate.
    assert np.all(np.abs(res.model.F - F) < 4 * se["F"])


def test_nothing_fitted_and_no_data():
    model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.5, R=1.0)
    res = model.em(np.ones(5), x0=0.0, P0=1.0, n_iter=1, fit=())
    assert res.standard_errors() == {}
    bare = kfast.linear.estimation.EMResult(model, np.zeros(1), np.ones((1, 1)), np.zeros(1), 0, False, ("F",))
    with pytest.raises(ValueError, match="standard_errors: this EMResult does not carry its data"):
        bare.standard_errors()
