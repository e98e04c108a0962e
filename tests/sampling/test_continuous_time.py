"""Continuous-time models and their sampling: textbook cases D1 (G&A ex. 4.7) and D3 (the
resonator), Van Loan's discretization against closed forms and its small-dt limit, the input
matrix, irregular sampling (from_continuous with times / dt) and the Kalman-Bucy gain."""

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sl

import kfast

CASES = json.loads((Path(__file__).parent.parent / "data" / "textbook_cases.json").read_text())


def test_d1_first_order_markov_mean_and_variance():
    """G&A ex. 4.7: with a mean input E w = 1, m(t) = 1 - e^-t, P(t) = (1 - e^-2t)/2."""
    dt, steps = 0.05, 200
    model = kfast.LinearGaussian.from_continuous([[-1.0]], [[1.0]], [[1.0]], [[1.0]], dt=dt, B=[[1.0]])
    fc = model.forecast([0.0], [[0.0]], steps, u=np.ones((steps, 1)))
    t = dt * np.arange(steps)
    np.testing.assert_allclose(fc.x[:, 0], 1 - np.exp(-t), atol=1e-12)
    np.testing.assert_allclose(fc.P[:, 0, 0], (1 - np.exp(-2 * t)) / 2, atol=1e-12)
    assert kfast.stationary_cov_continuous([[-1.0]], [[1.0]]).item() == pytest.approx(0.5, rel=1e-14)


def resonator(c):
    wr, wd = c["wr"], c["wd"]
    return np.array([[0.0, 1.0], [-(wr**2 + wd**2), -2 * wd]]), np.diag([0.0, c["q"]])


def test_d3_van_loan_matches_the_resonator_numbers_and_closed_form():
    c = CASES["D3"]
    A, Qc = resonator(c)
    F, Qd, _ = kfast.discretize(A, Qc, c["dt"])
    np.testing.assert_allclose(Qd, c["Qd"], rtol=c["rtol"])
    np.testing.assert_allclose(F, sl.expm(A * c["dt"]), rtol=1e-13)
    # Closed form (docs/algorithms.md, "Damped resonator") with omega the damped frequency, 1/tau the damping rate.
    w, tau, q, h = np.sqrt(c["wr"] ** 2), 1 / c["wd"], c["q"], c["dt"]
    S, C, E = np.sin(w * h), np.cos(w * h), np.exp(-2 * h / tau)
    q11 = q * tau * (w**2 * tau**2 * (1 - E) - 2 * S * E * (S + w * tau * C)) / (4 * w**2 * (1 + w**2 * tau**2))
    q12 = q * E * S**2 / (2 * w**2)
    q22 = q * (w**2 * tau**2 * (1 - E) - 2 * S * E * (S - w * tau * C)) / (4 * w**2 * tau)
    np.testing.assert_allclose(Qd, [[q11, q12], [q12, q22]], rtol=1e-12)
    wr, wd = c["wr"], c["wd"]
    Pi = kfast.stationary_cov_continuous(A, Qc)
    np.testing.assert_allclose(Pi, np.diag([q / (4 * wd * (wr**2 + wd**2)), q / (4 * wd)]), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("h", [1e-2, 1e-3, 1e-4])
def test_van_loan_small_dt_tends_to_the_first_order_approximation(h):
    """Qd = Qc h + (A Qc + Qc A') h^2 / 2 + O(h^3) (docs/algorithms.md, "First-order approximation")."""
    c = CASES["D3"]
    A, Qc = resonator(c)
    _, Qd, _ = kfast.discretize(A, Qc, h)
    second = Qc * h + (A @ Qc + Qc @ A.T) * h**2 / 2
    assert np.abs(Qd - second).max() <= 10 * h**3 * np.abs(A).max() ** 2
    assert np.abs(Qd - Qc * h).max() <= h**2 * np.abs(A).max()


def test_discretize_input_matrix_and_stacks():
    A = np.array([[0.0, 1.0], [-2.0, -0.5]])
    B = np.array([[0.0], [1.0]])
    F, Qd, Bd = kfast.discretize(A, np.eye(2), 0.3, B=B)
    # Bd = A^-1 (F - I) B for invertible A
    np.testing.assert_allclose(Bd, np.linalg.solve(A, F - np.eye(2)) @ B, rtol=1e-12)
    Fs, Qs, Bs = kfast.discretize(A, np.eye(2), [0.3, 0.1, 0.3], B=B)
    assert Fs.shape == (3, 2, 2) and Bs.shape == (3, 2, 1)
    np.testing.assert_allclose(Fs[0], F, rtol=1e-14)
    np.testing.assert_allclose(Qs[2], Qd, rtol=1e-14)


def test_irregular_sampling_equals_stacked_per_step_matrices():
    c = CASES["D3"]
    A, Qc = resonator(c)
    rng = np.random.default_rng(0)
    times = np.cumsum(rng.uniform(0.01, 0.3, size=60))
    y = rng.standard_normal((60, 1))
    H, R = [[1.0, 0.0]], [[0.05]]
    model = kfast.LinearGaussian.from_continuous(A, Qc, H, R, times=times)
    dt = np.append(np.diff(times), np.diff(times)[-1])
    F = np.stack([sl.expm(A * d) for d in dt])
    Qd = np.stack([kfast.discretize(A, Qc, d).Qd for d in dt])
    stacked = kfast.LinearGaussian(F, H, Qd, R)
    a = model.filter(y, np.zeros(2), np.eye(2))
    b = stacked.filter(y, np.zeros(2), np.eye(2))
    np.testing.assert_allclose(a.x_filt, b.x_filt, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(a.P_filt, b.P_filt, rtol=1e-10, atol=1e-14)
    assert a.loglik == pytest.approx(b.loglik, rel=1e-12)
    same = kfast.LinearGaussian.from_continuous(A, Qc, H, R, dt=dt)
    np.testing.assert_allclose(same.F, model.F, rtol=1e-14)
    with pytest.raises(kfast.KfastError, match=r"^times at step 3: not strictly increasing"):
        kfast.LinearGaussian.from_continuous(A, Qc, H, R, times=[0, 1, 2, 2, 3])
    with pytest.raises(kfast.KfastError, match=r"^dt at step 1: must be positive"):
        kfast.LinearGaussian.from_continuous(A, Qc, H, R, dt=[0.1, 0.0, 0.2])


def test_kalman_bucy_gain():
    c = CASES["D3"]
    A, Qc = resonator(c)
    H, Rc = np.array([[1.0, 0.0]]), np.array([[0.1]])
    kb = kfast.kalman_bucy(A, Qc, H, Rc)
    P = sl.solve_continuous_are(A.T, H.T, Qc, Rc)
    np.testing.assert_allclose(kb.P, P, rtol=1e-10)
    np.testing.assert_allclose(kb.K, P @ H.T @ np.linalg.inv(Rc), rtol=1e-10)
    assert np.real(np.linalg.eigvals(A - kb.K @ H)).max() < 0
