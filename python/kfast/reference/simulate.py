"""The model's recursion driven by given noise, in plain NumPy (the oracle for simulation)."""

from __future__ import annotations

import numpy as np

from kfast.reference.filter import _at


def propagate(F, H, x_init, w, v, B=None, D=None, u=None):
    """y[t] = H x[t] + D u[t] + v[t], x[t+1] = F x[t] + B u[t] + w[t] from x[0] = x_init."""
    T = len(w)
    x = np.zeros((T, len(x_init)))
    y = np.zeros((T, v.shape[1]))
    x[0] = x_init
    for t in range(T):
        y[t] = _at(H, t) @ x[t] + v[t] + (_at(D, t) @ u[t] if D is not None else 0)
        if t + 1 < T:
            x[t + 1] = _at(F, t) @ x[t] + w[t] + (_at(B, t) @ u[t] if B is not None else 0)
    return x, y
