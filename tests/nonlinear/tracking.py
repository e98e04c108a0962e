"""A nonlinear tracking model for the tests, written in NumPy: a coordinated turn (n = 5, state
(px, py, vx, vy, omega)) seen by a range-bearing sensor at the origin (the benchmarks' CT
workload), and data simulated from it."""

import numpy as np

DT = 0.1


def ct_one(x):
    px, py, vx, vy, w = x
    s, c = np.sin(w * DT), np.cos(w * DT)
    if abs(w) < 1e-9:
        return np.array([px + DT * vx, py + DT * vy, vx, vy, w])
    return np.array(
        [px + s / w * vx - (1 - c) / w * vy, py + (1 - c) / w * vx + s / w * vy, c * vx - s * vy, s * vx + c * vy, w]
    )


def ct_jac_one(x):
    """The coordinated turn's Jacobian in closed form (omega != 0)."""
    _, _, vx, vy, w = x
    S, C = np.sin(w * DT), np.cos(w * DT)
    s, c = S / w, (1 - C) / w
    ds, dc = (w * DT * C - S) / w**2, (w * DT * S - (1 - C)) / w**2
    return np.array(
        [
            [1, 0, s, -c, ds * vx - dc * vy],
            [0, 1, c, s, dc * vx + ds * vy],
            [0, 0, C, -S, -DT * (S * vx + C * vy)],
            [0, 0, S, C, DT * (C * vx - S * vy)],
            [0, 0, 0, 0, 1.0],
        ]
    )


def ct_jac(X, t, u):
    return np.array([ct_jac_one(x) for x in X])


def ct(X, t, u):
    return np.array([ct_one(x) for x in X])


def range_bearing(X, t, u):
    return np.stack([np.hypot(X[:, 0], X[:, 1]), np.arctan2(X[:, 1], X[:, 0])], axis=1)


def range_bearing_jac(X, t, u):
    J = np.zeros((len(X), 2, 5))
    r2 = X[:, 0] ** 2 + X[:, 1] ** 2
    r = np.sqrt(r2)
    J[:, 0, 0], J[:, 0, 1] = X[:, 0] / r, X[:, 1] / r
    J[:, 1, 0], J[:, 1, 1] = -X[:, 1] / r2, X[:, 0] / r2
    return J


def ct_problem(T=40, seed=7):
    q, sigma_w = 1.0, 0.05
    Qpv = q * np.array([[DT**3 / 3, DT**2 / 2], [DT**2 / 2, DT]])
    Q = np.zeros((5, 5))
    Q[np.ix_([0, 2], [0, 2])] = Qpv
    Q[np.ix_([1, 3], [1, 3])] = Qpv
    Q[4, 4] = sigma_w**2 * DT
    R = np.diag([1.0, np.deg2rad(0.5) ** 2])
    x0 = np.array([100.0, 50.0, 5.0, -2.0, 0.1])
    P0 = np.diag([100.0, 100.0, 4.0, 4.0, 0.01])
    rng = np.random.default_rng(seed)
    x = rng.multivariate_normal(x0, P0)
    y = np.zeros((T, 2))
    for t in range(T):
        y[t] = range_bearing(x[None], t, None)[0] + rng.multivariate_normal(np.zeros(2), R)
        x = ct_one(x) + rng.multivariate_normal(np.zeros(5), Q)
    return Q, R, y, x0, P0
