"""Stationary LQG control by separation (Söderström Thm 11.3): u(t) = -L x̂(t|t-k), k = 0 or 1,
with the LQ gain of :func:`kfast.control.lqr` and the stationary Kalman filter of the model; the
regulator realisation (11.33)-(11.38), the closed loop (11.42)-(11.44), its variances by a
Lyapunov equation, and the design helpers: the return-difference identity (11.49), the
reference pre-gain (11.89), integral action (11.90)-(11.91) and loop transfer recovery
(11.105)-(11.108). Sign convention: u = -L x.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

import numpy as np
from numpy.typing import ArrayLike

from kfast._kfast import KfastError
from kfast.control._checks import matrix
from kfast.control.lq import LQResult, lqr
from kfast.riccati.stationary import SteadyState

if TYPE_CHECKING:
    from kfast.linear.model import LinearGaussian

__all__ = [
    "LQGResult",
    "IntegralLQResult",
    "lqg",
    "return_difference",
    "reference_gain",
    "lqr_integral",
    "ltr_gain",
]


@dataclass(frozen=True, repr=False)
class LQGResult:
    """The stationary LQG regulator and its closed loop (Söderström Sec. 11.3).

    The regulator's state is z(t) = x̂(t|t-1) (Söderström (11.33)-(11.38)):
    ``z(t+1) = F_r z(t) + G_r y(t)``, ``u(t) = -H_r z(t) - J_r y(t)``; its transfer function
    y -> u is ``u = -C_reg(q) y`` with C_reg(z) = J_r + H_r (zI - F_r)^-1 G_r (the book's G(z) in
    (11.35), (11.37) is -C_reg). The closed loop's state is xi = (x, z)."""

    k: int
    """0: u(t) = -L x̂(t|t) (uses y(t)); 1: u(t) = -L x̂(t|t-1)."""
    L: np.ndarray
    """LQ gain (k_u, n), u = -L x."""
    L_w: np.ndarray
    """(k_u, m): the extra feedback of the innovation for k = 0 when N != 0,
    u = -L x̂(t|t) - L_w e(t), L_w = Γ^-1 G' S N S_e^-1 (zero when N = 0 or k = 1)."""
    F_r: np.ndarray
    G_r: np.ndarray
    H_r: np.ndarray
    J_r: np.ndarray
    A_cl: np.ndarray
    """Closed-loop matrix (2n, 2n) of xi = (x, z): xi(t+1) = A_cl xi(t) + B_cl (w(t), v(t))."""
    B_cl: np.ndarray
    closed_loop_poles: np.ndarray
    """eig(A_cl) = eig(F - G L) ∪ eig(F - K_pred H) (Söderström Lemma 11.4; D = 0)."""
    var_x: np.ndarray
    """Stationary covariance of x."""
    var_y: np.ndarray
    """Stationary covariance of y."""
    var_u: np.ndarray
    """Stationary covariance of u."""
    cost: float
    """Stationary average cost E[x' Q1 x + 2 x' Q12 u + u' Q2 u] per step."""
    lq: LQResult
    """The LQ solution (S, L, closed-loop eigenvalues of F - G L)."""
    filter: SteadyState
    """The stationary Kalman filter (K, K_pred, P_pred, P_filt, S)."""

    def regulator_response(self, z: ArrayLike) -> np.ndarray:
        """C_reg(z) = J_r + H_r (zI - F_r)^-1 G_r at the points ``z`` (complex), shape
        (len(z), k_u, m); the regulator is u = -C_reg(q) y."""
        zs = np.atleast_1d(np.asarray(z, dtype=complex))
        eye = np.eye(len(self.F_r))
        return np.stack([self.J_r + self.H_r @ np.linalg.solve(zi * eye - self.F_r, self.G_r) for zi in zs])

    def __repr__(self) -> str:
        rho = float(np.abs(self.closed_loop_poles).max())
        return f"LQGResult(k={self.k}, n={self.L.shape[1]}, closed-loop radius={rho:.4g}, cost={self.cost:.6g})"


def lqg(
    model: "LinearGaussian",
    Q1: ArrayLike,
    Q2: ArrayLike,
    Q12: Optional[ArrayLike] = None,
    k: int = 1,
) -> LQGResult:
    """The stationary LQG regulator for ``model`` (x(t+1) = F x + B u + w, y = H x + D u + v,
    Söderström's G is kfast's B): u(t) = -L x̂(t|t-k) with L from :func:`lqr` on (F, B, Q1, Q2,
    Q12) and the stationary Kalman filter of the model (separation, Söderström Thm 11.3).

    Parameters
    ----------
    model : LinearGaussian
        Constant matrices and an input matrix B.
    Q1, Q2, Q12 : array_like
        The weights of :func:`lqr`.
    k : {0, 1}
        1: the regulator uses y up to t - 1, u = -L x̂(t|t-1) (11.34); 0: it uses y(t) too,
        u = -L x̂(t|t) (11.36). With N != 0 and k = 0 the law adds -L_w e(t), the innovation's
        share of E[w(t) | y up to t] (Söderström requires N = 0 there; this is its extension by
        completing the square, docs/algorithms.md "LQG"). With D != 0, k = 0 closes an algebraic
        loop through y(t), solved exactly (refused when I - (L K + L_w) D is singular).

    Returns
    -------
    LQGResult
        The realisation (F_r, G_r, H_r, J_r), the closed loop (A_cl, B_cl, poles), the stationary
        variances of x, y and u, and the average cost.

    Examples
    --------
    Söderström ex. 11.4 (a) with the estimator of the book's R1, R2 (its h^2/3 read as h^3/3):

    >>> h = 0.5
    >>> plant = kfast.LinearGaussian(F=[[1, h], [0, 1]], H=[[1.0, 0.0]],
    ...     Q=1e-3 * np.array([[h**3 / 3, h**2 / 2], [h**2 / 2, h]]), R=1e-3, B=[[h**2 / 2], [h]])
    >>> reg = kfast.control.lqg(plant, np.eye(2), 0.1)
    >>> print(np.sort_complex(np.linalg.eigvals(plant.F - reg.filter.K_pred @ plant.H)).round(2))
    [0.6-0.27j 0.6+0.27j]
    """
    from kfast.riccati.stationary import steady_state

    if k not in (0, 1) or isinstance(k, bool):
        raise KfastError(f"k: expected 0 or 1, got {k!r}")
    if model.steps is not None:
        raise KfastError("model: lqg needs constant matrices (this model has per-step ones)")
    if model.B is None:
        raise KfastError("model: lqg needs the input matrix B (the model has no inputs)")
    F, H, B = model.F, model.H, model.B
    n, m, ku = F.shape[0], H.shape[0], B.shape[1]
    D = model.D if model.D is not None else np.zeros((m, ku))
    Nw = model.N if model.N is not None else np.zeros((n, m))
    lq = lqr(F, B, Q1, Q2, Q12)
    filt = steady_state(model)
    L, K, Kp = lq.L, filt.K, filt.K_pred
    Q2_ = matrix("Q2", Q2, ku, ku)
    L_w = np.zeros((ku, m))
    if k == 0 and np.any(Nw):
        gamma = B.T @ lq.S @ B + Q2_
        L_w = np.linalg.solve(gamma, B.T @ lq.S @ Nw) @ np.linalg.inv(filt.S)
    # u = -L z - M e with e = y - H z - D u (M = 0 for k = 1): solved for u.
    M = L @ K + L_w if k == 0 else np.zeros((ku, m))
    loop = np.eye(ku) - M @ D
    if np.linalg.cond(loop) > 1e12:
        raise KfastError("model: D closes an algebraic loop u = ... + (L K + L_w) D u that has no solution (I - (L K + L_w) D is singular)")
    H_r = np.linalg.solve(loop, L - M @ H)
    J_r = np.linalg.solve(loop, M)
    F_r = F - B @ H_r - Kp @ (H - D @ H_r)
    G_r = Kp @ (np.eye(m) + D @ J_r) - B @ J_r
    A_cl, B_cl, C_y, D_y, C_u, D_u = _closed_loop(F, H, B, D, F_r, G_r, H_r, J_r)
    W = np.block([[model.Q, Nw], [Nw.T, model.R]])
    from kfast.riccati.solvers import solve_discrete_lyapunov

    Pi = solve_discrete_lyapunov(A_cl, B_cl @ W @ B_cl.T)
    Pi = (Pi + Pi.T) / 2
    R = model.R
    var_y = C_y @ Pi @ C_y.T + D_y @ R @ D_y.T
    var_u = C_u @ Pi @ C_u.T + D_u @ R @ D_u.T
    # (x, u) = X xi + (0, D_u) v, v independent of xi(t).
    X = np.vstack([np.eye(n, 2 * n), C_u])
    cov_xu = X @ Pi @ X.T
    cov_xu[n:, n:] += D_u @ R @ D_u.T
    Q1_ = matrix("Q1", Q1, n, n)
    Q12_ = np.zeros((n, ku)) if Q12 is None else matrix("Q12", Q12, n, ku)
    weight = np.block([[Q1_, Q12_], [Q12_.T, Q2_]])
    return LQGResult(
        k=k,
        L=L,
        L_w=L_w,
        F_r=F_r,
        G_r=G_r,
        H_r=H_r,
        J_r=J_r,
        A_cl=A_cl,
        B_cl=B_cl,
        closed_loop_poles=np.linalg.eigvals(A_cl),
        var_x=Pi[:n, :n],
        var_y=(var_y + var_y.T) / 2,
        var_u=(var_u + var_u.T) / 2,
        cost=float(np.sum(weight * cov_xu)),
        lq=lq,
        filter=filt,
    )


def _closed_loop(F, H, B, D, F_r, G_r, H_r, J_r):
    """xi = (x, z): xi(t+1) = A xi + B_n (w, v); y = C_y xi + D_y v; u = C_u xi + D_u v, for the
    plant (F, B, H, D) under u = -H_r z - J_r y, z(t+1) = F_r z + G_r y."""
    n, m, ku = F.shape[0], H.shape[0], B.shape[1]
    # u = -H_r z - J_r (H x + D u + v)  =>  u = -W (J_r H x + H_r z + J_r v), W = (I + J_r D)^-1.
    W = np.linalg.inv(np.eye(ku) + J_r @ D)
    C_u = -W @ np.hstack([J_r @ H, H_r])
    D_u = -W @ J_r
    C_y = np.hstack([H, np.zeros((m, n))]) + D @ C_u
    D_y = np.eye(m) + D @ D_u
    A = np.block([[F, np.zeros((n, n))], [np.zeros((n, n)), F_r]]) + np.vstack([B @ C_u, G_r @ C_y])
    B_n = np.block([[np.eye(n), B @ D_u], [np.zeros((n, n)), G_r @ D_y]])
    return A, B_n, C_y, D_y, C_u, D_u


def return_difference(
    F: ArrayLike,
    G: ArrayLike,
    Q1: ArrayLike,
    Q2: ArrayLike,
    z: ArrayLike,
    Q12: Optional[ArrayLike] = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Both sides of the return-difference identity (Söderström Lemma 11.6, (11.49)) at the
    points ``z``, for the stationary LQ solution S, L of (F, G, Q1, Q2, Q12):

    ::

        [I + L (zI - F)^-1 G]' (G' S G + Q2) [I + L (z^-1 I - F)^-1 G]
            = Q2 + G' (zI - F')^-1 Q1 (z^-1 I - F)^-1 G + G' (zI - F')^-1 Q12 + Q12' (z^-1 I - F)^-1 G

    (transposes, not conjugate transposes: an identity of rational matrices in z). Returns
    (left, right), each of shape (len(z), k, k); they agree to rounding for the stabilizing S.
    """
    lq = lqr(F, G, Q1, Q2, Q12)
    F_, G_ = matrix("F", F), matrix("G", G)
    n, ku = G_.shape
    Q1_, Q2_ = matrix("Q1", Q1, n, n), matrix("Q2", Q2, ku, ku)
    Q12_ = np.zeros((n, ku)) if Q12 is None else matrix("Q12", Q12, n, ku)
    gamma = G_.T @ lq.S @ G_ + Q2_
    eye = np.eye(n)
    left, right = [], []
    for zi in np.atleast_1d(np.asarray(z, dtype=complex)):
        ahead = np.linalg.solve(zi * eye - F_, G_)  # (zI - F)^-1 G
        back = np.linalg.solve(eye / zi - F_, G_)  # (z^-1 I - F)^-1 G
        left.append((np.eye(ku) + lq.L @ ahead).T @ gamma @ (np.eye(ku) + lq.L @ back))
        right.append(Q2_ + ahead.T @ Q1_ @ back + ahead.T @ Q12_ + Q12_.T @ back)
    return np.array(left), np.array(right)


def reference_gain(F: ArrayLike, G: ArrayLike, H: ArrayLike, L: ArrayLike) -> np.ndarray:
    """The static pre-gain M of u = -L x + M r that gives y = H x unit static gain from r
    (Söderström (11.89)): M = [H (I - F + G L)^-1 G]^-1. Needs as many outputs as inputs and no
    closed-loop zero at z = 1; the same M serves u = -L x̂ + M r by (11.44)."""
    F_ = matrix("F", F)
    n = F_.shape[0]
    G_ = matrix("G", G, rows=n)
    H_ = matrix("H", H, cols=n) if np.ndim(H) == 2 else matrix("H", np.atleast_2d(H), cols=n)
    L_ = matrix("L", L, G_.shape[1], n) if np.ndim(L) == 2 else matrix("L", np.atleast_2d(L), G_.shape[1], n)
    if H_.shape[0] != G_.shape[1]:
        raise KfastError(f"H: the pre-gain needs as many outputs as inputs, got {H_.shape[0]} outputs and {G_.shape[1]} inputs")
    closed = np.eye(n) - F_ + G_ @ L_
    if np.linalg.cond(closed) > 1e12:
        raise KfastError("L: F - G L has an eigenvalue at 1 (the closed loop is not stable at zero frequency)")
    static = H_ @ np.linalg.solve(closed, G_)
    if np.linalg.cond(static) > 1e12:
        raise KfastError("H: the closed loop has a zero at z = 1: no static pre-gain gives unit gain")
    return np.linalg.inv(static)


@dataclass(frozen=True, repr=False)
class IntegralLQResult:
    """LQ control with integral action (Söderström (11.90)-(11.91)): u = -L1 x - L2 z with
    z(t+1) = z(t) + H x(t) - r(t), the running sum of the control error."""

    L1: np.ndarray
    """(k, n): the state feedback."""
    L2: np.ndarray
    """(k, p): the integral feedback."""
    augmented: LQResult
    """lqr of the augmented system [[F, 0], [H, I]], [G; 0] with weights blockdiag(Q1, Q3), Q2."""

    def __repr__(self) -> str:
        return f"IntegralLQResult(n={self.L1.shape[1]}, k={self.L1.shape[0]}, p={self.L2.shape[1]})"


def lqr_integral(F: ArrayLike, G: ArrayLike, H: ArrayLike, Q1: ArrayLike, Q2: ArrayLike, Q3: ArrayLike) -> IntegralLQResult:
    """The LQ regulator with integral action (Söderström (11.90)-(11.91)): the state is augmented
    with z(t+1) = z(t) + H x(t) - r(t) and weighted by Q3 (p x p; small: slow integral, large:
    a spiky input). The augmented pair is stabilizable only if the plant has no zero at z = 1."""
    F_ = matrix("F", F)
    n = F_.shape[0]
    G_ = matrix("G", G, rows=n)
    H_ = matrix("H", np.atleast_2d(np.asarray(H, dtype=float)), cols=n)
    p, ku = H_.shape[0], G_.shape[1]
    Fa = np.block([[F_, np.zeros((n, p))], [H_, np.eye(p)]])
    Ga = np.vstack([G_, np.zeros((p, ku))])
    Q1a = np.block([[matrix("Q1", Q1, n, n), np.zeros((n, p))], [np.zeros((p, n)), matrix("Q3", Q3, p, p)]])
    aug = lqr(Fa, Ga, Q1a, Q2)
    return IntegralLQResult(L1=aug.L[:, :n], L2=aug.L[:, n:], augmented=aug)


def ltr_gain(G: ArrayLike, H: ArrayLike) -> np.ndarray:
    """The loop-transfer-recovery filter gain K = G (H G)^-1 (Söderström (11.105)-(11.108)): the
    filter gain of Q = G G', R = 0, for which the k = 0 LQG loop G_R G_S equals the state-feedback
    loop L (qI - F)^-1 G (Lemma 11.9). Needs a square plant with H G invertible; the filter is
    stable only for a minimum-phase plant (the observer F - F K H has its eigenvalues at 0 and
    at the plant's zeros)."""
    G_ = matrix("G", G)
    H_ = matrix("H", np.atleast_2d(np.asarray(H, dtype=float)), cols=G_.shape[0])
    HG = H_ @ G_
    if HG.shape[0] != HG.shape[1] or np.linalg.cond(HG) > 1e12:
        raise KfastError(f"H: loop transfer recovery needs H G square and invertible (H G has shape {HG.shape})")
    return G_ @ np.linalg.inv(HG)
