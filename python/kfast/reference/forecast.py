"""k-step forecasting in plain NumPy (Söderström (6.38)-(6.42)).

(x, P) is the one-step prediction x(t|t-1), P(t|t-1); row j forecasts step t + j.
"""

from __future__ import annotations

import numpy as np


def forecast(F, H, Q, R, x, P, steps, B=None, D=None, u=None):
    """Returns (x_mean, P, y_mean, y_cov), each with a leading axis of length `steps`."""
    n, m = len(x), H.shape[0]
    xs, Ps, ys, Ss = np.zeros((steps, n)), np.zeros((steps, n, n)), np.zeros((steps, m)), np.zeros((steps, m, m))
    x, P = np.asarray(x, float), np.asarray(P, float)
    for j in range(steps):
        xs[j], Ps[j] = x, P
        ys[j] = H @ x + (D @ u[j] if D is not None else 0)
        Ss[j] = H @ P @ H.T + R
        x = F @ x + (B @ u[j] if B is not None else 0)  # x(t+j+1|t-1) = F x(t+j|t-1) + B u(t+j)
        P = F @ P @ F.T + Q  # P(t+j+1|t-1) = F P F' + Q
    return xs, Ps, ys, Ss
