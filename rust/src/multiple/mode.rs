//! [`ModeFilter`]: what a multiple-model filter needs of the filter of one mode.

use std::borrow::Borrow;

use crate::error::Result;
use crate::linear::filter::KalmanFilter;
use crate::linear::model::LinearGaussian;
use crate::nonlinear::NonlinearKalmanFilter;

/// The filter of one mode: the linear [`KalmanFilter`] or the EKF/UKF
/// ([`NonlinearKalmanFilter`]), each one step at a time from its own prior.
pub trait ModeFilter: Send + Sync {
    /// The state size n of the mode.
    fn n_states(&self) -> usize;
    /// The number of outputs m (every mode sees the same y).
    fn n_obs(&self) -> usize;
    /// The measurement update with y(t) (NaN: missing); returns the log-likelihood term
    /// log ℓ = log γ(y; ŷ, S) (0 when nothing was observed), Söderström (9.80)–(9.81).
    fn update(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<f64>;
    /// x̂(t|t), P(t|t) after an update, x̂(t|t−1), P(t|t−1) before it.
    fn current(&self) -> (&[f64], &[f64]);
    /// The time update from [`current`](Self::current).
    fn predict(&mut self, u: Option<&[f64]>) -> Result<()>;
    /// Makes `(x, p)` the filtered estimate x̂(t|t), P(t|t): the mixed state of the
    /// interacting multiple-model filter, Söderström (9.72)–(9.73), or a merged component.
    fn set_filtered(&mut self, x: &[f64], p: &[f64]);
    /// Why the mode cannot start its time update from a mixed state, if it cannot.
    fn refuses_mixing(&self) -> Option<&'static str> {
        None
    }
    /// A copy.
    fn boxed_clone(&self) -> Box<dyn ModeFilter>;
}

impl<M> ModeFilter for KalmanFilter<M>
where
    M: Borrow<LinearGaussian> + Clone + Send + Sync + 'static,
{
    fn n_states(&self) -> usize {
        self.model().n_states()
    }
    fn n_obs(&self) -> usize {
        self.model().n_obs()
    }
    fn update(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<f64> {
        KalmanFilter::update(self, y, u)?;
        Ok(self.loglik_t())
    }
    fn current(&self) -> (&[f64], &[f64]) {
        (self.x(), self.p())
    }
    fn predict(&mut self, u: Option<&[f64]>) -> Result<()> {
        KalmanFilter::predict(self, u)
    }
    fn set_filtered(&mut self, x: &[f64], p: &[f64]) {
        KalmanFilter::set_filtered(self, x, p)
    }
    fn refuses_mixing(&self) -> Option<&'static str> {
        // With N the time update uses the update's innovation (Söderström (6.25)), which a
        // mixed state does not have.
        self.model().matrices().n.as_ref().map(|_| "a model with N = E[w v'] (correlated noise) cannot be mixed")
    }
    fn boxed_clone(&self) -> Box<dyn ModeFilter> {
        Box::new(self.clone())
    }
}

impl ModeFilter for NonlinearKalmanFilter {
    fn n_states(&self) -> usize {
        NonlinearKalmanFilter::n_states(self)
    }
    fn n_obs(&self) -> usize {
        NonlinearKalmanFilter::n_obs(self)
    }
    fn update(&mut self, y: &[f64], u: Option<&[f64]>) -> Result<f64> {
        NonlinearKalmanFilter::update(self, y, u)?;
        Ok(self.loglik_t())
    }
    fn current(&self) -> (&[f64], &[f64]) {
        (self.x(), self.p())
    }
    fn predict(&mut self, u: Option<&[f64]>) -> Result<()> {
        NonlinearKalmanFilter::predict(self, u)
    }
    fn set_filtered(&mut self, x: &[f64], p: &[f64]) {
        NonlinearKalmanFilter::set_filtered(self, x, p)
    }
    fn boxed_clone(&self) -> Box<dyn ModeFilter> {
        Box::new(self.clone())
    }
}
