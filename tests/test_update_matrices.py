"""``KalmanFilter.update(y, H=..., R=...)``: the observation matrix and measurement noise
covariance of one update, as filterpy's ``update(z, R=None, H=None)``. Checked against
filterpy's KalmanFilter given the same per-call H and R, and against kfast's filter with
per-step H and R stacks; invalid H and R get errors naming the argument and the step."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FilterpyKalmanFilter

import kfast
from modelgen import random_spd, random_transition


def per_step_case(seed, n=3, m=2, T=30, correlated=False, inputs=False, missing=False):
    """Constant F (and B, D) with per-step H[t], Q[t], R[t] (N[t]); data from the model."""
    rng = np.random.default_rng(seed)
    F = random_transition(rng, n, 0.9)
    J = np.stack([random_spd(rng, n + m) for _ in range(T)])
    mats = dict(F=F, H=rng.standard_normal((T, m, n)), Q=J[:, :n, :n].copy(), R=J[:, n:, n:].copy())
    if correlated:
        mats["N"] = J[:, :n, n:].copy()
    u = None
    if inputs:
        mats["B"], mats["D"] = rng.standard_normal((n, 2)), rng.standard_normal((m, 2))
        u = rng.standard_normal((T, 2))
    y = rng.standard_normal((T, m)) * 2
    if missing:
        y[rng.random((T, m)) < 0.2] = np.nan
        y[5] = np.nan
    return mats, y, u, rng.standard_normal(n), random_spd(rng, n, jitter=0.5)


def streaming_model(mats):
    """The same model with one constant H and R that every update replaces (R large enough
    that [[Q, N], [N', R]] stays positive semidefinite at every step)."""
    m, n = mats["H"].shape[1:]
    other = dict(mats, H=np.ones((m, n)), R=100.0 * np.eye(m))
    return kfast.LinearGaussian(**other)


def run_stream(kf, mats, y, u, override=lambda t: True):
    """update with the step's H and R (where ``override``), then predict; records x, P after
    each operation and the log-likelihood."""
    seen = []
    for t in range(len(y)):
        u_t = None if u is None else u[t]
        extra = dict(H=mats["H"][t], R=mats["R"][t]) if override(t) else {}
        kf.update(y[t], u=u_t, **extra)
        seen.append((kf.x, kf.P))
        kf.predict(u=u_t)
        seen.append((kf.x, kf.P))
    return seen, kf.loglik


CASES = {
    "plain": {},
    "correlated-inputs": dict(correlated=True, inputs=True),
    "missing": dict(missing=True),
    "scalar": dict(n=1, m=1),
}


@pytest.mark.parametrize("form", ["joseph", "standard"])
@pytest.mark.parametrize("name", CASES)
def test_per_call_matrices_equal_the_per_step_model(name, form):
    mats, y, u, x0, P0 = per_step_case(11, **CASES[name])
    expected = kfast.LinearGaussian(**mats).filter(y, x0, P0, u=u, form=form)
    seen, loglik = run_stream(kfast.KalmanFilter(streaming_model(mats), x0, P0, form=form), mats, y, u)
    T = len(y)
    np.testing.assert_array_equal(np.array([s[0] for s in seen[0::2]]), expected.x_filt)
    np.testing.assert_array_equal(np.array([s[1] for s in seen[0::2]]), expected.P_filt)
    np.testing.assert_array_equal(np.array([s[0] for s in seen[1::2]])[: T - 1], expected.x_pred[1:])
    np.testing.assert_array_equal(np.array([s[1] for s in seen[1::2]])[: T - 1], expected.P_pred[1:])
    assert loglik == expected.loglik


def test_nearly_symmetric_R_is_symmetrized_as_the_models():
    """An R asymmetric within rounding (1e-13 relative) is used symmetrized, as the model's."""
    mats, y, u, x0, P0 = per_step_case(18)
    rng = np.random.default_rng(18)
    mats["R"] = mats["R"] * (1 + 1e-13 * rng.standard_normal(mats["R"].shape))
    assert not np.array_equal(mats["R"], np.swapaxes(mats["R"], 1, 2))
    expected = kfast.LinearGaussian(**mats).filter(y, x0, P0)
    seen, loglik = run_stream(kfast.KalmanFilter(streaming_model(mats), x0, P0), mats, y, u)
    np.testing.assert_array_equal(np.array([s[1] for s in seen[0::2]]), expected.P_filt)
    assert loglik == expected.loglik


def test_matrices_given_at_some_steps_only():
    """Steps without H, R use the model's: the model is not changed by an override."""
    mats, y, u, x0, P0 = per_step_case(12)
    model = streaming_model(mats)
    overridden = lambda t: t % 3 == 1  # noqa: E731
    stacks = dict(mats)
    for k in ("H", "R"):
        stacks[k] = np.stack([mats[k][t] if overridden(t) else getattr(model, k) for t in range(len(y))])
    expected = kfast.LinearGaussian(**stacks).filter(y, x0, P0)
    seen, loglik = run_stream(kfast.KalmanFilter(model, x0, P0), mats, y, u, override=overridden)
    np.testing.assert_array_equal(np.array([s[0] for s in seen[0::2]]), expected.x_filt)
    assert loglik == expected.loglik


@pytest.mark.parametrize("given", ["H", "R"])
def test_one_of_them(given):
    mats, y, _, x0, P0 = per_step_case(13)
    model = streaming_model(mats)
    stacks = dict(mats)
    other = "R" if given == "H" else "H"
    stacks[other] = np.broadcast_to(getattr(model, other), mats[other].shape)
    expected = kfast.LinearGaussian(**stacks).filter(y, x0, P0)
    kf = kfast.KalmanFilter(model, x0, P0)
    for t in range(len(y)):
        kf.step(y[t], **{given: mats[given][t]})
    np.testing.assert_array_equal(kf.x, expected.x_next)
    assert kf.loglik == expected.loglik


@pytest.mark.parametrize("n, m", [(3, 2), (2, 1), (4, 3)])
def test_against_filterpy(n, m):
    mats, y, _, x0, P0 = per_step_case(14 + n, n=n, m=m)
    Q = mats["Q"][0]
    mats["Q"] = Q  # filterpy's Q is constant
    model = kfast.LinearGaussian(F=mats["F"], H=np.ones((m, n)), Q=Q, R=np.eye(m))
    kf = kfast.KalmanFilter(model, x0, P0)  # Joseph form, as filterpy's update
    fp = FilterpyKalmanFilter(dim_x=n, dim_z=m)
    fp.x, fp.P, fp.F, fp.Q = x0[:, None].copy(), P0.copy(), mats["F"].copy(), Q.copy()
    fp.H, fp.R = np.ones((m, n)), np.eye(m)
    for t in range(len(y)):
        before = kf.loglik
        kf.update(y[t], H=mats["H"][t], R=mats["R"][t])
        # (filterpy reshapes z to a column only when H is not given: pass a column)
        fp.update(y[t][:, None], R=mats["R"][t], H=mats["H"][t])
        np.testing.assert_allclose(kf.x, fp.x[:, 0], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(kf.P, fp.P, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(kf.loglik - before, fp.log_likelihood, rtol=1e-10)
        kf.predict()
        fp.predict()
        np.testing.assert_allclose(kf.x, fp.x[:, 0], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(kf.P, fp.P, rtol=1e-10, atol=1e-12)
    # filterpy kept its own H and R: the per-call ones were for one update only, as in kfast
    np.testing.assert_array_equal(fp.H, np.ones((m, n)))


def test_inputs_are_not_modified():
    mats, y, _, x0, P0 = per_step_case(15)
    H, R = mats["H"][0].copy(), mats["R"][0].copy()
    H_before, R_before = H.copy(), R.copy()
    kf = kfast.KalmanFilter(streaming_model(mats), x0, P0)
    kf.update(y[0], H=H, R=R)
    np.testing.assert_array_equal(H, H_before)
    np.testing.assert_array_equal(R, R_before)


def test_pickled_after_an_update_with_its_own_matrices():
    mats, y, u, x0, P0 = per_step_case(16, correlated=True, inputs=True)
    kf = kfast.KalmanFilter(streaming_model(mats), x0, P0)
    run_stream(kf, mats, y[:4], u[:4])
    kf.update(y[4], u=u[4], H=mats["H"][4], R=mats["R"][4])
    restored = pickle.loads(pickle.dumps(kf))
    for f in (kf, restored):
        f.predict(u=u[4])
        for t in range(5, len(y)):
            f.update(y[t], u=u[t], H=mats["H"][t], R=mats["R"][t])
            f.predict(u=u[t])
    np.testing.assert_array_equal(kf.x, restored.x)
    np.testing.assert_array_equal(kf.P, restored.P)
    assert kf.loglik == restored.loglik


def bad_inputs():
    mats, y, _, x0, P0 = per_step_case(17, correlated=True)
    H, R = mats["H"][3], mats["R"][3]
    asym = R.copy()
    asym[0, 1] += 0.5
    return mats, y, x0, P0, {
        "H-shape": (dict(H=H.T), r"H at step 3: expected shape \(2, 3\), got \(3, 2\)"),
        "H-vector": (dict(H=H[0]), r"H at step 3: expected shape \(2, 3\), got \(3\)"),
        "H-nan": (dict(H=np.where(H > 0, np.nan, H)), r"H at step 3: contains a non-finite value \(NaN\)"),
        "H-complex": (dict(H=H + 1j), r"H: complex input is not supported"),
        "R-scalar": (dict(R=2.0), r"R at step 3: expected shape \(2, 2\), got \(\)"),
        "R-inf": (dict(R=R * np.inf), r"R at step 3: contains a non-finite value \(inf\)"),
        "R-asymmetric": (dict(R=asym), r"R at step 3: not symmetric"),
        "R-indefinite": (dict(R=-R), r"R at step 3: not positive semidefinite"),
        "R-joint": (dict(R=1e-6 * np.eye(2)), r"R at step 3: with the model's Q and N, \[\[Q, N\], \[N', R\]\] is not positive semidefinite"),
    }


@pytest.mark.parametrize("name", bad_inputs()[-1])
def test_invalid_matrices_are_refused_and_leave_the_filter_unchanged(name):
    mats, y, x0, P0, cases = bad_inputs()
    kwargs, message = cases[name]
    model = streaming_model(mats)
    kf = kfast.KalmanFilter(model, x0, P0)
    run_stream(kf, mats, y[:3], None)
    x, P, ll = kf.x, kf.P, kf.loglik
    with pytest.raises(kfast.KfastError, match=message):
        kf.update(y[3], **kwargs)
    np.testing.assert_array_equal(kf.x, x)
    np.testing.assert_array_equal(kf.P, P)
    assert kf.loglik == ll and kf.t == 3
    # and it goes on as if nothing happened
    kf.update(y[3], H=mats["H"][3], R=mats["R"][3])
    fresh = kfast.KalmanFilter(model, x0, P0)
    run_stream(fresh, mats, y[:3], None)
    fresh.update(y[3], H=mats["H"][3], R=mats["R"][3])
    np.testing.assert_array_equal(kf.x, fresh.x)


def test_matrices_are_keyword_only():
    model = kfast.LinearGaussian(F=1.0, H=1.0, Q=0.1, R=1.0)
    kf = kfast.KalmanFilter(model, 0.0, 1.0)
    with pytest.raises(TypeError):
        kf.update(1.0, None, 1.0)  # type: ignore[misc]
