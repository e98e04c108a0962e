//! Linear Gaussian state-space models: the model, the Kalman filter (whole series, streaming,
//! many series), the smoothers, forecasts and simulation.

pub mod batch;
pub mod diagnostics;
pub mod filter;
pub mod forecast;
pub mod model;
pub mod simulate;
pub mod smoother;
mod validate;
