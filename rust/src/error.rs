//! The one error type of the crate.
//!
//! Every public function returns `Result<_, Error>`. Each variant names the argument and,
//! where there is one, the time step, so that a message reads like
//! `Q at step 7: not positive semidefinite (smallest eigenvalue -0.25)`.

use std::fmt;

/// What went wrong, and where.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// An argument has the wrong shape or a value it may not have (NaN, inf, asymmetry,
    /// a covariance that is not positive semidefinite, ...).
    InvalidArgument {
        /// Name of the argument (`"F"`, `"y"`, `"x0"`, ...).
        arg: &'static str,
        /// Time step the problem was found at, for per-step arguments and data.
        step: Option<usize>,
        /// What was wrong.
        problem: String,
    },
    /// The innovation covariance `S = H P H' + R` at a step is not positive definite, so the
    /// measurement update cannot be computed (e.g. `R = 0` with `H P H'` singular).
    InnovationCovariance {
        /// Time step of the failed update.
        step: usize,
        /// Details.
        problem: String,
    },
    /// A state covariance computed during a run stopped being positive definite, so the next
    /// operation that needs its square root (the sigma points of an unscented filter) cannot
    /// run.
    NotPositiveDefinite {
        /// Which covariance (`"P(t|t-1)"`, `"P(t|t)"`).
        what: &'static str,
        /// Time step.
        step: usize,
        /// Details and the remedy.
        problem: String,
    },
    /// A Riccati equation has no stabilizing solution (or none could be found): the method
    /// never returns a non-stabilizing fixed point instead.
    NoStabilizingSolution {
        /// Details.
        problem: String,
    },
}

impl Error {
    /// An [`Error::InvalidArgument`] without a time step.
    pub fn arg(arg: &'static str, problem: impl Into<String>) -> Self {
        Error::InvalidArgument { arg, step: None, problem: problem.into() }
    }

    /// An [`Error::InvalidArgument`] at time step `step`.
    pub fn arg_at(arg: &'static str, step: usize, problem: impl Into<String>) -> Self {
        Error::InvalidArgument { arg, step: Some(step), problem: problem.into() }
    }

    /// The same error attached to time step `step` (used where per-step checks run on one
    /// matrix of a stack).
    pub(crate) fn at_step(self, t: Option<usize>) -> Self {
        match self {
            Error::InvalidArgument { arg, step: None, problem } => Error::InvalidArgument { arg, step: t, problem },
            other => other,
        }
    }
}

impl Error {
    /// The same error naming argument `to` where it named `from` (a check written for one
    /// argument applied to another).
    pub(crate) fn renamed(self, from: &'static str, to: &'static str) -> Self {
        match self {
            Error::InvalidArgument { arg, step, problem } if arg == from => {
                Error::InvalidArgument { arg: to, step, problem }
            }
            other => other,
        }
    }

    /// The same error with `context` (e.g. "mode 2") before its problem, for the filters a
    /// multiple-model filter runs.
    pub(crate) fn within(self, context: &str) -> Self {
        let tell = |problem: String| format!("{context}: {problem}");
        match self {
            Error::InvalidArgument { arg, step, problem } => {
                Error::InvalidArgument { arg, step, problem: tell(problem) }
            }
            Error::InnovationCovariance { step, problem } => {
                Error::InnovationCovariance { step, problem: tell(problem) }
            }
            Error::NotPositiveDefinite { what, step, problem } => {
                Error::NotPositiveDefinite { what, step, problem: tell(problem) }
            }
            Error::NoStabilizingSolution { problem } => Error::NoStabilizingSolution { problem: tell(problem) },
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidArgument { arg, step: None, problem } => write!(f, "{arg}: {problem}"),
            Error::InvalidArgument { arg, step: Some(t), problem } => {
                write!(f, "{arg} at step {t}: {problem}")
            }
            Error::NoStabilizingSolution { problem } => {
                write!(f, "no stabilizing solution of the Riccati equation: {problem}")
            }
            Error::NotPositiveDefinite { what, step, problem } => {
                write!(f, "{what} at step {step} is not positive definite: {problem}")
            }
            Error::InnovationCovariance { step, problem } => {
                write!(f, "innovation covariance S = H P H' + R at step {step} cannot be factorized: {problem}")
            }
        }
    }
}

impl std::error::Error for Error {}

/// Shorthand used throughout the crate.
pub type Result<T> = std::result::Result<T, Error>;
