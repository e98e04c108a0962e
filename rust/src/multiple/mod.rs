//! Multiple-model estimation (Söderström section 9.5): r filters — the modes — run side by
//! side on the same measurements, with the Bayes probabilities of the modes.
//!
//! - the **fixed bank** (9.56)–(9.63): the true model is one of r that never switch;
//! - the **interacting multiple-model (IMM) filter** (9.64)–(9.86): the mode is a Markov chain
//!   and each mode's time update starts from the mixture of all modes' estimates;
//! - the **Gaussian-sum filter** (9.43)–(9.55): a bank of one nonlinear model's EKF or UKF
//!   from the components of a Gaussian-mixture prior, with optional [`Reduction`].
//!
//! Each mode is a [`ModeFilter`] — the linear [`KalmanFilter`](crate::KalmanFilter) or the
//! [`NonlinearKalmanFilter`](crate::nonlinear::NonlinearKalmanFilter) — and
//! [`MultipleModelFilter`] runs them one step at a time ([`Interaction`] chooses the IMM or
//! the bank) or over a whole series ([`MultipleModelFilter::filter_into`] into
//! [`MultipleModelOutputs`]). Modes of different state sizes are related by [`StateMap`]s.

mod filter;
mod mixture;
mod mode;

pub use filter::{Interaction, MultipleModelFilter, MultipleModelOutputs, Reduction};
pub use mixture::StateMap;
pub use mode::ModeFilter;
