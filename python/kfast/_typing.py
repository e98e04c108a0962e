"""Type aliases of the public API, for annotations (and the stub of the compiled module): a
misspelt option such as ``form="josef"`` then fails type checking, not only at run time."""

from __future__ import annotations

from typing import Iterable, Literal, Union

__all__ = ["Form", "UpdateForm", "UkfForm", "Iteration", "Resample", "Keep", "DareMethod", "FilterOutput", "SmoothOutput", "FilterOutputs", "SmoothOutputs", "EMParameter"]

Form = Literal["joseph", "standard"]
"""The covariance measurement update: Joseph's (I-KH)P(I-KH)' + KRK' or the standard P - KSK'."""

UpdateForm = Literal["joseph", "standard", "sqrt", "ud", "information", "sequential"]
"""The linear filter's forms: the covariance forms, and the square-root (Cholesky factor moved by
orthogonal transformations), U-D (Bierman/Thornton), information (Y = P^-1) and sequential (one
scalar component at a time) filters."""

UkfForm = Literal["standard", "sqrt"]

Iteration = Literal["book", "gauss-newton"]
"""How the iterated EKF relinearizes: Söderström's (9.12)-(9.17) or Gauss-Newton (Bell & Cathey)."""

Resample = Literal["multinomial", "systematic", "stratified", "residual"]
"""The particle filter's resampling schemes."""

Keep = Literal["last", "all"]
"""Which steps' particles ``particle_filter(..., keep=...)`` returns."""

DareMethod = Literal["doubling", "newton", "iteration", "eigen"]
"""The algorithms of ``solve_discrete_are``."""

FilterOutput = Literal["x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "K_pred", "loglik_t", "x_next", "P_next"]
"""The fields of ``FilterResult`` that ``filter(..., outputs=...)`` can select."""

SmoothOutput = Union[FilterOutput, Literal["x_smooth", "P_smooth", "P_lag1"]]
"""The fields ``smooth(..., outputs=...)`` can select: the smoother's and the filter's."""

FilterOutputs = Union[FilterOutput, Iterable[FilterOutput], None]
"""``outputs=``: one name, several, or None for all."""

SmoothOutputs = Union[SmoothOutput, Iterable[SmoothOutput], None]

EMParameter = Literal["F", "H", "Q", "R", "x0", "P0"]
"""The parameters ``LinearGaussian.em`` can estimate."""
