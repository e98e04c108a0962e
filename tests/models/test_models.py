"""The stochastic-process model catalogue (kfast.models; docs/algorithms.md, "Model catalogue").

Stationary models: the sample autocovariance of one long simulated path, started from the
stationary covariance (scipy's discrete Lyapunov solver), matches the stated closed form within
a few Monte-Carlo standard errors (Bartlett's formula). Nonstationary models: the stated
covariance functions against many replicated short paths.
"""

import math

import numpy as np
import pytest
from scipy.linalg import expm as scipy_expm
from scipy.linalg import solve_discrete_lyapunov, toeplitz

import kfast
import kfast.models as km

NSE = 5.0  # tolerance in Monte-Carlo standard errors


def stationary_cov(model):
    P = solve_discrete_lyapunov(model.F, model.Q)
    return (P + P.T) / 2


def sample_acov(y, K):
    """Autocovariance estimates at lags 0..K of a zero-mean series (the mean is known)."""
    T = len(y)
    return np.array([np.dot(y[k:], y[: T - k]) / (T - k) for k in range(K + 1)])


def bartlett_se(r, K, T):
    """Standard errors of the zero-mean autocovariance estimates at lags 0..K of a Gaussian
    process with autocovariance r(0), r(1), ... (len(r) > 2K, decayed by the end):
    var = (1/T) Σ_j [r(j)² + r(j+k) r(j−k)]."""
    L = len(r) - K - 1
    j = np.arange(-L, L + 1)
    full = lambda i: r[np.abs(i)]  # noqa: E731
    return np.array([math.sqrt(np.sum(full(j) ** 2 + full(j + k) * full(j - k)) / (T - k)) for k in range(K + 1)])


def check_acov(y, r_theory, K):
    """r_theory: the autocovariance at lags 0..len-1 (long enough to have decayed)."""
    T = len(y)
    est = sample_acov(y, K)
    se = bartlett_se(r_theory, K, T)
    err = np.abs(est - r_theory[: K + 1]) / se
    assert err.max() < NSE, f"lag {err.argmax()}: {est[err.argmax()]} vs {r_theory[err.argmax()]} ({err.max():.2f} SE)"


def simulate_stationary(model, T, seed):
    P = stationary_cov(model)
    return model.simulate(T, np.zeros(model.n_states), P, seed=seed)


def replicate(model, P0, T, reps, seed):
    """States and outputs of `reps` independent paths, shapes (reps, T, n) and (reps, T, m)."""
    rng = np.random.default_rng(seed)
    xs, ys = [], []
    for _ in range(reps):
        sim = model.simulate(T, np.zeros(model.n_states), P0, seed=rng)
        xs.append(sim.x)
        ys.append(sim.y)
    return np.array(xs), np.array(ys)


def check_cov_matrix(samples_a, samples_b, C_theory, var_a, var_b):
    """Sample E[a b'] (zero-mean, over axis 0) against C_theory; var_a/var_b are the variances
    of the components (for the standard error sqrt((var_a var_b + C²)/N))."""
    N = samples_a.shape[0]
    est = np.einsum("ri,rj->ij", samples_a, samples_b) / N
    se = np.sqrt((np.outer(var_a, var_b) + C_theory**2) / N) + 1e-300
    err = np.abs(est - C_theory) / se
    assert err.max() < NSE, f"{est} vs {C_theory} ({err.max():.2f} SE)"


# --------------------------------------------------------------------------------------------
# stationary models: sample autocovariance vs the closed form


def test_gauss_markov_1_autocovariance():
    s2, beta, dt, r = 2.0, 0.8, 0.1, 0.5
    m = km.gauss_markov_1(s2, beta, dt, r=r)
    assert m.F[0, 0] == pytest.approx(math.exp(-beta * dt), rel=1e-15)
    assert m.Q[0, 0] == pytest.approx(s2 * (1 - math.exp(-2 * beta * dt)), rel=1e-14)
    assert stationary_cov(m)[0, 0] == pytest.approx(s2, rel=1e-12)
    cm = km.continuous("gauss_markov_1", sigma2=s2, beta=beta)
    F, Qd, _ = kfast.discretize(cm.A, cm.Qc, dt)
    np.testing.assert_allclose(m.F, F, rtol=1e-14)
    np.testing.assert_allclose(m.Q, Qd, rtol=1e-12)
    lags = np.arange(400) * dt
    r_y = km.gauss_markov_1_autocovariance(lags, s2, beta, r=r)
    np.testing.assert_allclose(r_y[1:], s2 * np.exp(-beta * dt) ** np.arange(1, 400), rtol=1e-12)
    assert r_y[0] == pytest.approx(s2 + r)
    y = simulate_stationary(m, 400_000, seed=11).y[:, 0]
    check_acov(y, r_y, 30)


@pytest.mark.parametrize("zeta", [0.2, 1.0, 2.5])
def test_gauss_markov_2_autocovariance(zeta):
    wn, q, dt, r = 1.5, 2.0, 0.2, 0.3
    m = km.gauss_markov_2(wn, zeta, q, dt, r=r)
    P = stationary_cov(m)
    np.testing.assert_allclose(P, np.diag([q / (4 * zeta * wn**3), q / (4 * zeta * wn)]), rtol=1e-10, atol=1e-12)
    lags = np.arange(600) * dt
    r_y = km.gauss_markov_2_autocovariance(lags, wn, zeta, q, r=r)
    # against the state-space form H F^k P H' (+ R at lag 0)
    Fk = np.eye(2)
    direct = []
    for _ in range(40):
        direct.append((Fk @ P)[0, 0])
        Fk = Fk @ m.F
    direct[0] += r
    np.testing.assert_allclose(r_y[:40], direct, rtol=1e-9, atol=1e-12)
    y = simulate_stationary(m, 200_000, seed=12).y[:, 0]
    check_acov(y, r_y, 40)


def test_gauss_markov_2_near_critical_damping_is_continuous():
    lags = np.linspace(0, 10, 51)
    crit = km.gauss_markov_2_autocovariance(lags, 1.3, 1.0, 1.0)
    for z in (1 - 1e-7, 1 + 1e-7):
        np.testing.assert_allclose(km.gauss_markov_2_autocovariance(lags, 1.3, z, 1.0), crit, rtol=1e-5, atol=1e-12)


def test_damped_resonator_autocovariance():
    omega, tau, q, dt, r = 2.0, 3.0, 1.0, 0.1, 0.01
    m = km.damped_resonator(omega, tau, q, dt, r=r)
    P = stationary_cov(m)
    np.testing.assert_allclose(P, np.diag([q * tau / (4 * (omega**2 + 1 / tau**2)), q * tau / 4]), rtol=1e-10, atol=1e-13)
    lags = np.arange(1500) * dt
    r_y = km.damped_resonator_autocovariance(lags, omega, tau, q, r=r)
    # the same process as gauss_markov_2 with omega_n^2 = omega^2 + 1/tau^2, zeta omega_n = 1/tau
    wn = math.sqrt(omega**2 + 1 / tau**2)
    np.testing.assert_allclose(r_y, km.gauss_markov_2_autocovariance(lags, wn, 1 / (tau * wn), q, r=r), rtol=1e-10, atol=1e-14)
    y = simulate_stationary(m, 200_000, seed=13).y[:, 0]
    check_acov(y, r_y, 60)


def test_singer_acceleration_autocovariance_and_qd():
    dt, alpha, s2 = 0.5, 0.4, 3.0
    m = km.singer(dt, alpha, s2, r=1.0)
    assert m.Q[2, 2] == pytest.approx(s2 * (1 - math.exp(-2 * alpha * dt)), rel=1e-12)
    # Qd against quadrature of e^{As} Qc e^{A's} over [0, dt] (Simpson, independent of Van Loan)
    A = np.array([[0, 1, 0], [0, 0, 1], [0, 0, -alpha]], float)
    Qc = np.diag([0, 0, 2 * alpha * s2])
    s = np.linspace(0, dt, 401)
    vals = np.array([scipy_expm(A * si) @ Qc @ scipy_expm(A * si).T for si in s])
    w = np.ones(len(s))
    w[1:-1:2], w[2:-1:2] = 4, 2
    quad = np.einsum("i,ijk->jk", w, vals) * (s[1] - s[0]) / 3
    np.testing.assert_allclose(m.Q, quad, rtol=1e-9)
    np.testing.assert_allclose(m.F, scipy_expm(A * dt), rtol=1e-13, atol=1e-15)
    # 2-D: block structure, derivative-major
    m2 = km.singer(dt, alpha, s2, dim=2, observe=(0, 2))
    np.testing.assert_allclose(m2.Q, np.kron(m.Q, np.eye(2)))
    np.testing.assert_allclose(m2.H, np.eye(6)[[0, 1, 4, 5]])
    # the acceleration is stationary GM1: simulate the acceleration-observed model from a
    # covariance that is stationary in the acceleration (the position part is irrelevant)
    ma = km.singer(dt, alpha, s2, r=0.0, observe=2)
    P0 = np.diag([1.0, 1.0, s2])
    y = ma.simulate(100_000, np.zeros(3), P0, seed=14).y[:, 0]
    r_a = km.singer_autocovariance(np.arange(300) * dt, alpha, s2)
    check_acov(y, r_a, 25)


@pytest.mark.parametrize("coeffs", [[-0.6], [-1.2, 0.5], [-0.5, 0.3, 0.1]])
def test_ar_companion(coeffs):
    lam2, r = 1.7, 0.4
    p = len(coeffs)
    m = km.ar(coeffs, lam2, r=r)
    assert m.F[0].tolist() == [-c for c in coeffs]
    assert m.Q[0, 0] == lam2 and np.count_nonzero(m.Q) == 1
    r_k = km.ar_autocovariance(np.arange(400), coeffs, lam2)
    # stationary covariance = Toeplitz matrix of r(0..p-1)
    np.testing.assert_allclose(stationary_cov(m), toeplitz(r_k[:p]), rtol=1e-10)
    # the recursion r(k) = -sum a_i r(k-i) holds at every lag >= 1
    for k in range(1, 20):
        assert r_k[k] == pytest.approx(-sum(a * r_k[abs(k - i - 1)] for i, a in enumerate(coeffs)), abs=1e-12)
    # spectrum route: r(k) = (1/2pi) ∫ lam2 / |A(e^{iw})|^2 e^{iwk} dw (no 1/2pi in phi)
    w = np.linspace(-np.pi, np.pi, 4097)[:-1]
    A = 1 + sum(a * np.exp(-1j * w * (i + 1)) for i, a in enumerate(coeffs))
    phi = lam2 / np.abs(A) ** 2
    r_fft = np.array([np.mean(phi * np.cos(w * k)) for k in range(6)])
    np.testing.assert_allclose(r_k[:6], r_fft, rtol=1e-8, atol=1e-10)
    # simulation, with measurement noise r at lag 0
    y = simulate_stationary(m, 100_000, seed=15).y[:, 0]
    r_y = r_k + r * (np.arange(400) == 0)
    assert km.ar_autocovariance(0, coeffs, lam2, r=r) == pytest.approx(r_y[0])
    check_acov(y, r_y, 25)


def test_ar_zero_measurement_noise_filters():
    m = km.ar([-0.5, 0.2], 1.0)
    assert m.R[0, 0] == 0.0
    y = m.simulate(50, np.zeros(2), stationary_cov(m), seed=3).y
    res = m.filter(y, np.zeros(2), stationary_cov(m))
    assert np.isfinite(res.loglik)


# --------------------------------------------------------------------------------------------
# nonstationary models: covariance functions over replicated paths


def test_random_walk_covariance():
    dt, q, r, P0 = 0.5, 0.8, 0.3, 1.5
    m = km.random_walk(dt, q, r)
    assert (m.F[0, 0], m.Q[0, 0], m.R[0, 0]) == (1.0, q * dt, r)
    T = 12
    x, y = replicate(m, P0, T, 4000, seed=21)
    k = np.arange(T)
    C = P0 + q * dt * np.minimum.outer(k, k)
    check_cov_matrix(x[:, :, 0], x[:, :, 0], C, np.diag(C), np.diag(C))
    Cy = C + r * np.eye(T)
    check_cov_matrix(y[:, :, 0], y[:, :, 0], Cy, np.diag(Cy), np.diag(Cy))


def test_random_constant_covariance():
    m = km.random_constant(r=0.5)
    assert (m.F[0, 0], m.Q[0, 0]) == (1.0, 0.0)
    x, y = replicate(m, 2.0, 6, 4000, seed=22)
    assert np.all(x[:, :, 0] == x[:, :1, 0])  # constant along each path
    Cy = 2.0 + 0.5 * np.eye(6)
    check_cov_matrix(y[:, :, 0], y[:, :, 0], Cy, np.diag(Cy), np.diag(Cy))


def test_random_ramp_covariance():
    dt = 0.4
    P0 = np.array([[1.0, 0.3], [0.3, 0.5]])
    m = km.random_ramp(dt, r=0.2)
    np.testing.assert_array_equal(m.F, [[1, dt], [0, 1]])
    assert not np.any(m.Q)
    x, _ = replicate(m, P0, 10, 3000, seed=23)
    t = np.arange(10) * dt
    C = P0[0, 0] + P0[0, 1] * np.add.outer(t, t) + P0[1, 1] * np.outer(t, t)
    check_cov_matrix(x[:, :, 0], x[:, :, 0], C, np.diag(C), np.diag(C))
    both = km.random_ramp(dt, observe=(0, 1))
    np.testing.assert_array_equal(both.H, np.eye(2))


def cv_cov(t, s, q, P0):
    """Per-axis Cov(x(t), x(s)) of constant velocity (docstring formula), t >= s."""
    Phi = lambda u: np.array([[1, u], [0, 1]])  # noqa: E731
    noise = q * np.array([[t * s**2 / 2 - s**3 / 6, t * s - s**2 / 2], [s**2 / 2, s]])
    return Phi(t) @ P0 @ Phi(s).T + noise


def test_constant_velocity_matches_cv_model_and_closed_form():
    dt, q = 0.1, 1.0
    m = km.constant_velocity(2, dt, q=q, r=1.0)
    I2 = np.eye(2)
    np.testing.assert_array_equal(m.F, [[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]])
    np.testing.assert_array_equal(m.H, [[1, 0, 0, 0], [0, 1, 0, 0]])
    Q = q * np.block([[dt**3 / 3 * I2, dt**2 / 2 * I2], [dt**2 / 2 * I2, dt * I2]])
    np.testing.assert_allclose(m.Q, Q, rtol=1e-15)
    np.testing.assert_array_equal(m.R, I2)
    from kfast.cli import constant_velocity_2d

    demo = constant_velocity_2d()
    for name in "FHQR":
        np.testing.assert_allclose(getattr(m, name), getattr(demo, name), rtol=1e-15)
    # closed form = Van Loan, 1-3 axes, per-axis q
    for dim in (1, 2, 3):
        qa = np.arange(1, dim + 1) * 0.7
        md = km.constant_velocity(dim, 0.3, q=qa)
        cm = km.continuous("constant_velocity", dim=dim, q=qa)
        F, Qd, _ = kfast.discretize(cm.A, cm.Qc, 0.3)
        np.testing.assert_allclose(md.F, F, rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(md.Q, Qd, rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(md.H, cm.H)
    assert km.constant_velocity(3, 0.1, observe=(0, 1)).H.shape == (6, 6)


def test_constant_velocity_covariance_function():
    dt, q = 0.5, 2.0
    P0 = np.array([[1.0, 0.2], [0.2, 0.5]])
    m = km.constant_velocity(1, dt, q=q)
    T = 8
    x, _ = replicate(m, P0, T, 4000, seed=24)
    k, l = T - 1, 3
    C = cv_cov(k * dt, l * dt, q, P0)
    Ck, Cl = cv_cov(k * dt, k * dt, q, P0), cv_cov(l * dt, l * dt, q, P0)
    check_cov_matrix(x[:, k], x[:, l], C, np.diag(Ck), np.diag(Cl))
    check_cov_matrix(x[:, l], x[:, l], Cl, np.diag(Cl), np.diag(Cl))
    # exact: the recursion of the discrete model reproduces the formula
    P = P0.copy()
    for _ in range(l):
        P = m.F @ P @ m.F.T + m.Q
    np.testing.assert_allclose(np.linalg.matrix_power(m.F, k - l) @ P, C, rtol=1e-12)


def test_constant_acceleration_closed_form_and_covariance():
    h, q = 0.25, 1.3
    m = km.constant_acceleration(1, h, q=q)
    Q = q * np.array([[h**5 / 20, h**4 / 8, h**3 / 6], [h**4 / 8, h**3 / 3, h**2 / 2], [h**3 / 6, h**2 / 2, h]])
    np.testing.assert_allclose(m.Q, Q, rtol=1e-15)
    np.testing.assert_allclose(m.F, [[1, h, h * h / 2], [0, 1, h], [0, 0, 1]])
    for dim in (1, 2, 3):
        md = km.constant_acceleration(dim, h, q=q, observe=(0, 2))
        cm = km.continuous("constant_acceleration", dim=dim, q=q, observe=(0, 2))
        F, Qd, _ = kfast.discretize(cm.A, cm.Qc, h)
        np.testing.assert_allclose(md.F, F, rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(md.Q, Qd, rtol=1e-12, atol=1e-16)
        np.testing.assert_array_equal(md.H, cm.H)
        assert md.H.shape == (2 * dim, 3 * dim)
    P0 = np.diag([1.0, 0.5, 0.2])
    T = 8
    x, _ = replicate(m, P0, T, 4000, seed=25)
    P = [P0]
    for _ in range(T - 1):
        P.append(m.F @ P[-1] @ m.F.T + m.Q)
    k, l = T - 1, 2
    C = np.linalg.matrix_power(m.F, k - l) @ P[l]
    check_cov_matrix(x[:, k], x[:, l], C, np.diag(P[k]), np.diag(P[l]))


# --------------------------------------------------------------------------------------------
# damped resonator closed forms (G&A ex. 4.9)


def test_damped_resonator_closed_form_equals_van_loan():
    for omega, tau, q, dt in [(2.0, 3.0, 1.0, 0.1), (0.7, 0.5, 2.5, 0.3), (5.0, 10.0, 0.3, 1.7), (1.0, 1.0, 1.0, 0.05)]:
        m = km.damped_resonator(omega, tau, q, dt)
        cm = km.continuous("damped_resonator", omega=omega, tau=tau, q=q)
        F, Qd, _ = kfast.discretize(cm.A, cm.Qc, dt)
        np.testing.assert_allclose(m.F, F, atol=1e-12, rtol=1e-12)
        np.testing.assert_allclose(m.Q, Qd, atol=1e-12, rtol=1e-10)


def test_damped_resonator_grewal_andrews_example_4_9():
    # G&A: omega_r = 2 (damped frequency), omega_d = 1/tau = 1/3 (damping rate),
    # A = [[0, 1], [-(omega_r^2 + omega_d^2), -2 omega_d]], q = 1, dt = 0.1
    m = km.damped_resonator(omega=2.0, tau=3.0, q=1.0, dt=0.1)
    expected = np.array([[3.14589889e-4, 4.615499469e-3], [4.615499469e-3, 9.2369208819e-2]])
    np.testing.assert_allclose(m.Q, expected, rtol=1e-9)
    A = np.array([[0, 1], [-(4 + 1 / 9), -2 / 3]])
    np.testing.assert_allclose(m.F, scipy_expm(A * 0.1), rtol=1e-13)


# --------------------------------------------------------------------------------------------
# coloured noise


def test_augment_measurement_noise_gauss_markov_1():
    dt = 0.2
    plant = km.gauss_markov_2(1.2, 0.4, 1.0, dt, r=0.1)
    s2, beta = 0.6, 0.5
    shaping = km.gauss_markov_1(s2, beta, dt, r=0.0)
    m = km.augment(plant, shaping, where="measurement")
    np.testing.assert_allclose(m.F, [[*plant.F[0], 0], [*plant.F[1], 0], [0, 0, shaping.F[0, 0]]])
    np.testing.assert_allclose(m.H, [[1, 0, 1]])
    np.testing.assert_allclose(m.R, plant.R)
    np.testing.assert_allclose(m.Q[2, 2], shaping.Q[0, 0])
    assert m.N is None
    P = stationary_cov(m)
    lags = np.arange(800) * dt
    r_y = km.gauss_markov_2_autocovariance(lags, 1.2, 0.4, 1.0, r=0.1) + km.gauss_markov_1_autocovariance(lags, s2, beta)
    # H Pi H' + the shaping autocorrelation, at lag 0
    assert r_y[0] == pytest.approx((m.H @ P @ m.H.T + m.R)[0, 0], rel=1e-10)
    y = m.simulate(100_000, np.zeros(3), P, seed=31).y[:, 0]
    check_acov(y, r_y, 40)
    # purely coloured measurement noise (R = 0) still filters
    m0 = km.augment(plant, shaping, "measurement", R=0.0)
    assert m0.R[0, 0] == 0.0
    assert np.isfinite(m0.filter(y[:200], np.zeros(3), P).loglik)


def test_augment_process_noise_structure():
    plant = km.constant_velocity(1, 0.1, q=0.0, r=1.0)
    shaping = km.gauss_markov_1(1.0, 2.0, 0.1, r=0.0)
    gamma = [[0.0], [1.0]]
    m = km.augment(plant, shaping, "process", gamma=gamma)
    F = np.zeros((3, 3))
    F[:2, :2] = plant.F
    F[1, 2] = 1.0
    F[2, 2] = shaping.F[0, 0]
    np.testing.assert_allclose(m.F, F)
    np.testing.assert_allclose(m.Q, np.diag([0, 0, shaping.Q[0, 0]]), atol=1e-300)
    np.testing.assert_allclose(m.H, [[1, 0, 0]])
    # a shaping filter with white output noise adds Gamma R_s Gamma' to the white part
    m2 = km.augment(plant, km.gauss_markov_1(1.0, 2.0, 0.1, r=0.3), "process", gamma=gamma, Q=0.0)
    np.testing.assert_allclose(m2.Q[:2, :2], [[0, 0], [0, 0.3]])
    with pytest.raises(kfast.KfastError, match="gamma"):
        km.augment(plant, shaping, "process")
    with pytest.raises(kfast.KfastError, match="where"):
        km.augment(plant, shaping, "input")


def test_augment_continuous_process_noise_is_exact():
    """A first-order lag driven by GM1 noise: x' = -a x + w1, w1 ~ GM1(s2, beta). Its exact
    autocovariance is s2 beta/(beta² - a²) [e^{-a|t|}/a - e^{-beta|t|}/beta]; the jointly
    discretized model reproduces it exactly, the separately discretized one does not."""
    a, s2, beta, dt = 0.7, 1.5, 2.0, 0.5
    plant = km.Continuous(np.array([[-a]]), np.zeros((1, 1)), np.ones((1, 1)))
    shaping = km.continuous("gauss_markov_1", sigma2=s2, beta=beta)
    joint = km.augment_continuous(plant, shaping, "process", gamma=1.0).discretize(dt, r=0.0)
    k = np.arange(15)
    t = k * dt
    exact = s2 * beta / (beta**2 - a**2) * (np.exp(-a * t) / a - np.exp(-beta * t) / beta)
    P = stationary_cov(joint)
    got = [(np.linalg.matrix_power(joint.F, j) @ P)[0, 0] for j in k]
    np.testing.assert_allclose(got, exact, rtol=1e-10)
    assert joint.Q[0, 1] != 0 and joint.Q[0, 0] > 0  # the cross terms of the joint Qd
    separate = km.augment(plant.discretize(dt, r=0.0), km.gauss_markov_1(s2, beta, dt, r=0.0), "process", gamma=1.0)
    Ps = stationary_cov(separate)
    assert abs(Ps[0, 0] - exact[0]) > 1e-3 * exact[0]
    # measurement case: block diagonal, H = [H, H_s]
    cm = km.augment_continuous(plant, shaping, "measurement")
    np.testing.assert_allclose(cm.A, np.diag([-a, -beta]))
    np.testing.assert_allclose(cm.H, [[1, 1]])


# --------------------------------------------------------------------------------------------
# parameter checks


BAD = [
    (km.random_walk, dict(dt=0.0), "dt"),
    (km.random_walk, dict(dt=1.0, q=-1.0), "q"),
    (km.random_walk, dict(dt=1.0, r=-0.1), "r"),
    (km.random_walk, dict(dt=float("nan")), "dt"),
    (km.random_constant, dict(r=-1.0), "r"),
    (km.random_ramp, dict(dt=-1.0), "dt"),
    (km.random_ramp, dict(dt=1.0, observe=2), "observe"),
    (km.constant_velocity, dict(dim=0, dt=0.1), "dim"),
    (km.constant_velocity, dict(dim=2, dt=0.1, q=[1.0, -1.0]), "q"),
    (km.constant_velocity, dict(dim=2, dt=0.1, q=[1.0, 1.0, 1.0]), "q"),
    (km.constant_velocity, dict(dim=1, dt=-0.1), "dt"),
    (km.constant_velocity, dict(dim=1.5, dt=0.1), "dim"),
    (km.constant_acceleration, dict(dim=1, dt=0.1, q=-2.0), "q"),
    (km.constant_acceleration, dict(dim=1, dt=0.1, observe=3), "observe"),
    (km.gauss_markov_1, dict(sigma2=-1.0, beta=1.0, dt=0.1), "sigma2"),
    (km.gauss_markov_1, dict(sigma2=1.0, beta=0.0, dt=0.1), "beta"),
    (km.gauss_markov_1, dict(sigma2=1.0, beta=1.0, dt=0.0), "dt"),
    (km.gauss_markov_2, dict(omega_n=1.0, zeta=-0.5, q=1.0, dt=0.1), "zeta"),
    (km.gauss_markov_2, dict(omega_n=1.0, zeta=0.0, q=1.0, dt=0.1), "zeta"),
    (km.gauss_markov_2, dict(omega_n=-1.0, zeta=0.5, q=1.0, dt=0.1), "omega_n"),
    (km.gauss_markov_2, dict(omega_n=1.0, zeta=0.5, q=-1.0, dt=0.1), "q"),
    (km.damped_resonator, dict(omega=0.0, tau=1.0, q=1.0, dt=0.1), "omega"),
    (km.damped_resonator, dict(omega=1.0, tau=-1.0, q=1.0, dt=0.1), "tau"),
    (km.damped_resonator, dict(omega=1.0, tau=1.0, q=1.0, dt=0.0), "dt"),
    (km.singer, dict(dt=0.1, alpha=0.0, sigma_m2=1.0), "alpha"),
    (km.singer, dict(dt=0.1, alpha=1.0, sigma_m2=-1.0), "sigma_m2"),
    (km.singer, dict(dt=-0.1, alpha=1.0, sigma_m2=1.0), "dt"),
    (km.ar, dict(coeffs=[], noise_var=1.0), "coeffs"),
    (km.ar, dict(coeffs=[0.5, float("inf")], noise_var=1.0), "coeffs"),
    (km.ar, dict(coeffs=[0.5], noise_var=-1.0), "noise_var"),
    (km.ar, dict(coeffs=[0.5], noise_var=1.0, r=-1.0), "r"),
    (km.ar_autocovariance, dict(lags=[0, 1], coeffs=[-1.0], noise_var=1.0), "coeffs"),
    (km.ar_autocovariance, dict(lags=[0.5], coeffs=[-0.5], noise_var=1.0), "lags"),
    (km.gauss_markov_1_autocovariance, dict(lag=1.0, sigma2=-1.0, beta=1.0), "sigma2"),
    (km.gauss_markov_2_autocovariance, dict(lag=1.0, omega_n=1.0, zeta=-1.0, q=1.0), "zeta"),
    (km.continuous, dict(kind="nonsense"), "kind"),
]


@pytest.mark.parametrize("fn,kwargs,name", BAD, ids=[f"{f.__name__}-{n}-{i}" for i, (f, _, n) in enumerate(BAD)])
def test_bad_parameters_are_rejected(fn, kwargs, name):
    with pytest.raises(kfast.KfastError, match=rf"^{name}:"):
        fn(**kwargs)
