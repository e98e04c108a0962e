"""One EM iteration in plain NumPy, step by step over t (the oracle for ``LinearGaussian.em``).

Shumway & Stoffer (1982; missing data 2000). With prior x(0|-1) ~ N(x0, P0), smoothed moments
x^ = x(t|T-1), P = P(t|T-1), L = Cov(x[t], x[t-1] | Y) and E[x x'] = P + x^ x^', the M-step is

    H = sum_t (E[y x'] - d x^') (sum_t E[x x'])^-1          over rows with an observation
    R = mean_t E[(y - H x - d)(y - H x - d)']                 over rows with an observation
    F = sum_{t>=1} (L[t] + x^[t] x^[t-1]' - a[t-1] x^[t-1]') (sum_{t<=T-2} E[x x'])^-1
    Q = mean_{t<=T-2} E[(x[t+1] - F x[t] - a[t])(...)']
    x0 = x^[0],  P0 = P[0] + (x^[0] - x0)(x^[0] - x0)'

with a = B u, d = D u. A missing component y_q of a partly observed row is replaced by its
conditional law given x and the observed y_o: y_q = H_q x + d_q + G (y_o - H_o x - d_o) + eta,
G = R_qo R_oo^-1, cov eta = R_qq - G R_oq.
"""

from __future__ import annotations

import numpy as np

from kfast.reference.smoother import rts_smoother


def em_step(F, H, Q, R, x0, P0, y, B=None, D=None, u=None):
    """Returns the updated (F, H, Q, R, x0, P0) and the log-likelihood before the update."""
    T, m = y.shape
    n = len(x0)
    xs, Ps, Pl, f = rts_smoother(F, H, Q, R, y, x0, P0, B=B, D=D, u=u)
    a = [B @ u[t] if B is not None else np.zeros(n) for t in range(T)]
    d = [D @ u[t] if D is not None else np.zeros(m) for t in range(T)]
    Exx = [Ps[t] + np.outer(xs[t], xs[t]) for t in range(T)]

    # Conditional moments of y[t] = M x + c + eta given Y (old H, R).
    moments = []
    for t in range(T):
        o = ~np.isnan(y[t])
        if not o.any():
            moments.append(None)
            continue
        q = ~o
        M, c, Rc = np.zeros((m, n)), np.where(o, y[t], 0.0), np.zeros((m, m))
        if q.any():
            G = R[np.ix_(q, o)] @ np.linalg.inv(R[np.ix_(o, o)])
            M[q] = H[q] - G @ H[o]
            c[q] = d[t][q] + G @ (y[t][o] - d[t][o])
            Rc[np.ix_(q, q)] = R[np.ix_(q, q)] - G @ R[np.ix_(o, q)]
        moments.append((M, c, Rc))
    used = [t for t in range(T) if moments[t] is not None]

    num = sum(moments[t][0] @ Exx[t] + np.outer(moments[t][1], xs[t]) - np.outer(d[t], xs[t]) for t in used)
    H_new = num @ np.linalg.pinv(sum(Exx[t] for t in used))
    R_new = np.zeros((m, m))
    for t in used:
        M, c, Rc = moments[t]
        A, e = M - H_new, c - d[t]
        R_new += A @ Exx[t] @ A.T + np.outer(A @ xs[t], e) + np.outer(e, A @ xs[t]) + np.outer(e, e) + Rc
    R_new /= len(used)

    num = sum(Pl[t] + np.outer(xs[t], xs[t - 1]) - np.outer(a[t - 1], xs[t - 1]) for t in range(1, T))
    F_new = num @ np.linalg.pinv(sum(Exx[t] for t in range(T - 1)))
    Q_new = np.zeros((n, n))
    for t in range(T - 1):
        err = xs[t + 1] - F_new @ xs[t] - a[t]
        Q_new += np.outer(err, err) + F_new @ Ps[t] @ F_new.T + Ps[t + 1] - Pl[t + 1] @ F_new.T - F_new @ Pl[t + 1].T
    Q_new /= T - 1
    x0_new = xs[0]
    P0_new = Ps[0]
    sym = lambda A: (A + A.T) / 2  # noqa: E731
    return (F_new, H_new, sym(Q_new), sym(R_new), x0_new, sym(P0_new)), f["loglik"]
