//! Algebraic Riccati equations (discrete and continuous) and Lyapunov equations, with SciPy's
//! argument conventions.

pub mod are;
pub mod lyapunov;

pub use are::{solve_continuous_are, solve_discrete_are, DareMethod, RiccatiProblem, RiccatiSolution};
pub use lyapunov::{solve_continuous_lyapunov, solve_discrete_lyapunov, stationary_covariance};
