//! Optimal control (Söderström ch. 11), with the sign convention u = −L x throughout.
//!
//! - [`lqr`] of an [`LqProblem`] → [`LqSolution`]: the stationary LQ regulator (11.47)–(11.48).
//! - [`lq_finite`] of [`LqSteps`] → [`LqFinite`]: the finite-horizon regulator (11.6)–(11.7),
//!   time-varying data allowed.
//!
//! Both solve the filter's Riccati equation on the dual data (Söderström (11.19)–(11.31)), so
//! they share its solvers, checks and fixed-size kernels. The LQG regulator, its closed loop
//! and the design helpers are composed in Python from these and the stationary filter.

mod lq;

pub use lq::{lq_finite, lqr, LqFinite, LqProblem, LqSolution, LqSteps};
