"""filter_batch: every series equals filtering it alone, bit for bit, on the shared-covariance
path and the per-series path, with any thread count."""

import numpy as np
import pytest

import kfast
from modelgen import random_case


def batch_case(seed, B=7, T=30, inputs=False, correlated=False, time_varying=False):
    case = random_case(seed, n=1 + seed % 5, m=1 + seed % 3, T=T, inputs=inputs, correlated=correlated, time_varying=time_varying)
    model = kfast.LinearGaussian(**case.model)
    rng = np.random.default_rng(seed)
    Y = case.y[None] + rng.standard_normal((B, T, model.n_obs))
    return case, model, Y


def each(model, Y, x0, P0, u=None):
    out = []
    for b in range(len(Y)):
        xb = x0 if np.ndim(x0) == 1 else x0[b]
        Pb = P0 if np.ndim(P0) == 2 else P0[b]
        ub = None if u is None else (u if u.ndim == 2 else u[b])
        out.append(model.filter(Y[b], xb, Pb, u=ub))
    return out


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("threads", [None, 1, 3])
def test_shared_covariance_path_equals_single_series(seed, threads):
    case, model, Y = batch_case(seed, inputs=bool(seed % 2), correlated=bool(seed % 3 == 0), time_varying=bool(seed % 4 == 1))
    u = case.u
    res = kfast.filter_batch(model, Y, case.x0, case.P0, u=u, threads=threads, form=("joseph", "standard")[seed % 2])
    assert res.shared_covariance
    singles = each(model, Y, case.x0, case.P0, u)
    forms = [model.filter(Y[b], case.x0, case.P0, u=u, form=("joseph", "standard")[seed % 2]) for b in range(len(Y))]
    for b, single in enumerate(forms):
        np.testing.assert_array_equal(res.x_filt[b], single.x_filt)
        np.testing.assert_array_equal(res.P_filt[b], single.P_filt)
        assert res.loglik[b] == single.loglik
    assert len(singles) == len(Y)
    assert not res.P_filt.flags.writeable  # a broadcast view of the shared covariances


@pytest.mark.parametrize("seed", range(10))
def test_per_series_path_with_missing_data_and_priors(seed):
    case, model, Y = batch_case(100 + seed, inputs=bool(seed % 2))
    rng = np.random.default_rng(seed)
    Y[rng.random(Y.shape) < 0.2] = np.nan
    B, n = len(Y), model.n_states
    x0 = case.x0 + rng.standard_normal((B, n))
    P0 = np.stack([case.P0 * (1 + b) for b in range(B)])
    u = None if case.u is None else case.u[None] + rng.standard_normal((B,) + case.u.shape)
    res = kfast.filter_batch(model, Y, x0, P0, u=u)
    assert not res.shared_covariance
    for b, single in enumerate(each(model, Y, x0, P0, u)):
        np.testing.assert_array_equal(res.x_filt[b], single.x_filt)
        np.testing.assert_array_equal(res.P_filt[b], single.P_filt)
        assert res.loglik[b] == single.loglik


def test_without_covariances_and_the_cv_workload_shape():
    model = kfast.models.constant_velocity(2, 0.1)
    Y = np.random.default_rng(1).standard_normal((50, 40, 2))
    x0, P0 = np.array([1.0, -1.0, 0.5, 0.2]), np.diag([10.0, 10.0, 1.0, 1.0])
    res = kfast.filter_batch(model, Y, x0, P0, return_covs=False)
    assert res.P_filt is None and res.x_filt.shape == (50, 40, 4) and res.loglik.shape == (50,)
    np.testing.assert_array_equal(res.x_filt[49], model.filter(Y[49], x0, P0).x_filt)


def test_batch_bad_input():
    model = kfast.models.constant_velocity(2, 0.1)
    x0, P0 = np.zeros(4), np.eye(4)
    with pytest.raises(kfast.KfastError, match=r"^Y: expected a 3-D array"):
        kfast.filter_batch(model, np.zeros((5, 2)), x0, P0)
    with pytest.raises(kfast.KfastError, match=r"^Y: expected shape \(B, T, 2\)"):
        kfast.filter_batch(model, np.zeros((5, 3, 3)), x0, P0)
    with pytest.raises(kfast.KfastError, match=r"^x0: expected shape \(4,\) \(shared\) or \(5, 4\)"):
        kfast.filter_batch(model, np.zeros((5, 3, 2)), np.zeros((4, 4)), P0)
    with pytest.raises(kfast.KfastError, match=r"^Y at step 1: \(series 2\) component 0 is inf"):
        Y = np.zeros((5, 3, 2))
        Y[2, 1, 0] = np.inf
        kfast.filter_batch(model, Y, x0, P0)
    with pytest.raises(kfast.KfastError, match=r"^threads: must be >= 1"):
        kfast.filter_batch(model, np.zeros((5, 3, 2)), x0, P0, threads=0)
    with pytest.raises(kfast.KfastError, match=r"^P0: \(series 0\) not positive semidefinite"):
        kfast.filter_batch(model, np.zeros((5, 3, 2)), x0, -np.eye(4))


def test_scalar_model_accepts_scalars_and_2d_y():
    model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
    Y = np.random.default_rng(2).standard_normal((3, 6))
    res = kfast.filter_batch(model, Y, 0.0, 1.0)
    np.testing.assert_array_equal(res.x_filt[1], model.filter(Y[1], 0.0, 1.0).x_filt)
