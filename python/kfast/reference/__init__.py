"""Plain NumPy reference implementations: short, textbook-readable, the oracle for tests.

Never imported by the fast path. Each function cites the equations it implements.
"""

from kfast.reference.filter import kalman_filter

__all__ = ["kalman_filter"]

from kfast.reference.smoother import fixed_lag_augmented, fixed_point_augmented, map_smoother, rts_smoother  # noqa: E402

__all__ += ["rts_smoother", "map_smoother", "fixed_lag_augmented", "fixed_point_augmented"]

from kfast.reference.forecast import forecast  # noqa: E402
from kfast.reference.simulate import propagate  # noqa: E402

__all__ += ["forecast", "propagate"]

from kfast.reference.estimation import em_step  # noqa: E402

__all__ += ["em_step"]

from kfast.reference.lyapunov import (  # noqa: E402
    discrete_lyapunov_doubling,
    solve_continuous_lyapunov_kron,
    solve_discrete_lyapunov_kron,
)
from kfast.reference.riccati import (  # noqa: E402
    care_eigen,
    care_residual,
    dare_eigen,
    dare_gain,
    dare_iteration,
    dare_residual,
    is_stabilizing_dare,
)
from kfast.reference.sampling import expm_taylor, qd_first_order, van_loan  # noqa: E402

__all__ += [
    "discrete_lyapunov_doubling",
    "solve_continuous_lyapunov_kron",
    "solve_discrete_lyapunov_kron",
    "care_eigen",
    "care_residual",
    "dare_eigen",
    "dare_gain",
    "dare_iteration",
    "dare_residual",
    "is_stabilizing_dare",
    "expm_taylor",
    "qd_first_order",
    "van_loan",
]

from kfast.reference import nonlinear  # noqa: E402  (EKF, UKF and their smoothers: kfast.reference.nonlinear)

__all__ += ["nonlinear"]

from kfast.reference.particle import particle_filter  # noqa: E402

__all__ += ["particle_filter"]

from kfast.reference.median import mean_filter, median_filter  # noqa: E402

__all__ += ["median_filter", "mean_filter"]

from kfast.reference.multiple import gaussian_sum_filter, imm_filter, model_bank  # noqa: E402

__all__ += ["imm_filter", "model_bank", "gaussian_sum_filter"]

from kfast.reference import quantized  # noqa: E402  (quantize, moments_over_cells, moments_by_series, quantized_loglik)

__all__ += ["quantized"]
