"""The robust update forms (form="sqrt", "ud", "information", "sequential"): each equals the
Joseph form and its own NumPy reference (python/kfast/reference/forms.py) on seeded random
models with every option (time-varying matrices, missing data, N, inputs, diagonal or full R),
and the square-root and U-D forms keep P positive definite on the classical ill-conditioned
update where the standard form does not."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import kfast
from kfast.reference.forms import information_filter, sequential_filter, square_root_filter, ud_filter
from modelgen import at, random_case

FORMS = ["sqrt", "ud", "information", "sequential"]
REFERENCES = {
    "sqrt": square_root_filter,
    "ud": ud_filter,
    "information": information_filter,
    "sequential": sequential_filter,
}
FIELDS = ["x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "K_pred", "loglik_t", "x_next", "P_next"]

# inputs, N, time-varying, missing pattern, diagonal R: every combination over the seeds.
OPTIONS = list(itertools.product([False, True], [False, True], [False, True], ["none", "rows", "partial"], [False, True]))


def case_for(seed):
    inputs, correlated, time_varying, missing, diagonal = OPTIONS[seed % len(OPTIONS)]
    rng = np.random.default_rng(5000 + seed)
    # n up to 14: compile-time sizes (n <= 12) and run-time ones.
    n, m = int(rng.integers(1, 15)), int(rng.integers(1, 6))
    case = random_case(seed, n, m, inputs=inputs, correlated=correlated, time_varying=time_varying, missing=missing)
    if diagonal:
        # diag(R) + lambda_max(R) I >= R keeps the joint covariance with N positive semidefinite.
        R = case.model["R"]
        lam = np.linalg.eigvalsh(R)[..., -1]
        diag = np.einsum("...ii->...i", R)
        case.model["R"] = np.apply_along_axis(np.diag, -1, diag) + lam[..., None, None] * np.eye(m)
        # Data from the changed model are not needed: any y is data.
    case.info["diagonal_R"] = diagonal
    return case


def f_tilde_condition(case):
    """The largest condition number over the steps of the F - N R^-1 H that the time update
    maps Y through (F without N), with N, R and H restricted to the step's observed components:
    the information filter's accuracy scales with it, and a missing pattern can make one step's
    far worse than the fully observed one (seed 65: 17 observed, 920 with y[6, 4] missing)."""
    model = {k: np.asarray(v) for k, v in case.model.items()}
    worst = 0.0
    for t, y_t in enumerate(np.asarray(case.y)):
        F_t, H_t, R_t = (at(model[k], t) for k in "FHR")
        observed = ~np.isnan(y_t)
        if "N" in model and observed.any():
            gain = np.linalg.solve(R_t[np.ix_(observed, observed)], at(model["N"], t)[:, observed].T).T
            F_t = F_t - gain @ H_t[observed]
        worst = max(worst, float(np.linalg.cond(F_t)))
    return worst


def information_seeds(per_option=2, max_condition=100.0):
    """The information form's cases: for each combination of options, the first seeds whose
    F - N R^-1 H has a condition number below 100 (beyond, the form agrees with the Joseph form
    to about 1e-13 times that number)."""
    seeds = []
    for option in range(len(OPTIONS)):
        found = (s for s in range(option, 100 * len(OPTIONS), len(OPTIONS)) if f_tilde_condition(case_for(s)) < max_condition)
        seeds += [next(found) for _ in range(per_option)]
    return seeds


INFORMATION_SEEDS = information_seeds()


def assert_close(got, want, name, rtol=1e-10):
    got, want = np.asarray(got), np.asarray(want)
    scale = max(1.0, float(np.nanmax(np.abs(want)))) if want.size else 1.0
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale, err_msg=name)


@pytest.mark.parametrize("seeds", [range(96), INFORMATION_SEEDS])
def test_options_are_all_covered(seeds):
    assert len(seeds) == 96
    assert {tuple(OPTIONS[s % len(OPTIONS)]) for s in seeds} == set(OPTIONS)
    sizes = {case_for(s).info["n"] for s in seeds}
    assert max(sizes) > 12 and min(sizes) == 1 and len(sizes) >= 12


CASES = [(form, seed) for form in FORMS for seed in (INFORMATION_SEEDS if form == "information" else range(96))]


@pytest.mark.parametrize(("form", "seed"), CASES)
def test_form_equals_joseph_and_its_reference(form, seed):
    case = case_for(seed)
    model = kfast.LinearGaussian(**case.model)
    res = model.filter(case.y, case.x0, case.P0, u=case.u, form=form)
    joseph = model.filter(case.y, case.x0, case.P0, u=case.u)
    ref = REFERENCES[form](**case.model, y=case.y, x0=case.x0, P0=case.P0, u=case.u)
    for name in FIELDS:
        assert_close(getattr(res, name), getattr(joseph, name), f"{form} vs joseph: {name} {case.info}")
        assert_close(getattr(res, name), ref[name], f"{form} vs reference: {name} {case.info}")
    assert res.loglik == pytest.approx(joseph.loglik, rel=1e-10)
    assert model.loglik(case.y, case.x0, case.P0, u=case.u, form=form) == pytest.approx(res.loglik, rel=1e-12)


@pytest.mark.parametrize("form", FORMS)
def test_outputs_subset_gives_the_same_numbers(form):
    case = case_for(7)
    model = kfast.LinearGaussian(**case.model)
    full = model.filter(case.y, case.x0, case.P0, u=case.u, form=form)
    part = model.filter(case.y, case.x0, case.P0, u=case.u, form=form, outputs=("x_filt", "loglik_t"))
    np.testing.assert_array_equal(part.x_filt, full.x_filt)
    np.testing.assert_array_equal(part.loglik_t, full.loglik_t)
    assert part.P_filt is None and part.loglik == full.loglik


@pytest.mark.parametrize(
    ("form", "seed"),
    [(form, seed) for form in FORMS for seed in [1, 2, 13, 46]] + [("sqrt", seed) for seed in range(48)],
)
def test_smoother_with_each_form(form, seed):
    case = case_for(seed)
    model = kfast.LinearGaussian(**case.model)
    res = model.smooth(case.y, case.x0, case.P0, u=case.u, form=form)
    joseph = model.smooth(case.y, case.x0, case.P0, u=case.u)
    for name in ["x_smooth", "P_smooth", "P_lag1"]:
        assert_close(getattr(res, name), getattr(joseph, name), f"{form}: {name} {case.info}")


def test_square_root_smoother_with_singular_predicted_covariance():
    """Q = 0 and a singular F make P(t+1|t) singular: the square-root smoother takes those
    steps' gain from the pseudo-inverse, like the covariance-form smoother."""
    model = kfast.LinearGaussian(F=[[1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]], H=[[1.0, 0.0, 1.0]], Q=np.zeros((3, 3)), R=0.5)
    y = np.sin(np.arange(12.0))[:, None]
    res = model.smooth(y, np.zeros(3), np.eye(3), form="sqrt")
    joseph = model.smooth(y, np.zeros(3), np.eye(3))
    for name in ["x_smooth", "P_smooth", "P_lag1"]:
        assert_close(getattr(res, name), getattr(joseph, name), name)


def test_square_root_smoother_outputs_subset():
    case = case_for(21)
    model = kfast.LinearGaussian(**case.model)
    full = model.smooth(case.y, case.x0, case.P0, u=case.u, form="sqrt")
    part = model.smooth(case.y, case.x0, case.P0, u=case.u, form="sqrt", outputs=("x_smooth", "x_filt"))
    np.testing.assert_array_equal(part.x_smooth, full.x_smooth)
    np.testing.assert_array_equal(part.filter.x_filt, full.filter.x_filt)
    assert part.P_smooth is None


@pytest.mark.parametrize("form", FORMS)
def test_exact_diffuse_start_then_each_form(form):
    trend = kfast.models.local_linear_trend(0.5, 0.1, irregular=1.0)
    y = np.sin(np.arange(40) / 5.0) + np.arange(40) * 0.1
    y[[3, 17]] = np.nan
    res = trend.filter(y, np.zeros(2), np.zeros((2, 2)), P0_inf=np.eye(2), form=form)
    joseph = trend.filter(y, np.zeros(2), np.zeros((2, 2)), P0_inf=np.eye(2))
    assert res.n_diffuse == joseph.n_diffuse == 2
    for name in FIELDS:
        assert_close(getattr(res, name), getattr(joseph, name), f"{form}: {name}")


def ill_conditioned(d):
    """The classical example (Grewal & Andrews' roundoff example after Dyer & McReynolds):
    P0 = I, two nearly collinear measurements H = [[1, 1, 1], [1, 1, 1 + d]] with R = d^2 I."""
    model = kfast.LinearGaussian(F=np.eye(3), H=[[1.0, 1.0, 1.0], [1.0, 1.0, 1.0 + d]], Q=np.zeros((3, 3)), R=d**2 * np.eye(2))
    return model, np.array([[1.0, 1.0]]), np.zeros(3), np.eye(3)


def exact_posterior(d):
    """P(0|0) of the example computed at 60 digits (mpmath)."""
    import mpmath

    with mpmath.workdps(60):
        dm = mpmath.mpf(d)
        H = mpmath.matrix([[1, 1, 1], [1, 1, 1 + dm]])
        P = mpmath.eye(3)
        S = H * P * H.T + dm**2 * mpmath.eye(2)
        return np.array((P - P * H.T * S**-1 * H * P).tolist(), dtype=float)


def test_standard_form_loses_definiteness_where_the_factored_forms_do_not():
    d = 3e-6
    model, y, x0, P0 = ill_conditioned(d)
    smallest = np.linalg.eigvalsh(exact_posterior(d))[0]
    assert smallest == pytest.approx(1.5e-12, rel=0.01)  # positive definite, barely
    assert np.linalg.eigvalsh(model.filter(y, x0, P0, form="standard").P_filt[0])[0] < 0
    for form in ["sqrt", "ud"]:
        P = model.filter(y, x0, P0, form=form).P_filt[0]
        assert np.linalg.eigvalsh(P)[0] == pytest.approx(smallest, rel=0.01), form


@pytest.mark.parametrize("form", ["sqrt", "ud"])
def test_factored_forms_work_where_s_is_singular_in_double_precision(form):
    """With d^2 below the machine epsilon S = H P H' + R is singular to working precision: the
    covariance forms refuse it, the scalar updates of the factored forms do not need it."""
    d = 1e-9
    model, y, x0, P0 = ill_conditioned(d)
    with pytest.raises(kfast.InnovationCovarianceError):
        model.filter(y, x0, P0, form="standard")
    P = model.filter(y, x0, P0, form=form).P_filt[0]
    np.testing.assert_allclose(P, exact_posterior(d), atol=1e-8)
    assert np.linalg.eigvalsh(P)[0] > -4 * np.finfo(float).eps * np.abs(P).max()


def test_information_form_handles_many_measurements_without_forming_s():
    """The information form adds H' R^-1 H: a 50-component measurement of a 2-state model."""
    rng = np.random.default_rng(3)
    H = rng.standard_normal((50, 2))
    model = kfast.LinearGaussian(F=[[1.0, 1.0], [0.0, 1.0]], H=H, Q=0.01 * np.eye(2), R=np.eye(50))
    y = rng.standard_normal((20, 50))
    info = model.filter(y, np.zeros(2), np.eye(2), form="information")
    joseph = model.filter(y, np.zeros(2), np.eye(2))
    assert_close(info.x_filt, joseph.x_filt, "x_filt")
    assert info.loglik == pytest.approx(joseph.loglik, rel=1e-10)


# -- refusals --------------------------------------------------------------------------------


def test_information_form_needs_invertible_f_and_p0_and_r():
    y = np.ones((4, 1))
    singular_f = kfast.LinearGaussian(F=[[1.0, 1.0], [1.0, 1.0]], H=[[1.0, 0.0]], Q=np.eye(2), R=1.0)
    with pytest.raises(ValueError, match=r"F.*step 0.*invertible"):
        singular_f.filter(y, np.zeros(2), np.eye(2), form="information")
    model = kfast.LinearGaussian(F=np.eye(2), H=[[1.0, 0.0]], Q=np.eye(2), R=1.0)
    with pytest.raises(ValueError, match=r"P0.*positive definite.*P0_inf"):
        model.filter(y, np.zeros(2), np.diag([1.0, 0.0]), form="information")
    exact = kfast.LinearGaussian(F=np.eye(2), H=[[1.0, 0.0]], Q=np.eye(2), R=0.0)
    with pytest.raises(ValueError, match=r"R.*step 0.*positive definite"):
        exact.filter(y, np.zeros(2), np.eye(2), form="information")


@pytest.mark.parametrize("form", ["sqrt", "ud", "sequential"])
def test_exact_measurements_are_fine_in_the_scalar_forms(form):
    """R = 0 (an exact measurement) with H P H' > 0: the scalar forms need no R^-1."""
    model = kfast.LinearGaussian(F=[[1.0, 1.0], [0.0, 1.0]], H=[[1.0, 0.0]], Q=0.1 * np.eye(2), R=0.0)
    y = np.cumsum(np.ones((15, 1)), axis=0)
    res = model.filter(y, np.zeros(2), np.eye(2), form=form)
    joseph = model.filter(y, np.zeros(2), np.eye(2))
    assert_close(res.x_filt, joseph.x_filt, "x_filt")
    assert_close(res.P_filt, joseph.P_filt, "P_filt", rtol=1e-9)
    assert res.loglik == pytest.approx(joseph.loglik, rel=1e-10)


def test_singular_full_r_is_refused_by_name():
    model = kfast.LinearGaussian(F=np.eye(2), H=np.eye(2), Q=np.eye(2), R=np.ones((2, 2)))
    with pytest.raises(ValueError, match=r"R.*step 0.*positive definite"):
        model.filter(np.ones((3, 2)), np.zeros(2), np.eye(2), form="sequential")


@pytest.mark.parametrize("form", FORMS)
def test_covariance_form_options_are_refused(form):
    model = kfast.LinearGaussian(F=0.9, H=1.0, Q=1.0, R=1.0)
    with pytest.raises(ValueError, match="converge_tol"):
        model.filter(np.ones(5), 0.0, 1.0, form=form, converge_tol=1e-9)
    with pytest.raises(ValueError, match="form"):
        model.smooth_fixed_lag(np.ones(5), 0.0, 1.0, lag=2, form=form)
    with pytest.raises(ValueError, match="form"):
        kfast.FixedLagSmoother(model, 0.0, 1.0, lag=2, form=form)


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("seed", [3, 13, 22, 35, 47])
def test_streaming_filter_in_each_form_equals_the_batch_filter(form, seed):
    case = case_for(seed)
    model = kfast.LinearGaussian(**case.model)
    # Every fifth step is a predict without an update: the batch filter sees it as missing.
    gapped = case.y.copy()
    gapped[4::5] = np.nan
    batch = model.filter(gapped, case.x0, case.P0, u=case.u, form=form)
    kf = kfast.KalmanFilter(model, case.x0, case.P0, form=form)
    for t in range(len(case.y)):
        u = None if case.u is None else case.u[t]
        assert_close(kf.x, batch.x_pred[t], f"x_pred {t}")
        assert_close(kf.P, batch.P_pred[t], f"P_pred {t}")
        if t % 5 != 4:
            kf.update(case.y[t], u)
            assert_close(kf.x, batch.x_filt[t], f"x_filt {t}")
            assert_close(kf.P, batch.P_filt[t], f"P_filt {t}")
        kf.predict(u)
    assert_close(kf.x, batch.x_next, "x_next")
    assert_close(kf.P, batch.P_next, "P_next")
    assert kf.loglik == pytest.approx(batch.loglik, rel=1e-12)


@pytest.mark.parametrize("form", FORMS)
def test_streaming_update_with_its_own_h_and_r(form):
    model = kfast.LinearGaussian(F=[[1.0, 1.0], [0.0, 1.0]], H=[[1.0, 0.0]], Q=0.1 * np.eye(2), R=1.0)
    joseph = kfast.KalmanFilter(model, np.zeros(2), np.eye(2))
    robust = kfast.KalmanFilter(model, np.zeros(2), np.eye(2), form=form)
    for t in range(6):
        H, R = [[1.0, 0.5 * t]], [[1.0 + t]]
        for kf in (joseph, robust):
            kf.update([float(t)], H=H, R=R)
        assert_close(robust.x, joseph.x, f"x {t}")
        assert_close(robust.P, joseph.P, f"P {t}")
        joseph.predict()
        robust.predict()
    assert robust.loglik == pytest.approx(joseph.loglik, rel=1e-12)


@pytest.mark.parametrize("form", FORMS)
def test_streaming_filter_in_each_form_pickles(form):
    import pickle

    case = case_for(13)
    model = kfast.LinearGaussian(**case.model)
    kf = kfast.KalmanFilter(model, case.x0, case.P0, form=form)
    u = lambda t: None if case.u is None else case.u[t]  # noqa: E731
    for t in range(10):
        kf.step(case.y[t], u(t))
    copy = pickle.loads(pickle.dumps(kf))
    for t in range(10, 20):
        kf.step(case.y[t], u(t))
        copy.step(case.y[t], u(t))
    assert_close(copy.x, kf.x, "x")
    assert_close(copy.P, kf.P, "P")
    assert copy.loglik == pytest.approx(kf.loglik, rel=1e-12)


@pytest.mark.parametrize("form", FORMS)
def test_filter_batch_runs_each_series_in_the_form(form):
    case = case_for(9)
    model = kfast.LinearGaussian(**case.model)
    rng = np.random.default_rng(1)
    Y = case.y[None] + rng.standard_normal((4,) + case.y.shape)
    res = kfast.filter_batch(model, Y, case.x0, case.P0, u=case.u, form=form)
    assert not res.shared_covariance
    for b in range(4):
        one = model.filter(Y[b], case.x0, case.P0, u=case.u, form=form)
        np.testing.assert_array_equal(res.x_filt[b], one.x_filt)
        np.testing.assert_array_equal(res.P_filt[b], one.P_filt)
        assert res.loglik[b] == one.loglik


def test_unknown_form_lists_the_choices():
    model = kfast.LinearGaussian(F=0.9, H=1.0, Q=1.0, R=1.0)
    with pytest.raises(ValueError, match="sequential"):
        model.filter(np.ones(5), 0.0, 1.0, form="cholesky")


@pytest.mark.parametrize("seed, missing, correlated_R", [(0, False, False), (1, True, False), (2, True, True)])
def test_information_form_diffuse_start_is_the_information_filter_from_y0(seed, missing, correlated_R):
    """form="information" with P0_inf is the information filter started at Y0 = lim (P0 + k
    P0_inf)^-1 (P0^-1 = 0 in the diffuse directions): once Y is nonsingular the estimates are
    the pure information recursion's, and the diffuse log-likelihood is the one computed from
    information quantities alone (reference.forms.information_filter_diffuse)."""
    from kfast.reference.forms import information_filter_diffuse
    from test_diffuse import _mixed_model

    model, y, x0, P0, P_inf = _mixed_model(seed, correlated_R=correlated_R)
    if missing:
        y[0, 1] = y[2] = y[7, 0] = np.nan
    res = model.filter(y, x0, P0, P0_inf=P_inf, form="information")
    ref = information_filter_diffuse(model.F, model.H, model.Q, model.R, y, x0, P0, P_inf)
    assert res.loglik == pytest.approx(ref["loglik"], rel=1e-10)
    known = ref["identified"]
    assert known[res.n_diffuse:].all() and known.sum() >= len(y) - res.n_diffuse
    for name in ["x_filt", "P_filt"]:
        assert_close(getattr(res, name)[known], ref[name][known], name, rtol=1e-8)
    ahead = ~np.isnan(ref["x_pred"][:, 0])
    for name in ["x_pred", "P_pred"]:
        assert_close(getattr(res, name)[ahead], ref[name][ahead], name, rtol=1e-8)


def test_information_form_fully_diffuse_start():
    """P0 = 0, P0_inf = I: the textbook information filter with Y0 = P0^-1 = 0."""
    from kfast.reference.forms import information_filter_diffuse

    trend = kfast.models.local_linear_trend(0.5, 0.1, irregular=1.0)
    y = (np.sin(np.arange(40) / 5.0) + np.arange(40) * 0.1)[:, None]
    y[[1, 17]] = np.nan
    res = trend.filter(y, np.zeros(2), np.zeros((2, 2)), P0_inf=np.eye(2), form="information")
    ref = information_filter_diffuse(trend.F, trend.H, trend.Q, trend.R, y, np.zeros(2), np.zeros((2, 2)), np.eye(2))
    assert res.n_diffuse == 3 and not ref["identified"][:2].any() and ref["identified"][2:].all()
    assert res.loglik == pytest.approx(ref["loglik"], rel=1e-10)
    assert_close(res.x_filt[2:], ref["x_filt"][2:], "x_filt", rtol=1e-9)
    assert_close(res.P_filt[2:], ref["P_filt"][2:], "P_filt", rtol=1e-9)
