"""Algebraic Riccati and Lyapunov equations with SciPy's conventions (``solvers``) and the
stationary analysis of a constant model built on them (``stationary``: steady-state filter,
innovations form, autocovariance, spectral density). The Rust side is ``rust/src/riccati/``."""
