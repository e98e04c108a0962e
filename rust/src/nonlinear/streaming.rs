//! [`NonlinearKalmanFilter`]: the EKF or the UKF one step at a time, for streams.

use std::sync::Arc;

use super::filter::{Ekf, EkfOptions, GaussianFilter, Sensor, Ukf, UkfOptions};
use super::model::{NoiseScratch, NonlinearModel};
use crate::core::validate::{check_input_row, check_observation, check_prior, check_psd, check_symmetric};
use crate::error::{Error, Result};

/// The EKF or the UKF over a stream: `update(y)` at step t (as often as there are
/// measurements of step t, each from the prior the last left), then `predict()` to t + 1.
/// Starts at t = 0 from the prior x(0|−1) ~ N(x0, P0). The arithmetic is that of
/// [`ekf_into`](super::ekf_into) / [`ukf_into`](super::ukf_into): the same steps give the same
/// numbers.
pub struct NonlinearKalmanFilter {
    model: Arc<NonlinearModel>,
    filter: Box<dyn GaussianFilter>,
    t: usize,
    /// Whether the state is x̂(t|t) (an update was the last operation).
    filtered: bool,
    loglik: f64,
    noise: NoiseScratch,
}

impl Clone for NonlinearKalmanFilter {
    fn clone(&self) -> Self {
        NonlinearKalmanFilter {
            model: Arc::clone(&self.model),
            filter: self.filter.boxed_clone(),
            t: self.t,
            filtered: self.filtered,
            loglik: self.loglik,
            noise: self.noise.clone(),
        }
    }
}

impl NonlinearKalmanFilter {
    /// The EKF (with `options`) from the prior (x0, P0).
    pub fn ekf(model: Arc<NonlinearModel>, x0: &[f64], p0: &[f64], options: EkfOptions) -> Result<Self> {
        check_prior(model.n_states(), x0, p0)?;
        let filter = Ekf::new(model.n_states(), model.n_obs(), x0, p0, options)?;
        Ok(Self::of(model, Box::new(filter)))
    }

    /// The UKF (with the sigma points and form of `options`) from the prior (x0, P0).
    pub fn ukf(model: Arc<NonlinearModel>, x0: &[f64], p0: &[f64], options: UkfOptions) -> Result<Self> {
        check_prior(model.n_states(), x0, p0)?;
        let filter = Ukf::new(model.n_states(), model.n_obs(), x0, p0, options, model.noise_inputs())?;
        Ok(Self::of(model, Box::new(filter)))
    }

    fn of(model: Arc<NonlinearModel>, filter: Box<dyn GaussianFilter>) -> Self {
        NonlinearKalmanFilter { model, filter, t: 0, filtered: false, loglik: 0.0, noise: NoiseScratch::default() }
    }

    /// The state size n.
    pub fn n_states(&self) -> usize {
        self.model.n_states()
    }

    /// The current step t.
    pub fn t(&self) -> usize {
        self.t
    }

    /// The current estimate: x̂(t|t) after an update, x̂(t|t−1) otherwise.
    pub fn x(&self) -> &[f64] {
        self.filter.state().current(self.filtered).0
    }

    /// Its covariance.
    pub fn p(&self) -> &[f64] {
        self.filter.state().current(self.filtered).1
    }

    /// The sum of the log-likelihood terms of the updates so far.
    pub fn loglik(&self) -> f64 {
        self.loglik
    }

    /// The log-likelihood term of the last update (0 when nothing was observed).
    pub fn loglik_t(&self) -> f64 {
        self.filter.state().loglik_t()
    }

    /// The number of outputs m of the model's h.
    pub fn n_obs(&self) -> usize {
        self.model.n_obs()
    }

    /// The measurement update with y(t) (NaN: missing) by the model's h and R.
    pub fn update(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<()> {
        let model = Arc::clone(&self.model);
        if let Some(steps) = model.steps() {
            if self.t >= steps {
                return Err(Error::arg_at("y", self.t, format!("the model's per-step Q/R end at step {}", steps - 1)));
            }
        }
        self.update_by(model.sensor(self.t), y, u)
    }

    /// The measurement update with y(t) by another sensor: its h (any m), R (m × m, symmetric
    /// positive semidefinite) and angular outputs.
    pub fn update_with(&mut self, sensor: Sensor<'_>, y: &[f64], u: Option<&[f64]>) -> Result<()> {
        let m = sensor.h.dim_out();
        if sensor.h.dim_in() != self.model.n_states() {
            return Err(Error::arg(
                "h",
                format!("takes {} states, the model has {}", sensor.h.dim_in(), self.model.n_states()),
            ));
        }
        if sensor.r.len() != m * m || sensor.r.iter().any(|v| !v.is_finite()) {
            return Err(Error::arg("R", format!("expected a finite ({m}, {m}) matrix for the m = {m} outputs of h")));
        }
        check_symmetric(sensor.r, m).map_err(|p| Error::arg("R", p))?;
        check_psd(sensor.r, m).map_err(|p| Error::arg("R", p))?;
        if let Some(&a) = sensor.angles.iter().find(|&&a| a >= m) {
            return Err(Error::arg("angles", format!("index {a} is not an output of h (m = {m})")));
        }
        self.update_by(sensor, y, u)
    }

    fn update_by(&mut self, sensor: Sensor<'_>, y: &[f64], u: Option<&[f64]>) -> Result<()> {
        let (t, m) = (self.t, sensor.h.dim_out());
        if y.len() != m {
            return Err(Error::arg_at("y", t, format!("expected {m} values (the outputs of h), got {}", y.len())));
        }
        check_observation(y, Some(t))?;
        if let Some(u) = u {
            check_input_row(u, Some(t))?;
        }
        if self.filtered {
            self.filter.state_mut().carry(true);
        }
        // An update writes only x̂(t|t), P(t|t): after a failure the state is its prior.
        if let Err(err) = self.filter.update(sensor, y, t, u) {
            self.filtered = false;
            return Err(err);
        }
        self.loglik += self.filter.state().loglik_t();
        self.filtered = true;
        Ok(())
    }

    /// Makes `(x, p)` the filtered estimate x̂(t|t), P(t|t) of this step, in place of an
    /// update's: the interacting multiple-model filter's mixed state (Söderström
    /// (9.72)–(9.74)) or a Gaussian-sum filter's merged component; the next
    /// [`predict`](Self::predict) starts from it. `x` has n values, `p` n × n.
    pub fn set_filtered(&mut self, x: &[f64], p: &[f64]) {
        self.filter.state_mut().set_filtered(x, p);
        self.filtered = true;
    }

    /// The time update to t + 1 (from x̂(t|t), or from x̂(t|t−1) when there was no update).
    pub fn predict(&mut self, u: Option<&[f64]>) -> Result<()> {
        let t = self.t;
        if let Some(steps) = self.model.steps() {
            if t >= steps {
                return Err(Error::arg_at("u", t, format!("the model's per-step Q/R end at step {}", steps - 1)));
            }
        }
        if let Some(u) = u {
            check_input_row(u, Some(t))?;
        }
        if !self.filtered {
            self.filter.state_mut().carry(false);
        }
        let model = Arc::clone(&self.model);
        let transition = model.transition(t, self.filter.state().current(true).0, u, &mut self.noise)?;
        self.filter.predict(transition, t, u, None)?;
        self.t += 1;
        self.filtered = false;
        Ok(())
    }
}
