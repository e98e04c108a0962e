//! # kfast
//!
//! State estimation with a Rust core and a Python face: Kalman filters and smoothers for
//! linear Gaussian state-space models, Riccati and Lyapunov solvers, sampling of
//! continuous-time models.
//!
//! ```text
//! x[t+1] = F x[t] + B u[t] + w[t]        w ~ N(0, Q)
//! y[t]   = H x[t] + D u[t] + v[t]        v ~ N(0, R),   E[w[t] v[t]'] = N
//! prior:  x[0] ~ N(x0, P0)               (x0, P0) is x̂(0|−1): the first step is an update
//! ```
//!
//! The crate is organised by family over a shared core (docs/architecture.md): [`linear`]
//! (the model, filter, smoothers, many series, forecasts, simulation), [`riccati`] (algebraic
//! Riccati and Lyapunov equations), [`sampling`] (continuous to discrete time); the core (small
//! dense kernels, compile-time sizes, validators and the model-agnostic Gaussian measurement
//! update every filter ends its step with) is internal.
//!
//! The Rust API in one screen:
//!
//! - [`StepMatrix`], [`Matrices`] and [`LinearGaussian`]: the model, each matrix constant or
//!   given per step, validated once by [`LinearGaussian::new`].
//! - [`filter`] / [`filter_into`] → [`FilterResult`]: the whole series; [`loglik`]: the
//!   likelihood alone. [`Series`] wraps the row-major `(T, m)` data and `(T, k)` inputs.
//! - [`KalmanFilter`]: the same filter one step at a time for streams, over an owned,
//!   borrowed or shared (`Arc`) model.
//! - [`FilterOptions`]: the [`UpdateForm`] (Joseph, the default, or standard) and the optional
//!   freezing of the gains once the covariance has converged (`converge_tol`).
//! - [`smooth`] → [`SmootherResult`] (RTS with lag-one covariances; [`smooth_into`] stores
//!   only the outputs asked for), [`smooth_fixed_lag`] ([`FixedLagOptions`]) and
//!   the online [`FixedLagSmoother`], [`smooth_fixed_point`].
//! - [`filter_batch`]: many series ([`Batch`] → [`BatchOutputs`]) through one model on all
//!   cores (feature `rayon`, on by default), the covariance recursion computed once when it is
//!   shared.
//! - [`forecast`] → [`Forecast`]: k-step state and output predictions.
//! - [`linear::diagnostics`]: is a run consistent with its model? Standardized innovations,
//!   NIS / NEES with their χ² bounds, autocorrelation, Ljung–Box and Jarque–Bera tests.
//! - [`propagate`]: sample paths from given noise (the core of simulation).
//! - [`solve_discrete_are`] / [`solve_continuous_are`] of a [`RiccatiProblem`] →
//!   [`RiccatiSolution`] (SciPy's conventions, [`DareMethod`]), [`solve_discrete_lyapunov`],
//!   [`solve_continuous_lyapunov`], [`stationary_covariance`].
//! - [`expm`], [`discretize`] / [`discretize_steps`] → [`Discretized`]: Van Loan sampling of
//!   continuous-time models.
//! - [`NonlinearModel`] of f and h given as [`PointFunction`]s (built-ins in
//!   [`nonlinear::models`]), [`ekf_into`] (EKF, iterated: [`EkfOptions`]) and [`ukf_into`]
//!   (UKF with [`SigmaPoints`], standard or square-root: [`UkfOptions`]): the nonlinear
//!   Gaussian filters; a noise gain g through [`NonlinearModel::with_noise_gain`], noise as an
//!   input of f through [`NonlinearModel::with_noise_input`]; [`ekf_batch`] / [`ukf_batch`] for
//!   many tracks.
//! - [`nonlinear::particle_filter`] ([`nonlinear::ParticleOptions`], a
//!   [`nonlinear::Resampling`] scheme) and the streaming [`nonlinear::ParticleFilter`]: the
//!   particle filter of the same model, on all cores, fixed by its seed;
//!   [`nonlinear::median_filter`] / [`nonlinear::mean_filter`]: the running median and mean;
//!   [`nonlinear::quantize`], [`nonlinear::quantized_loglik`] and [`nonlinear::quantized_moments`]:
//!   quantized measurements.
//! - [`multiple::MultipleModelFilter`]: the interacting multiple-model filter, the fixed
//!   model bank and the Gaussian-sum filter over linear or nonlinear modes
//!   ([`multiple::ModeFilter`]), modes of different sizes related by [`multiple::StateMap`]s.
//! - [`control::lqr`] / [`control::lq_finite`]: LQ regulators u = −L x, stationary and over a
//!   finite horizon (Söderström ch. 11), on the same Riccati code by duality.
//! - [`poly`]: polynomial methods — zeros, the spectral factor, the Diophantine equation and the
//!   predictor identity (Söderström ch. 7).
//! - [`Error`]: every public function returns `Result<_, Error>`; nothing panics on bad input.
//!
//! ```
//! use kfast::{filter, LinearGaussian, Matrices, Series, StepMatrix, UpdateForm};
//! let c = |v: f64| StepMatrix::constant(1, 1, vec![v]).unwrap();
//! let model = LinearGaussian::new(Matrices::new(c(0.8), c(1.0), c(0.68), c(1.0))).unwrap();
//! let y = [0.3, -0.1, 0.7];
//! let res = filter(&model, Series::new("y", &y, 3, 1).unwrap(), None, &[0.0], &[1.0], UpdateForm::Joseph).unwrap();
//! assert!((res.p_pred[0] - 1.0).abs() < 1e-12); // Söderström ex. 6.17: P = 1 is stationary
//! ```

#![warn(missing_docs)]

pub mod control;
mod core;
pub mod error;
pub mod linear;
pub mod multiple;
pub mod nonlinear;
pub mod poly;
#[cfg(feature = "python")]
mod python;
pub mod riccati;
pub mod sampling;

pub use self::core::batch::{Batch, BatchOutputs};
pub use self::core::isa::{deterministic, instruction_set, set_deterministic};
pub use self::core::Series;
pub use error::{Error, Result};
pub use linear::batch::filter_batch;
pub use linear::filter::{
    filter, filter_diffuse_into, filter_into, loglik, FilterOptions, FilterOutputs, FilterResult, KalmanFilter,
    UpdateForm,
};
pub use linear::forecast::{forecast, Forecast};
pub use linear::model::{LinearGaussian, Matrices, StepMatrix};
pub use linear::simulate::propagate;
pub use linear::smoother::{
    smooth, smooth_fixed_lag, smooth_fixed_point, smooth_into, FixedLagOptions, FixedLagResult, FixedLagSmoother,
    FixedPointResult, SmoothOutputs, SmootherResult,
};
pub use nonlinear::{
    ekf_batch, ekf_into, smooth_nonlinear_into, ukf_batch, ukf_into, EkfOptions, Iteration, NonlinearKalmanFilter,
    NonlinearModel, PointFunction, SigmaPoints, SmoothMethod, UkfForm, UkfOptions,
};
pub use riccati::{
    solve_continuous_are, solve_continuous_lyapunov, solve_discrete_are, solve_discrete_lyapunov,
    stationary_covariance, DareMethod, RiccatiProblem, RiccatiSolution,
};
pub use sampling::{discretize, discretize_steps, expm, Discretized};
