"""The multiple-model filters (IMM, fixed bank, Gaussian sum) against the NumPy reference, the
Kalman filter they reduce to, filterpy's IMMEstimator and Söderström's Example 9.2."""

import numpy as np
import pytest
import switching

import kfast
from kfast.reference import kalman_filter
from kfast.reference.multiple import gaussian_sum_filter, imm_filter, model_bank

TRANS = np.array([[0.9, 0.1], [0.2, 0.8]])


def cv_models():
    """Two 1-D constant-velocity modes (a quiet and a manoeuvring one), position measured."""
    dt = 1.0
    F = np.array([[1.0, dt], [0.0, 1.0]])
    G = np.array([[dt**2 / 2], [dt]])
    H = np.array([[1.0, 0.0]])
    dicts = [dict(F=F, H=H, Q=q * G @ G.T + 1e-9 * np.eye(2), R=np.array([[1.0]])) for q in (0.01, 4.0)]
    return dicts, [kfast.LinearGaussian(**d) for d in dicts]


def simulate_cv(seed, T=120):
    rng = np.random.default_rng(seed)
    x, ys = np.zeros(2), []
    for t in range(T):
        a = 3.0 * rng.standard_normal() if 40 <= t < 70 else 0.1 * rng.standard_normal()
        x = np.array([x[0] + x[1] + a / 2, x[1] + a])
        ys.append(x[0] + rng.standard_normal())
    y = np.array(ys)[:, None]
    y[rng.random(T) < 0.05] = np.nan
    return y


def assert_same(res, ref, tol=1e-9):
    for name in ("x_filt", "P_filt", "x_pred", "P_pred", "mode_probs", "mode_probs_pred", "loglik_t"):
        np.testing.assert_allclose(getattr(res, name), ref[name], rtol=tol, atol=tol, err_msg=name)
    assert res.loglik == pytest.approx(ref["loglik"], rel=1e-10)
    for j, (x, P) in enumerate(zip(res.x_filt_modes, res.P_filt_modes)):
        np.testing.assert_allclose(x, ref["x_filt_modes"][j], rtol=tol, atol=tol)
        np.testing.assert_allclose(P, ref["P_filt_modes"][j], rtol=tol, atol=tol)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_imm_equals_the_reference(seed):
    dicts, models = cv_models()
    y = simulate_cv(seed)
    x0, P0 = np.array([0.0, 0.0]), np.diag([10.0, 4.0])
    res = kfast.imm_filter(models, TRANS, y, x0, P0, mode_probs=[0.7, 0.3])
    ref = imm_filter(dicts, TRANS, y, x0, P0, [0.7, 0.3])
    assert_same(res, ref)


def test_identical_modes_are_the_kalman_filter():
    dicts, models = cv_models()
    y = simulate_cv(5)
    x0, P0 = np.zeros(2), np.eye(2) * 5
    res = kfast.imm_filter([models[1]] * 3, np.full((3, 3), 1 / 3), y, x0, P0)
    kf = models[1].filter(y, x0, P0)
    np.testing.assert_allclose(res.x_filt, kf.x_filt, atol=1e-10)
    np.testing.assert_allclose(res.P_filt, kf.P_filt, atol=1e-10)
    np.testing.assert_allclose(res.loglik_t, kf.loglik_t, atol=1e-10)
    np.testing.assert_allclose(res.mode_probs, 1 / 3, atol=1e-12)
    one = kfast.imm_filter([models[1]], [[1.0]], y, x0, P0)
    np.testing.assert_allclose(one.x_filt, kf.x_filt, atol=1e-12)
    assert one.loglik == pytest.approx(kf.loglik, rel=1e-12)


def test_the_object_forms_are_the_functions():
    """kfast.IMM(models, transition=, mode_probs=).filter(y, x0, P0), kfast.ModelBank and
    NonlinearModel.gaussian_sum (the interfaces the design pins) give the functions' numbers."""
    _, models = cv_models()
    y = simulate_cv(6)
    x0, P0 = np.zeros(2), np.eye(2) * 5
    imm = kfast.IMM(models, transition=TRANS, mode_probs=[0.7, 0.3])
    by_object, by_function = imm.filter(y, x0, P0), kfast.imm_filter(models, TRANS, y, x0, P0, mode_probs=[0.7, 0.3])
    for name in ("x_filt", "P_filt", "mode_probs", "loglik_t"):
        np.testing.assert_array_equal(getattr(by_object, name), getattr(by_function, name))
    stream = imm.stream(x0, P0)
    for t, value in enumerate(y[:5]):
        stream.update(value)
        np.testing.assert_array_equal(stream.mode_probs, by_function.mode_probs[t])
        stream.predict()
    bank = kfast.ModelBank(models, mode_probs=[0.5, 0.5]).filter(y, x0, P0)
    np.testing.assert_array_equal(bank.mode_probs, kfast.model_bank(models, y, x0, P0, mode_probs=[0.5, 0.5]).mode_probs)
    with pytest.raises(ValueError, match="transition"):
        kfast.IMM(models).filter(y, x0, P0)
    model = kfast.NonlinearModel(lambda X, t, u: 0.9 * X, lambda X, t, u: X**2 / 20, Q=0.5, R=0.1, n=1)
    yq = np.array([0.8, 0.7, 0.9])
    method = model.gaussian_sum(yq, [[-4.0], [4.0]], [[[1.0]], [[1.0]]], method="ukf")
    function = kfast.gaussian_sum(model, yq, [[-4.0], [4.0]], [[[1.0]], [[1.0]]], method="ukf")
    np.testing.assert_array_equal(method.x_filt, function.x_filt)


def test_imm_equals_filterpy_step_for_step():
    fp = pytest.importorskip("filterpy.kalman")
    dicts, models = cv_models()
    y = simulate_cv(3)
    y = y[~np.isnan(y[:, 0])]
    x0, P0, mu0 = np.array([0.0, 0.0]), np.diag([10.0, 4.0]), np.array([0.6, 0.4])
    filters = []
    for d in dicts:
        kf = fp.KalmanFilter(dim_x=2, dim_z=1)
        kf.F, kf.H, kf.Q, kf.R = d["F"], d["H"], d["Q"], d["R"]
        kf.x, kf.P = x0.copy(), P0.copy()
        filters.append(kf)
    imm = fp.IMMEstimator(filters, mu0, TRANS)
    xs, Ps, mus = [], [], []
    for z in y:
        imm.update(z)
        xs.append(imm.x.copy())
        Ps.append(imm.P.copy())
        mus.append(imm.mu.copy())
        imm.predict()
    # filterpy's first update weighs the modes by mu0 @ M (computed in its constructor).
    res = kfast.imm_filter(models, TRANS, y, x0, P0, mode_probs=mu0 @ TRANS)
    np.testing.assert_allclose(res.x_filt, np.array(xs), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(res.P_filt, np.array(Ps), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(res.mode_probs, np.array(mus), rtol=1e-9, atol=1e-12)


def test_streaming_gives_the_numbers_of_the_series():
    dicts, models = cv_models()
    y = simulate_cv(7, T=40)
    x0, P0 = np.zeros(2), np.eye(2)
    res = kfast.imm_filter(models, TRANS, y, x0, P0)
    imm = kfast.IMMFilter(models, TRANS, x0, P0)
    for t in range(len(y)):
        imm.update(y[t])
        assert np.array_equal(imm.x, res.x_filt[t]) and np.array_equal(imm.P, res.P_filt[t])
        assert np.array_equal(imm.mode_probs, res.mode_probs[t])
        x1, P1 = imm.mode_estimate(1)
        assert np.array_equal(x1, res.x_filt_modes[1][t])
        imm.predict()
    assert imm.t == len(y) and imm.loglik == pytest.approx(res.loglik, rel=1e-14)


def example_9_2(seed):
    """Example 9.2 with its modes as kfast models."""
    case, dicts, u, y, xs, true_mode = switching.example_9_2(seed)
    return case, [kfast.LinearGaussian(**d) for d in dicts], u, y, xs, true_mode


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_example_9_2_tracks_the_switching_system(seed):
    """Söderström Example 9.2: the IMM tracks nearly as well as a filter that knows the mode,
    far better than either fixed-mode filter, and mu_1 follows the true mode."""
    case, models, u, y, xs, true_mode = example_9_2(seed)
    x0, P0 = case["x0"], case["P0"]
    res = kfast.imm_filter(models, case["transition"], y, x0, P0, mode_probs=case["mode_probs"], u=u)
    rmse = lambda est: float(np.sqrt(np.mean((est[:, 0] - xs) ** 2)))  # noqa: E731
    fixed = [rmse(m.filter(y, x0, P0, u=u).x_filt) for m in models]
    F = np.array([[[models[k].F[0, 0]]] for k in true_mode])
    B = np.array([[[models[k].B[0, 0]]] for k in true_mode])
    Q = np.array([[[models[k].Q[0, 0]]] for k in true_mode])
    aware = kalman_filter(F, np.ones((1, 1)), Q, np.full((1, 1), case["R"]), y, np.array([x0]), np.array([[P0]]), B=B, u=u)
    best = rmse(aware["x_filt"])
    assert rmse(res.x_filt) < 1.25 * best
    assert all(rmse(res.x_filt) < 0.35 * f for f in fixed), (rmse(res.x_filt), fixed)
    mu1 = res.mode_probs[:, 0]
    assert np.mean(mu1[true_mode == 0] > 0.5) > 0.9
    assert np.mean(mu1[true_mode == 1] < 0.5) > 0.9


def test_the_bank_finds_the_true_model():
    dicts, models = cv_models()
    rng = np.random.default_rng(4)
    x, ys = np.zeros(2), []
    for _ in range(200):  # simulated from model 1 (the manoeuvring one)
        ys.append(x[0] + rng.standard_normal())
        x = dicts[1]["F"] @ x + rng.multivariate_normal(np.zeros(2), dicts[1]["Q"])
    y = np.array(ys)[:, None]
    res = kfast.model_bank(models, y, np.zeros(2), np.eye(2))
    ref = model_bank(dicts, y, np.zeros(2), np.eye(2), [0.5, 0.5])
    assert_same(res, ref)
    assert res.mode_probs[-1, 1] > 0.99


def test_bank_of_different_sizes_has_no_combination():
    _, models = cv_models()
    scalar = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=1.0)
    y = simulate_cv(1)
    res = kfast.model_bank([models[0], scalar], y, [np.zeros(2), np.zeros(1)], [np.eye(2), np.eye(1)])
    assert res.x_filt is None and res.mode_probs.shape == (len(y), 2)
    assert res.x_filt_modes[0].shape == (len(y), 2) and res.x_filt_modes[1].shape == (len(y), 1)
    np.testing.assert_allclose(res.mode_probs.sum(axis=1), 1.0)


def test_state_maps_mix_modes_of_different_sizes():
    """CV (p, v) and constant acceleration (p, v, a): with a = 0 held exactly, the CA mode is
    the CV mode, and the IMM equals the IMM of two CV modes."""
    dicts, models = cv_models()
    y = simulate_cv(9)
    Fa = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    Qa = np.zeros((3, 3))
    Qa[:2, :2] = dicts[1]["Q"]
    ca = kfast.LinearGaussian(F=Fa, H=[[1.0, 0.0, 0.0]], Q=Qa, R=1.0)
    up = (np.array([[1.0, 0], [0, 1], [0, 0]]), np.zeros(3), np.zeros((3, 3)))
    down = np.array([[1.0, 0, 0], [0, 1, 0]])
    x0, P0 = np.zeros(2), np.diag([10.0, 4.0])
    maps = {(0, 1): up, (1, 0): down}
    res = kfast.imm_filter([models[0], ca], TRANS, y, x0, P0, state_maps=maps)
    same = kfast.imm_filter(models, TRANS, y, x0, P0)
    np.testing.assert_allclose(res.x_filt, same.x_filt, atol=1e-9)
    np.testing.assert_allclose(res.P_filt, same.P_filt, atol=1e-9)
    np.testing.assert_allclose(res.mode_probs, same.mode_probs, atol=1e-9)
    ref = imm_filter([dicts[0], dict(F=Fa, H=np.array([[1.0, 0, 0]]), Q=Qa, R=np.eye(1))], TRANS, y, x0, P0, [0.5, 0.5],
                     state_maps=maps)
    assert_same(res, ref)


def turn_modes():
    """Straight, left and right turns at 0.1 rad/s (the 4-state known-rate turn), position
    measured: as NonlinearModels and as the same LinearGaussians."""
    turns = [kfast.models.coordinated_turn(dt=1.0, q=0.5, omega=w) for w in (0.0, 0.1, -0.1)]
    R = np.eye(2) * 4.0
    position = lambda X, t, u: X[:, :2]  # noqa: E731
    nonlinear = [kfast.NonlinearModel(ct, position, ct.Q, R, n=4) for ct in turns]
    H = np.eye(2, 4)
    linear = [kfast.LinearGaussian(F=ct.params, H=H, Q=ct.Q, R=R) for ct in turns]
    return nonlinear, linear


def turn_track(seed, T=60):
    rng = np.random.default_rng(seed)
    _, linear = turn_modes()
    x, ys = np.array([0.0, 0.0, 10.0, 0.0]), []
    for t in range(T):
        F = linear[0 if t < 20 else 1 if t < 40 else 2].F
        ys.append(x[:2] + 2.0 * rng.standard_normal(2))
        x = F @ x + np.array([0, 0, 0.3, 0.3]) * rng.standard_normal(4)
    return np.array(ys)


@pytest.mark.parametrize("method", ["ekf", "ukf"])
def test_nonlinear_modes_by_ekf_and_ukf(method):
    """Turn models given as NonlinearModels (f linear in x, so the EKF and the UKF are the
    Kalman filter) give the linear IMM's numbers, and the turn's mode wins while it lasts."""
    nonlinear, linear = turn_modes()
    y = turn_track(0)
    trans = np.full((3, 3), 0.025) + np.eye(3) * 0.925
    x0, P0 = np.array([0.0, 0.0, 10.0, 0.0]), np.diag([10.0, 10.0, 4.0, 4.0])
    res = kfast.imm_filter(nonlinear, trans, y, x0, P0, method=method)
    lin = kfast.imm_filter(linear, trans, y, x0, P0)
    np.testing.assert_allclose(res.x_filt, lin.x_filt, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(res.mode_probs, lin.mode_probs, rtol=1e-6, atol=1e-6)
    assert np.mean(np.argmax(res.mode_probs[25:40], axis=1) == 1) > 0.7


def test_gaussian_sum_of_one_component_is_the_kalman_filter():
    _, models = cv_models()
    y = simulate_cv(2)
    kf = models[0].filter(y, np.zeros(2), np.eye(2))
    res = kfast.gaussian_sum(models[0], y, [np.zeros(2)], [np.eye(2)])
    np.testing.assert_allclose(res.x_filt, kf.x_filt, atol=1e-12)
    res3 = kfast.gaussian_sum(models[0], y, [np.zeros(2)] * 3, [np.eye(2)] * 3)
    np.testing.assert_allclose(res3.x_filt, kf.x_filt, atol=1e-10)
    np.testing.assert_allclose(res3.mode_probs, 1 / 3, atol=1e-12)


def test_gaussian_sum_equals_the_reference_on_a_bimodal_problem():
    """y = x^2/20 cannot tell x from -x: a two-component prior keeps both modes."""
    model = kfast.NonlinearModel(lambda X, t, u: 0.9 * X, lambda X, t, u: X**2 / 20, Q=0.5, R=0.1, n=1)
    rng = np.random.default_rng(0)
    x, ys = 4.0, []
    for _ in range(30):
        ys.append(x**2 / 20 + np.sqrt(0.1) * rng.standard_normal())
        x = 0.9 * x + np.sqrt(0.5) * rng.standard_normal()
    y = np.array(ys)[:, None]
    means, covs, weights = np.array([[-4.0], [4.0]]), np.array([[[1.0]], [[1.0]]]), np.array([0.5, 0.5])
    res = kfast.gaussian_sum(model, y, means, covs, weights)
    ref = gaussian_sum_filter(lambda x: 0.9 * x, lambda x: x**2 / 20, lambda x: np.array([[0.9]]),
                              lambda x: np.array([[x[0] / 10]]), np.array([[0.5]]), np.array([[0.1]]), y, means, covs, weights)
    np.testing.assert_allclose(res.x_filt, ref["x_filt"], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(res.mode_probs, ref["weights"], rtol=1e-6, atol=1e-6)
    assert res.loglik == pytest.approx(ref["loglik"], rel=1e-6)


def test_pruning_and_merging_reduce_the_components():
    _, models = cv_models()
    y = simulate_cv(2)
    means = [np.zeros(2), np.zeros(2) + 1e-3, np.array([50.0, 0.0])]
    covs = [np.eye(2)] * 3
    full = kfast.gaussian_sum(models[0], y, means, covs)
    merged = kfast.gaussian_sum(models[0], y, means, covs, merge=0.1)
    pruned = kfast.gaussian_sum(models[0], y, means, covs, prune=1e-6)
    assert np.isnan(merged.x_filt_modes[1][-1]).all() and not np.isnan(merged.x_filt_modes[0][-1]).any()
    assert np.isnan(pruned.x_filt_modes[2][-1]).all() and pruned.mode_probs[-1, 2] == 0.0
    np.testing.assert_allclose(merged.x_filt, full.x_filt, atol=1e-3)
    np.testing.assert_allclose(pruned.x_filt, full.x_filt, atol=1e-6)


def test_merging_three_components_keeps_the_moments_of_all_three():
    """Merging is moment matching: one step after three close components merge into one, the
    mixture's mean and covariance are those of all three (a merge into a component that
    already absorbed another must start from the merged state)."""
    _, models = cv_models()
    y = simulate_cv(3)[:1]
    means = [np.zeros(2), np.array([0.1, 0.0]), np.array([0.2, 0.0])]
    covs, weights = [np.eye(2)] * 3, [0.5, 0.3, 0.2]
    full = kfast.gaussian_sum(models[0], y, means, covs, weights)
    merged = kfast.gaussian_sum(models[0], y, means, covs, weights, merge=1.0)
    assert not np.isnan(merged.x_filt_modes[0][0]).any()
    assert np.isnan(merged.x_filt_modes[1][0]).all() and np.isnan(merged.x_filt_modes[2][0]).all()
    np.testing.assert_allclose(merged.mode_probs[0], [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(merged.x_filt_modes[0][0], full.x_filt[0], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(merged.P_filt_modes[0][0], full.P_filt[0], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(merged.x_filt, full.x_filt, rtol=1e-12, atol=1e-14)


def test_inputs_per_mode():
    case, models, u, y, xs, true_mode = example_9_2(1)
    both = kfast.imm_filter(models, case["transition"], y, 5.0, 1.0, u=u)
    per = kfast.imm_filter(models, case["transition"], y, 5.0, 1.0, u=[u, u])
    np.testing.assert_array_equal(both.x_filt, per.x_filt)
    none = kfast.imm_filter(models, case["transition"], y, 5.0, 1.0, u=[u, np.zeros_like(u)])
    assert not np.allclose(none.x_filt, both.x_filt)


@pytest.mark.parametrize(
    "change, arg",
    [
        (dict(transition=[[0.9, 0.2], [0.1, 0.9]]), "transition"),
        (dict(transition=[[1.5, -0.5], [0.1, 0.9]]), "transition"),
        (dict(transition=[[np.nan, 1.0], [0.1, 0.9]]), "transition"),
        (dict(transition=[[1.0]]), "transition"),
        (dict(mode_probs=[0.5, 0.6]), "mode_probs"),
        (dict(mode_probs=[np.nan, 1.0]), "mode_probs"),
        (dict(mode_probs=[0.0, 0.0]), "mode_probs"),
        (dict(mode_probs=[1.0]), "mode_probs"),
        (dict(y=np.ones((5, 2))), "y"),
        (dict(y=np.array([[1.0], [np.inf]])), "y"),
        (dict(x0=np.zeros(3)), "x0"),
        (dict(method="pf"), "method"),
        (dict(state_maps={(0, 5): np.eye(2)}), "state_maps"),
        (dict(state_maps={(0, 1): np.eye(3)}), "state_maps"),
    ],
)
def test_bad_input_is_named(change, arg):
    _, models = cv_models()
    args = dict(transition=TRANS, y=np.zeros((5, 1)), x0=np.zeros(2), P0=np.eye(2), mode_probs=None)
    args.update(change)
    y_before = np.array(args["y"], copy=True)
    with pytest.raises(ValueError, match=f"^{arg}"):
        kfast.imm_filter(models, **args)
    np.testing.assert_array_equal(np.asarray(args["y"]), y_before)


def test_models_of_different_sizes_need_maps():
    _, models = cv_models()
    scalar = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=1.0)
    with pytest.raises(ValueError, match=r"^state_maps.*\(0, 1\)"):
        kfast.imm_filter([models[0], scalar], TRANS, np.zeros((3, 1)), [np.zeros(2), np.zeros(1)], [np.eye(2), np.eye(1)])
    with pytest.raises(ValueError, match="^x0"):
        kfast.imm_filter([models[0], scalar], TRANS, np.zeros((3, 1)), np.zeros(2), np.eye(2))
    with pytest.raises(ValueError, match="^models"):
        kfast.imm_filter([models[0], "cv"], TRANS, np.zeros((3, 1)), np.zeros(2), np.eye(2))


def test_correlated_noise_is_refused_by_the_imm_only():
    _, models = cv_models()
    corr = kfast.LinearGaussian(F=models[0].F, H=models[0].H, Q=np.eye(2) * 0.1, R=1.0, N=[[0.01], [0.0]])
    with pytest.raises(ValueError, match="^models.*N"):
        kfast.imm_filter([models[0], corr], TRANS, np.zeros((3, 1)), np.zeros(2), np.eye(2))
    kfast.model_bank([models[0], corr], np.zeros((3, 1)), np.zeros(2), np.eye(2))


def test_a_mode_that_cannot_be_reached_keeps_probability_zero():
    _, models = cv_models()
    y = simulate_cv(0, T=30)
    res = kfast.imm_filter(models, [[1.0, 0.0], [0.5, 0.5]], y, np.zeros(2), np.eye(2), mode_probs=[1.0, 0.0])
    assert np.all(res.mode_probs[:, 1] == 0.0)
    assert np.isfinite(res.x_filt).all()


def test_an_observation_no_mode_can_explain_leaves_the_probabilities():
    """Every mode's likelihood underflows (a prior 1e155 away): the probabilities stay at cbar
    and log c is -inf, as the Kalman filter's own term -- not NaN."""
    _, models = cv_models()
    x0 = np.array([-1e155, 0.0])  # the measured position: e'S^-1 e overflows
    res = kfast.imm_filter(models, TRANS, np.ones((2, 1)), x0, np.eye(2), mode_probs=[0.3, 0.7])
    assert res.loglik_t[0] == -np.inf
    np.testing.assert_array_equal(res.mode_probs[0], [0.3, 0.7])
    assert not np.isnan(res.mode_probs).any()
