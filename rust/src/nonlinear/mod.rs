//! Nonlinear Gaussian filters: the extended Kalman filter (and its iterated forms) and the
//! unscented Kalman filter, for the model with additive noise
//!
//! ```text
//! x[t+1] = f(x[t], t, u[t]) + w[t]     w ~ N(0, Q)
//! y[t]   = h(x[t], t, u[t]) + v[t]     v ~ N(0, R)      prior x(0|−1) ~ N(x0, P0)
//! ```
//!
//! f and h are [`PointFunction`]s, evaluated at a batch of points per call: the built-in
//! models of [`models`], a [`LinearMap`], or (in the Python extension) a Python callable.
//! [`NonlinearModel`] validates them with Q and R once; [`ekf_into`] and [`ukf_into`] run a
//! whole series into [`FilterOutputs`](crate::FilterOutputs), the linear filter's outputs;
//! [`ekf_batch`] and [`ukf_batch`] run many series at once, in parallel;
//! [`smooth_nonlinear_into`] adds the extended or unscented RTS backward pass;
//! [`NonlinearKalmanFilter`] runs either filter one step at a time; [`particle_filter`] (with
//! [`ParticleOptions`] and a [`Resampling`] scheme) is the sequential Monte Carlo filter of
//! the same model; [`median_filter`] and [`mean_filter`] are the running order-statistic and
//! moving-average filters of Söderström section 9.7; [`quantize`], [`quantized_loglik`] and
//! [`quantized_moments`] are the quantized measurements of section 9.6.

mod batch;
mod filter;
mod function;
mod median;
mod model;
pub mod models;
mod particle;
mod quantized;
mod sigma;
pub(crate) use sigma::cholesky;
mod smoother;
mod square_root;
mod streaming;
mod trig;

pub use batch::{ekf_batch, ukf_batch};
pub use filter::{ekf_into, ukf_into, EkfOptions, Iteration, Sensor, UkfForm, UkfOptions};
pub use function::{wrap_angle, ConstantMap, LinearMap, PointFunction};
pub use median::{mean_filter, median_filter, StartUp};
pub use model::NonlinearModel;
pub use particle::{
    particle_filter, particle_filter_into, MeasurementLikelihood, ParticleFilter, ParticleFunction, ParticleOptions,
    ParticleOutputs, ParticleResult, Resampling,
};
pub use quantized::{
    log_normal_cdf, log_normal_interval, quantize, quantize_into, quantized_loglik, quantized_moments, Distribution,
    QuantizedMoments, QuantizedSensor,
};
pub use sigma::{CustomPoints, SigmaPoints};
pub use smoother::{smooth_nonlinear_into, SmoothMethod};
pub use streaming::NonlinearKalmanFilter;
