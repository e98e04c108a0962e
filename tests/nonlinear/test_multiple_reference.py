"""The NumPy reference of the multiple-model filters (kfast.reference.multiple: the IMM, the fixed
model bank and the Gaussian-sum filter), the oracle for kfast's own, checked against the Kalman
filter they reduce to, filterpy's IMMEstimator step for step, the exact mixture posterior of a
linear model, and Söderström's Example 9.2 (tests/data/imm_example_9_2.json).

filterpy's IMMEstimator (filterpy/kalman/IMM.py), read for these tests: the same steps in the
same order (update every mode, mu = cbar * l / sum; the mixing and the time update in predict),
row-stochastic M as here (cbar = mu @ M, omega_ij = M_ij mu_i / cbar_j), although its docstring
says M[i, j] is the switch from j to i. Differences: (1) its constructor already forms
cbar = mu0 @ M, which weighs the first update, so its mu0 is our mode_probs = mu0 @ M; (2) its
combined prior x_prior, P_prior after predict() weighs the modes' predictions by mu(t|t), not by
cbar(t+1) as (9.64)-(9.86) and this reference do (so the test compares x_pred with filterpy's
per-mode predictions weighed by its cbar); (3) it multiplies likelihoods, not their logarithms,
flooring an underflowed one at the smallest float; (4) update(None) (a missing y) reweighs the
modes by the density at zero of their last S instead of leaving mu = cbar; (5) no cbar_j = 0
guard, no likelihood of the data, one u for every mode, modes of one state size only.
"""

import numpy as np
import pytest
from modelgen import random_case
from switching import example_9_2

from kfast.reference import gaussian_sum_filter, imm_filter, kalman_filter, model_bank

TRANS = np.array([[0.9, 0.1], [0.2, 0.8]])  # not symmetric: a transposed p fails the tests


def assert_close(got, want, tol, name=""):
    np.testing.assert_allclose(got, want, rtol=tol, atol=tol, err_msg=name)


def assert_psd(P, tol=1e-9):
    P = np.asarray(P)
    assert np.all(np.isfinite(P))
    np.testing.assert_allclose(P, np.swapaxes(P, -1, -2), atol=1e-12)
    scale = max(1.0, float(np.max(np.abs(P))))
    assert np.min(np.linalg.eigvalsh(P)) > -tol * scale


def cv_modes(q=(0.01, 4.0)):
    """1-D constant velocity [p, v], position measured; a quiet and a manoeuvring mode."""
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    G = np.array([[0.5], [1.0]])
    H = np.array([[1.0, 0.0]])
    return [dict(F=F, H=H, Q=qi * G @ G.T + 1e-6 * np.eye(2), R=np.array([[1.0]])) for qi in q]


def simulate_manoeuvre(seed, T=120, missing=0.0):
    """A track that manoeuvres (acceleration sd 3) for 40 <= t < 70, else sd 0.1."""
    rng = np.random.default_rng(seed)
    x, ys = np.zeros(2), []
    for t in range(T):
        ys.append(x[0] + rng.standard_normal())
        a = (3.0 if 40 <= t < 70 else 0.1) * rng.standard_normal()
        x = np.array([x[0] + x[1] + a / 2, x[1] + a])
    y = np.array(ys)[:, None]
    y[rng.random(T) < missing] = np.nan
    return y


def simulate_linear(rng, mode, x0, T):
    x, ys = np.array(x0, dtype=float), []
    for _ in range(T):
        ys.append(mode["H"] @ x + rng.multivariate_normal(np.zeros(len(mode["R"])), mode["R"]))
        x = mode["F"] @ x + rng.multivariate_normal(np.zeros(len(x)), mode["Q"])
    return np.array(ys)


# ----------------------------------------------------------------------------------------------
# The IMM reduces to the Kalman filter
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed, n, m, missing", [(1, 2, 1, "none"), (2, 3, 2, "partial"), (3, 4, 3, "rows")])
def test_one_mode_is_the_kalman_filter(seed, n, m, missing):
    c = random_case(seed, n, m, T=40, inputs=True, missing=missing)
    want = kalman_filter(**c.model, y=c.y, x0=c.x0, P0=c.P0, u=c.u)
    got = imm_filter([c.model], [[1.0]], c.y, c.x0, c.P0, [1.0], u=c.u)
    for name in ("x_filt", "P_filt", "x_pred", "P_pred", "loglik_t"):
        assert_close(got[name], want[name], 1e-12, name)
    assert_close(got["x_filt_modes"][0], want["x_filt"], 1e-12)
    assert got["loglik"] == pytest.approx(want["loglik"], rel=1e-12)
    assert np.all(got["mode_probs"] == 1.0) and np.all(got["mode_probs_pred"] == 1.0)


@pytest.mark.parametrize("seed", [4, 5])
def test_identical_modes_are_the_kalman_filter(seed):
    """With r copies of one mode every likelihood is the same: mu(t|t) = cbar(t), which follows
    the Markov chain alone (cbar(t+1) = p' mu(t)), and every estimate is the Kalman filter's."""
    c = random_case(seed, 3, 2, T=40, inputs=True, missing="partial")
    rng = np.random.default_rng(seed)
    p = rng.random((3, 3)) + 0.1
    p /= p.sum(axis=1, keepdims=True)
    mu0 = np.array([0.2, 0.5, 0.3])
    want = kalman_filter(**c.model, y=c.y, x0=c.x0, P0=c.P0, u=c.u)
    got = imm_filter([c.model] * 3, p, c.y, c.x0, c.P0, mu0, u=c.u)
    for name in ("x_filt", "P_filt", "x_pred", "P_pred", "loglik_t"):
        assert_close(got[name], want[name], 1e-12, name)
    chain = [mu0]
    for _ in range(len(c.y) - 1):
        chain.append(p.T @ chain[-1])
    assert_close(got["mode_probs"], np.array(chain), 1e-12)
    assert_close(got["mode_probs_pred"], np.array(chain), 1e-12)
    # a doubly stochastic p (a mixture of permutations) keeps the uniform prior where it is
    cycle = np.roll(np.eye(3), 1, axis=1)
    flat = imm_filter([c.model] * 3, 0.6 * np.eye(3) + 0.3 * cycle + 0.1 * cycle.T, c.y, c.x0, c.P0, None, u=c.u)
    assert_close(flat["mode_probs"], np.full((len(c.y), 3), 1 / 3), 1e-12)


# ----------------------------------------------------------------------------------------------
# The IMM against filterpy's IMMEstimator
# ----------------------------------------------------------------------------------------------


def filterpy_problem(name):
    """(modes, transition, y, u, x0, P0, mu0) for filterpy: two CV modes on a manoeuvring track,
    or Söderström's Example 9.2 (per-mode input gains)."""
    if name == "cv":
        y = simulate_manoeuvre(3)
        return cv_modes(), TRANS, y, None, np.zeros(2), np.diag([10.0, 4.0]), np.array([0.6, 0.4])
    case, modes, u, y, _, _ = example_9_2(21, T=150)
    return modes, TRANS, y, u, np.array([case["x0"]]), np.array([[case["P0"]]]), np.array([0.3, 0.7])


@pytest.mark.parametrize("problem", ["cv", "example_9_2"])
def test_imm_equals_filterpy_step_for_step(problem):
    fp = pytest.importorskip("filterpy.kalman")
    modes, p, y, u, x0, P0, mu0 = filterpy_problem(problem)
    n, m = len(x0), y.shape[1]
    filters = []
    for d in modes:
        kf = fp.KalmanFilter(dim_x=n, dim_z=m, dim_u=0 if u is None else 1)
        kf.F, kf.H, kf.Q, kf.R = (np.atleast_2d(d[k]).astype(float) for k in "FHQR")
        if u is not None:
            kf.B = np.atleast_2d(d["B"]).astype(float)
        kf.x, kf.P = x0.copy(), P0.copy()
        filters.append(kf)
    imm = fp.IMMEstimator(filters, mu0, p)
    rec = {k: [] for k in ("x", "P", "mu", "modes", "cbar", "x_pred", "P_pred")}
    for t, z in enumerate(y):
        imm.update(z)
        rec["x"].append(imm.x.copy())
        rec["P"].append(imm.P.copy())
        rec["mu"].append(imm.mu.copy())
        rec["modes"].append([f.x.copy() for f in filters])
        rec["cbar"].append(imm.cbar.copy())  # cbar(t+1) = mu(t) @ M, formed in update
        imm.predict(None if u is None else u[t])
        # filterpy's own x_prior weighs the predictions by mu(t|t); (9.64)-(9.86) by cbar(t+1)
        x_pred = sum(c * f.x for c, f in zip(imm.cbar, filters))
        P_pred = sum(c * (f.P + np.outer(f.x - x_pred, f.x - x_pred)) for c, f in zip(imm.cbar, filters))
        rec["x_pred"].append(x_pred)
        rec["P_pred"].append(P_pred)
    # filterpy's first update weighs the modes by mu0 @ M (the mixing of its constructor)
    got = imm_filter(modes, p, y, x0, P0, mu0 @ p, u=u)
    assert_close(got["x_filt"], np.array(rec["x"]), 1e-10, "x_filt")
    assert_close(got["P_filt"], np.array(rec["P"]), 1e-10, "P_filt")
    assert_close(got["mode_probs"], np.array(rec["mu"]), 1e-10, "mode_probs")
    for j in range(len(modes)):
        assert_close(got["x_filt_modes"][j], np.array([r[j] for r in rec["modes"]]), 1e-10, f"mode {j}")
    assert_close(got["mode_probs_pred"][1:], np.array(rec["cbar"][:-1]), 1e-10, "cbar")
    assert_close(got["x_pred"][1:], np.array(rec["x_pred"][:-1]), 1e-10, "x_pred")
    assert_close(got["P_pred"][1:], np.array(rec["P_pred"][:-1]), 1e-10, "P_pred")
    # the test has teeth: the modes disagree, so the mixing and the weights matter
    assert np.ptp(got["mode_probs"][:, 0]) > 0.5


def test_the_probabilities_stay_at_cbar_when_y_tells_nothing():
    """A step with y missing leaves mu = cbar and adds 0 to the log-likelihood; so does, with
    log c = -inf instead of NaN, a y that every mode's likelihood underflows on (1e155 away)."""
    modes = cv_modes()
    y = simulate_manoeuvre(2, T=10)
    y[3] = np.nan
    got = imm_filter(modes, TRANS, y, np.zeros(2), np.eye(2), [0.3, 0.7])
    assert_close(got["mode_probs"][3], got["mode_probs_pred"][3], 1e-15)
    assert abs(got["loglik_t"][3]) < 1e-15 and np.all(np.isfinite(got["loglik_t"]))  # log sum cbar
    with np.errstate(over="ignore"):  # e' S^-1 e overflows to inf
        far = imm_filter(modes, TRANS, np.ones((3, 1)), np.array([1e155, 0.0]), np.eye(2), [0.3, 0.7])
    assert far["loglik_t"][0] == -np.inf
    np.testing.assert_array_equal(far["mode_probs"][0], [0.3, 0.7])
    assert not np.isnan(far["mode_probs"]).any() and not np.isnan(far["x_filt"]).any()


# ----------------------------------------------------------------------------------------------
# The fixed model bank
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("true_mode", [0, 1])
def test_the_bank_finds_the_true_model(true_mode):
    modes = cv_modes()
    y = simulate_linear(np.random.default_rng(10 + true_mode), modes[true_mode], [0.0, 1.0], T=200)
    x0, P0, mu0 = np.zeros(2), np.eye(2) * 10, np.array([0.5, 0.5])
    got = model_bank(modes, y, x0, P0, mu0)
    assert got["mode_probs"][-1, true_mode] > 0.999
    assert np.mean(got["mode_probs"][100:, true_mode] > 0.99) > 0.95
    # no switching: each mode is its own Kalman filter, and c(t) multiplies out to the mixture
    # of the filters' whole likelihoods, p(Y) = sum_j mu_j(0) p(Y | mode j)
    each = [kalman_filter(d["F"], d["H"], d["Q"], d["R"], y, x0, P0) for d in modes]
    for j in range(2):
        assert_close(got["x_filt_modes"][j], each[j]["x_filt"], 1e-12)
        assert_close(got["P_filt_modes"][j], each[j]["P_filt"], 1e-12)
    logs = np.log(mu0) + np.array([e["loglik"] for e in each])
    assert got["loglik"] == pytest.approx(np.logaddexp.reduce(logs), rel=1e-12)
    logs_t = np.log(mu0) + np.cumsum([e["loglik_t"] for e in each], axis=1).T
    assert_close(got["mode_probs"], np.exp(logs_t - np.logaddexp.reduce(logs_t, axis=1, keepdims=True)), 1e-10)


def test_a_bank_of_different_sizes_has_no_combined_estimate():
    modes = cv_modes()[:1] + [dict(F=1.0, H=1.0, Q=1.0, R=1.0)]
    y = simulate_manoeuvre(1)
    got = model_bank(modes, y, [np.zeros(2), np.zeros(1)], [np.eye(2), np.eye(1)], [0.5, 0.5])
    assert all(got[k] is None for k in ("x_filt", "P_filt", "x_pred", "P_pred"))
    assert got["x_filt_modes"][0].shape == (len(y), 2) and got["x_filt_modes"][1].shape == (len(y), 1)
    assert_close(got["mode_probs"].sum(axis=1), np.ones(len(y)), 1e-12)
    walk = kalman_filter(np.eye(1), np.eye(1), np.eye(1), np.eye(1), y, np.zeros(1), np.eye(1))
    assert_close(got["x_filt_modes"][1], walk["x_filt"], 1e-12)
    assert np.ptp(got["mode_probs"][:, 1]) > 0.5
    with pytest.raises(ValueError, match="state_maps"):
        imm_filter(modes, TRANS, y, [np.zeros(2), np.zeros(1)], [np.eye(2), np.eye(1)], [0.5, 0.5])


# ----------------------------------------------------------------------------------------------
# Söderström Example 9.2
# ----------------------------------------------------------------------------------------------


def rmse(est, xs):
    return float(np.sqrt(np.mean((est[:, 0] - xs) ** 2)))


@pytest.mark.parametrize("seed", [92, 93, 94])
def test_example_9_2_tracks_the_switching_system(seed):
    """The IMM tracks nearly as well as a Kalman filter that knows the mode at each step, far
    better than either fixed-mode filter, and mu_1 follows the true mode. Over seeds 0-29 the
    ratios were IMM / mode-aware 1.00-1.14, IMM / fixed M1 0.21-0.26, IMM / fixed M2 0.15-0.20,
    and mu_1 sided with the true mode on at least 92% of its steps."""
    case, modes, u, y, xs, true_mode = example_9_2(seed)
    x0, P0 = np.array([case["x0"]]), np.array([[case["P0"]]])
    res = imm_filter(modes, case["transition"], y, x0, P0, case["mode_probs"], u=u)
    imm = rmse(res["x_filt"], xs)
    H, R = np.eye(1), np.array([[case["R"]]])
    fixed = []
    for d in modes:
        F, B, Q = (np.array([[d[k]]]) for k in "FBQ")
        fixed.append(rmse(kalman_filter(F, H, Q, R, y, x0, P0, B=B, u=u)["x_filt"], xs))
    # the time-varying filter that knows the mode: per-step stacks F[t], B[t], Q[t] (T, 1, 1)
    F, B, Q = (np.array([[[modes[j][k]]] for j in true_mode]) for k in "FBQ")
    aware = rmse(kalman_filter(F, H, Q, R, y, x0, P0, B=B, u=u)["x_filt"], xs)
    assert imm <= 1.3 * aware, (imm, aware)
    assert imm < 0.4 * min(fixed), (imm, fixed)
    mu1 = res["mode_probs"][:, 0]
    assert np.mean(mu1[true_mode == 0] > 0.5) > 0.85
    assert np.mean(mu1[true_mode == 1] < 0.5) > 0.85
    assert np.isfinite(res["loglik"])


# ----------------------------------------------------------------------------------------------
# The Gaussian-sum filter
# ----------------------------------------------------------------------------------------------


def linear_functions(F, H):
    return (lambda x: F @ x), (lambda x: H @ x), (lambda x: F), (lambda x: H)


@pytest.mark.parametrize("r", [1, 3])
def test_gaussian_sum_of_identical_components_is_the_kalman_filter(r):
    c = random_case(6, 3, 2, T=40, missing="partial")
    F, H, Q, R = (c.model[k] for k in "FHQR")
    want = kalman_filter(F, H, Q, R, c.y, c.x0, c.P0)
    got = gaussian_sum_filter(*linear_functions(F, H), Q, R, c.y, [c.x0] * r, [c.P0] * r, np.full(r, 1 / r))
    for name in ("x_filt", "P_filt", "x_pred", "P_pred", "loglik_t"):
        assert_close(got[name], want[name], 1e-12, name)
    assert_close(got["weights"], np.full((len(c.y), r), 1 / r), 1e-12)
    assert_close(got["means"][:, -1], want["x_filt"], 1e-12)


def test_gaussian_sum_on_a_linear_model_is_the_exact_mixture_posterior():
    """With linear f and h each component is a Kalman filter from its own prior, and the
    weights are the prior weights times each filter's whole likelihood: the exact posterior."""
    c = random_case(7, 2, 1, T=30, missing="rows")
    F, H, Q, R = (c.model[k] for k in "FHQR")
    means = np.array([c.x0, c.x0 + 3.0, c.x0 - [2.0, 0.0]])
    covs = np.array([c.P0, 2 * c.P0, np.eye(2)])
    alpha0 = np.array([0.2, 0.3, 0.5])
    got = gaussian_sum_filter(*linear_functions(F, H), Q, R, c.y, means, covs, alpha0)
    each = [kalman_filter(F, H, Q, R, c.y, mu, P) for mu, P in zip(means, covs)]
    for i in range(3):
        assert_close(got["means"][:, i], each[i]["x_filt"], 1e-12)
    logs_t = np.log(alpha0) + np.cumsum([e["loglik_t"] for e in each], axis=1).T
    weights = np.exp(logs_t - np.logaddexp.reduce(logs_t, axis=1, keepdims=True))
    assert_close(got["weights"], weights, 1e-10)
    assert got["loglik"] == pytest.approx(np.logaddexp.reduce(logs_t[-1]), rel=1e-12)
    x = np.einsum("ti,tin->tn", weights, got["means"])
    assert_close(got["x_filt"], x, 1e-10)
    d = got["means"] - x[:, None, :]
    P = sum(weights[:, i, None, None] * (each[i]["P_filt"] + np.einsum("ti,tj->tij", d[:, i], d[:, i])) for i in range(3))
    assert_close(got["P_filt"], P, 1e-10)
    assert np.max(np.abs(got["weights"][-1] - alpha0)) > 0.3  # the data do tell the components apart


def test_gaussian_sum_keeps_both_signs_of_a_sign_blind_measurement():
    """y = x^2 / 20 cannot tell x from -x: a prior of two mirrored components stays mirrored,
    the weights stay 1/2 and the mixture mean at 0, while each component follows |x|."""
    rng = np.random.default_rng(0)
    x, ys, xs = 4.0, [], []
    for _ in range(30):
        xs.append(x)
        ys.append(x**2 / 20 + np.sqrt(0.1) * rng.standard_normal())
        x = 0.9 * x + np.sqrt(0.05) * rng.standard_normal()
    got = gaussian_sum_filter(
        lambda x: 0.9 * x, lambda x: x**2 / 20, lambda x: np.array([[0.9]]), lambda x: np.array([[x[0] / 10]]),
        np.array([[0.05]]), np.array([[0.1]]), np.array(ys)[:, None], [[-4.0], [4.0]], [[[1.0]], [[1.0]]], [0.5, 0.5],
    )
    assert_close(got["means"][:, 0], -got["means"][:, 1], 1e-12)
    assert_close(got["weights"], np.full((30, 2), 0.5), 1e-12)
    assert_close(got["x_filt"], np.zeros((30, 1)), 1e-12)
    assert np.mean(np.abs(got["means"][:, 1, 0] - np.abs(xs))) < 1.0
    assert_psd(got["P_filt"])


# ----------------------------------------------------------------------------------------------
# Modes of different state sizes
# ----------------------------------------------------------------------------------------------

UP = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])  # [p, v] -> [p, v, a]
DOWN = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # [p, v, a] -> [p, v]


def ca_mode(q_a, a_dynamics=1.0):
    F = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, a_dynamics]])
    return dict(F=F, H=np.array([[1.0, 0.0, 0.0]]), Q=q_a, R=np.array([[1.0]]))


def test_state_maps_run_a_constant_velocity_and_a_constant_acceleration_mode():
    cv = cv_modes()[0]
    ca = ca_mode(np.diag([1e-6, 1e-6, 0.5]))
    y = simulate_manoeuvre(8, missing=0.05)
    maps = {(0, 1): (UP, np.zeros(3), np.diag([0.0, 0.0, 2.0])), (1, 0): DOWN}
    got = imm_filter([cv, ca], TRANS, y, np.zeros(2), np.diag([10.0, 4.0]), [0.5, 0.5], state_maps=maps)
    for name in ("x_filt", "x_pred", "loglik_t"):
        assert np.all(np.isfinite(got[name])), name
    for P in (got["P_filt"], got["P_pred"], *got["P_filt_modes"]):
        assert_psd(P)
    assert got["x_filt_modes"][1].shape == (len(y), 3)
    assert_close(got["mode_probs"].sum(axis=1), np.ones(len(y)), 1e-12)
    # the prior of mode 1 is mode 0's mapped: a(0|-1) = 0 with variance Sigma_aa = 2
    first = imm_filter([cv, ca], TRANS, y[:1], np.zeros(2), np.diag([10.0, 4.0]), [0.5, 0.5], state_maps=maps)
    assert first["P_filt_modes"][1][0, 2, 2] == pytest.approx(2.0)  # a is not seen by one y
    # the quiet mode holds the quiet start; the acceleration mode gains in the manoeuvre (40 <= t < 70)
    quiet, manoeuvre = np.mean(got["mode_probs"][5:40, 1]), np.mean(got["mode_probs"][45:70, 1])
    assert quiet < 0.3 and manoeuvre > quiet + 0.2, (quiet, manoeuvre)


def test_a_zero_acceleration_mode_is_the_constant_velocity_mode():
    """a held at 0 exactly (no dynamics, no noise, Sigma = 0): the 3-state mode is the 2-state
    one, and the IMM with maps equals the IMM of the same-size modes."""
    cv0, cv1 = cv_modes()
    Qa = np.zeros((3, 3))
    Qa[:2, :2] = cv1["Q"]
    ca = ca_mode(Qa, a_dynamics=0.0)
    y = simulate_manoeuvre(9, missing=0.05)
    x0, P0 = np.zeros(2), np.diag([10.0, 4.0])
    maps = {(0, 1): (UP, np.zeros(3), np.zeros((3, 3))), (1, 0): DOWN}
    got = imm_filter([cv0, ca], TRANS, y, x0, P0, [0.4, 0.6], state_maps=maps)
    want = imm_filter([cv0, cv1], TRANS, y, x0, P0, [0.4, 0.6])
    for name in ("x_filt", "P_filt", "x_pred", "P_pred", "mode_probs", "loglik_t"):
        assert_close(got[name], want[name], 1e-10, name)
    assert_close(got["x_filt_modes"][1][:, :2], want["x_filt_modes"][1], 1e-10)
    assert np.all(got["x_filt_modes"][1][:, 2] == 0.0)
    # the same with the modes' priors given one by one
    per_mode = imm_filter([cv0, ca], TRANS, y, [x0, UP @ x0], [P0, UP @ P0 @ UP.T], [0.4, 0.6], state_maps=maps)
    assert_close(per_mode["x_filt"], want["x_filt"], 1e-10)
