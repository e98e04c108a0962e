//! [`NonlinearModel`]: f, h, Q, R and the angular outputs, validated once.

use std::sync::Arc;

use super::filter::Sensor;
use super::function::PointFunction;
use crate::core::validate::{check_input_row, check_observations, check_prior, check_psd, check_symmetric};
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::model::StepMatrix;

/// The nonlinear model with additive Gaussian noise (prior x(0|−1) ~ N(x0, P0)):
///
/// ```text
/// x[t+1] = f(x[t], t, u[t]) + w[t]     w ~ N(0, Q[t])
/// y[t]   = h(x[t], t, u[t]) + v[t]     v ~ N(0, R[t])
/// ```
///
/// Q and R are constant or given per step as in [`LinearGaussian`](crate::LinearGaussian)
/// (`Q[t]` takes `x[t]` to `x[t+1]`, `R[t]` goes with `y[t]`); a singular Q (even 0) is allowed.
/// `angles` lists the components of y that are angles: innovations and sigma-point deviations
/// of those components are wrapped to [−π, π).
#[derive(Clone)]
pub struct NonlinearModel {
    f: Arc<dyn PointFunction>,
    h: Arc<dyn PointFunction>,
    q: StepMatrix,
    r: StepMatrix,
    angles: Vec<usize>,
}

impl std::fmt::Debug for NonlinearModel {
    fn fmt(&self, out: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(out, "NonlinearModel(n = {}, m = {}, angles = {:?})", self.n_states(), self.n_obs(), self.angles)
    }
}

impl NonlinearModel {
    /// Validates the model once: f maps n states to n, h maps n states to m outputs, Q is
    /// n × n and R m × m (constant or per step, stacks of one length), both symmetric positive
    /// semidefinite and finite, and `angles` are distinct output indices.
    pub fn new(
        f: Arc<dyn PointFunction>,
        h: Arc<dyn PointFunction>,
        q: StepMatrix,
        r: StepMatrix,
        angles: Vec<usize>,
    ) -> Result<Self> {
        let n = f.dim_in();
        if f.dim_out() != n {
            return Err(Error::arg("f", format!("maps {n} states to {} numbers, not to {n}", f.dim_out())));
        }
        if h.dim_in() != n {
            return Err(Error::arg("h", format!("takes {} states, but f takes n = {n}", h.dim_in())));
        }
        let m = h.dim_out();
        check_covariance("Q", &q, n)?;
        check_covariance("R", &r, m)?;
        if let (Some(a), Some(b)) = (q.steps(), r.steps()) {
            if a != b {
                return Err(Error::arg("R", format!("has {b} steps but Q has {a}")));
            }
        }
        for (i, &a) in angles.iter().enumerate() {
            if a >= m {
                return Err(Error::arg("angles", format!("index {a} is not an output of h (m = {m})")));
            }
            if angles[..i].contains(&a) {
                return Err(Error::arg("angles", format!("index {a} is listed twice")));
            }
        }
        Ok(NonlinearModel { f, h, q, r, angles })
    }

    /// The state size n.
    pub fn n_states(&self) -> usize {
        self.f.dim_in()
    }

    /// The output size m.
    pub fn n_obs(&self) -> usize {
        self.h.dim_out()
    }

    /// The number of per-step noise covariances, if Q or R is given per step.
    pub fn steps(&self) -> Option<usize> {
        self.q.steps().or(self.r.steps())
    }

    /// Whether f and h can run on several threads at once (see [`PointFunction::parallel`]).
    pub fn parallel(&self) -> bool {
        self.f.parallel() && self.h.parallel()
    }

    /// The angular outputs.
    pub fn angles(&self) -> &[usize] {
        &self.angles
    }

    pub(crate) fn f(&self) -> &dyn PointFunction {
        &*self.f
    }

    /// The measurement model of step t.
    pub(crate) fn sensor(&self, t: usize) -> Sensor<'_> {
        Sensor { h: &*self.h, r: self.r.at(t), angles: &self.angles }
    }

    pub(crate) fn q_at(&self, t: usize) -> &[f64] {
        self.q.at(t)
    }

    /// Validates data, inputs and prior for a run; returns T.
    pub(crate) fn check_run(&self, y: Series<'_>, u: Option<Series<'_>>, x0: &[f64], p0: &[f64]) -> Result<usize> {
        let steps = check_observations(y, self.n_obs(), self.steps())?;
        if let Some(u) = u {
            if u.steps() != steps {
                return Err(Error::arg("u", format!("has {} steps but y has {steps}", u.steps())));
            }
            for t in 0..steps {
                check_input_row(u.row(t), Some(t))?;
            }
        }
        check_prior(self.n_states(), x0, p0)?;
        Ok(steps)
    }
}

fn check_covariance(arg: &'static str, mat: &StepMatrix, size: usize) -> Result<()> {
    if mat.rows() != size || mat.cols() != size {
        return Err(Error::arg(arg, format!("expected ({size}, {size}), got ({}, {})", mat.rows(), mat.cols())));
    }
    for t in 0..mat.steps().unwrap_or(1) {
        let step = mat.steps().map(|_| t);
        let a = mat.at(t);
        if let Some(v) = a.iter().find(|v| !v.is_finite()) {
            return Err(Error::arg(arg, format!("contains a non-finite value ({v})")).at_step(step));
        }
        check_symmetric(a, size).map_err(|p| Error::arg(arg, p).at_step(step))?;
        check_psd(a, size).map_err(|p| Error::arg(arg, p).at_step(step))?;
    }
    Ok(())
}
