//! The robust forms one step at a time, for the streaming [`KalmanFilter`](super::super::KalmanFilter):
//! the same recursions as the batch loop, behind the streaming filter's `Stream` trait.
//!
//! Every update prepares its components afresh (a step may replace H or R: `update_with`), and
//! every time update refactors Q̃; x̂ and P are formed after each half step, since the
//! streaming filter reports them.

use super::{information, sequential, sqrt, ud, Measurement, Recursion};
use crate::core::dims::{Dims, Dyn, Fixed};
use crate::core::gaussian::{LoglikSum, UpdateForm};
use crate::error::{Error, Result};
use crate::linear::filter::step::{overflowed, LastUpdate};
use crate::linear::filter::streaming::Stream;
use crate::linear::model::StepView;

/// A robust form's streaming state: the recursion, its prepared measurement, and x̂, P of
/// both halves of the step as the streaming filter reports them.
#[derive(Debug, Clone)]
struct FormStream<D: Dims, R> {
    d: D,
    form: R,
    meas: Measurement,
    /// An all-missing observation, for a time update without an update.
    nothing: Vec<f64>,
    x_pred: Vec<f64>,
    p_pred: Vec<f64>,
    x_filt: Vec<f64>,
    p_filt: Vec<f64>,
    loglik_t: f64,
    /// The gain outputs the covariance forms report (zero here: the fixed-lag smoother, their
    /// only reader, refuses the robust forms).
    gain_pred: Vec<f64>,
    /// A state set by `set_filtered` that this form could not factor, reported by the next
    /// time update.
    pending: Option<Error>,
}

/// The streaming state of `form` (a robust form) from the prior x̂(0|−1) = `x0`, P(0|−1) = `p0`.
pub(in crate::linear::filter) fn new_stream(
    form: UpdateForm,
    n: usize,
    m: usize,
    k: usize,
    x0: &[f64],
    p0: &[f64],
) -> Result<Box<dyn Stream>> {
    with_state_dims!(crate::core::isa::kernel(), n, |d| by_form(d, form, m, k, x0, p0))
}

fn by_form<D: Dims + std::fmt::Debug + 'static>(
    d: D,
    form: UpdateForm,
    m: usize,
    k: usize,
    x0: &[f64],
    p0: &[f64],
) -> Result<Box<dyn Stream>>
where
    sequential::Sequential<D>: Send + Sync,
    sqrt::SquareRoot<D>: Send + Sync,
    ud::UD<D>: Send + Sync,
    information::Information<D>: Send + Sync,
{
    Ok(match form {
        UpdateForm::Sequential => Box::new(FormStream::new(d, sequential::Sequential::<D>::new(d, x0, p0)?, m, k)),
        UpdateForm::SquareRoot => Box::new(FormStream::new(d, sqrt::SquareRoot::<D>::new(d, x0, p0)?, m, k)),
        UpdateForm::UD => Box::new(FormStream::new(d, ud::UD::<D>::new(d, x0, p0)?, m, k)),
        UpdateForm::Information => Box::new(FormStream::new(d, information::Information::<D>::new(d, x0, p0)?, m, k)),
        UpdateForm::Joseph | UpdateForm::Standard => unreachable!("the covariance forms stream in Workspace"),
    })
}

impl<D: Dims, R: Recursion<D>> FormStream<D, R> {
    fn new(d: D, form: R, m: usize, k: usize) -> Self {
        let n = d.n();
        let mut s = FormStream {
            d,
            form,
            meas: Measurement::new(n, m, k),
            nothing: vec![f64::NAN; m],
            x_pred: vec![0.0; n],
            p_pred: vec![0.0; n * n],
            x_filt: vec![0.0; n],
            p_filt: vec![0.0; n * n],
            loglik_t: 0.0,
            gain_pred: vec![0.0; n * m],
            pending: None,
        };
        s.x_pred.copy_from_slice(s.form.x());
        s.form.covariance(&mut s.p_pred);
        s
    }
}

impl<D, R> Stream for FormStream<D, R>
where
    D: Dims + std::fmt::Debug + 'static,
    R: Recursion<D> + Clone + std::fmt::Debug + Send + Sync + 'static,
{
    fn update(&mut self, sys: &StepView<'_>, y: &[f64], u: Option<&[f64]>, _form: UpdateForm, t: usize) -> Result<()> {
        self.meas.prepare(sys, y, u, false, t)?;
        let loglik_t = if self.meas.mo == 0 { 0.0 } else { self.form.update(&self.meas, t)? - self.meas.log_det_l };
        if !loglik_t.is_finite() || self.form.x().iter().any(|v| !v.is_finite()) {
            return Err(overflowed(t));
        }
        self.loglik_t = loglik_t;
        self.x_filt.copy_from_slice(self.form.x());
        self.form.covariance(&mut self.p_filt);
        Ok(())
    }

    fn predict(&mut self, sys: &StepView<'_>, u: Option<&[f64]>, updated: bool, t: usize) -> Result<()> {
        if let Some(err) = self.pending.take() {
            return Err(err);
        }
        if !updated {
            self.meas.prepare(sys, &self.nothing, u, false, t)?;
            self.loglik_t = 0.0;
            self.x_filt.copy_from_slice(self.form.x());
            self.form.covariance(&mut self.p_filt);
        }
        self.form.set_dynamics(self.meas.f_tilde(sys), self.meas.q_tilde(sys), t)?;
        self.meas.shift(sys, u);
        self.form.predict(self.meas.f_tilde(sys), &self.meas.shift, t)?;
        if self.form.x().iter().any(|v| !v.is_finite()) {
            return Err(overflowed(t));
        }
        self.x_pred.copy_from_slice(self.form.x());
        self.form.covariance(&mut self.p_pred);
        Ok(())
    }

    fn add_loglik(&self, sum: &mut LoglikSum) {
        sum.add_term(self.loglik_t);
    }

    fn loglik_t(&self) -> f64 {
        self.loglik_t
    }

    fn set_filtered(&mut self, x: &[f64], p: &[f64]) {
        // The next time update is F x + B u, F P F' + Q: no update's N terms.
        self.meas.mo = 0;
        self.meas.has_n = false;
        match R::new(self.d, x, p) {
            Ok(form) => self.form = form,
            Err(err) => self.pending = Some(err.renamed("P0", "P")),
        }
        self.x_filt.copy_from_slice(x);
        self.p_filt.copy_from_slice(p);
        self.loglik_t = 0.0;
    }

    fn x_pred(&self) -> &[f64] {
        &self.x_pred
    }
    fn p_pred(&self) -> &[f64] {
        &self.p_pred
    }
    fn x_filt(&self) -> &[f64] {
        &self.x_filt
    }
    fn p_filt(&self) -> &[f64] {
        &self.p_filt
    }
    fn gain_pred(&self) -> &[f64] {
        &self.gain_pred
    }
    fn last_update<'a>(&'a self, h: &'a [f64]) -> LastUpdate<'a> {
        LastUpdate { m_obs: 0, h: &h[..0], s_factor: &[], s_inv_e: &[] }
    }
    fn boxed_clone(&self) -> Box<dyn Stream> {
        Box::new(self.clone())
    }
}
