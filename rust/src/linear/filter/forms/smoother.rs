//! The RTS smoother in square-root form, after the square-root filter (docs/algorithms.md,
//! "Update forms"): the smoothed covariance as a lower triangular factor S(t|T−1), never
//! formed in the recursion.
//!
//! With F̃ and Q̃ of the decorrelated model (the module docs of `forms`) and the factors
//! S(t|t), S(t+1|t) of the forward pass, the gain J = P(t|t) F̃' P(t+1|t)⁻¹ (the RTS gain
//! (P F' − K N') P(t+1|t)⁻¹ of docs/algorithms.md, "RTS") is
//!
//! ```text
//! W = S(t+1|t)⁻¹ F̃ S(t|t)        J = S(t|t) W' S(t+1|t)⁻¹          (triangular solves)
//! ```
//!
//! and P(t|T−1) = P(t|t) − J P(t+1|t) J' + J P(t+1|T−1) J' equals the sum of congruences
//! (I − J F̃) P(t|t) (I − J F̃)' + J Q̃ J' + J P(t+1|T−1) J' (because J P(t+1|t) = P(t|t) F̃'), so
//!
//! ```text
//! [ (I − J F̃) S(t|t)   J √Q̃   J S(t+1|T−1) ] Θ = [ S(t|T−1)  0  0 ]
//! ```
//!
//! by Householder reflections (an LQ factorization). A step whose S(t+1|t) has a pivot at
//! rounding level (a singular P(t+1|t): Q = 0 with a singular F, R = 0) takes J from the
//! pseudo-inverse as the covariance-form smoother does, forming P(t|t) and P(t+1|t) for that
//! step only.

use super::sqrt::{lower_product, lq_lower, positive_diagonal, SquareRoot};
use super::{drive, not_psd, psd_cholesky, FactorStore, Measurement};
use crate::core::dense::{solve_lower, solve_lower_t};
use crate::core::dims::{Dims, Dyn, Fixed};
use crate::core::isa::run_best;
use crate::error::Result;
use crate::linear::filter::outputs::FilterOutputs;
use crate::linear::filter::Run;
use crate::linear::smoother::{pseudo_inverse_failed, solve_psd};

/// The smoother's buffers besides the filter's: x̂(t|t) copied out before it is smoothed in
/// place, P(t|T−1) and the lag-one covariances Cov(x(t), x(t−1) | all data) `(T, n, n)`
/// (formed when given).
pub(crate) struct SquareRootSmootherOutputs<'a> {
    pub x_filt: Option<&'a mut [f64]>,
    pub p_smooth: Option<&'a mut [f64]>,
    pub p_lag1: Option<&'a mut [f64]>,
}

/// The square-root filter, storing the outputs given in `out` (`out.x_pred` and `out.x_filt`
/// required: x̂(t|t) is smoothed in place into x̂(t|T−1)), then the square-root RTS backward
/// pass; returns the log-likelihood.
pub(crate) fn smooth_square_root(
    run: &Run<'_>,
    out: &mut FilterOutputs<'_>,
    smooth: SquareRootSmootherOutputs<'_>,
) -> Result<f64> {
    with_state_dims!(run.kernel, run.model.n_states(), |d| in_best_loop(d, run, out, smooth))
}

/// [`smooth_in`] for the call's instruction set, in the size's codegen unit (as the filter).
fn in_best_loop<D: Dims>(
    d: D,
    run: &Run<'_>,
    out: &mut FilterOutputs<'_>,
    smooth: SquareRootSmootherOutputs<'_>,
) -> Result<f64> {
    run_best!(run.kernel, d, |d| smooth_in(d, run, out, smooth))
}

#[inline(always)]
fn smooth_in<D: Dims>(
    d: D,
    run: &Run<'_>,
    out: &mut FilterOutputs<'_>,
    smooth: SquareRootSmootherOutputs<'_>,
) -> Result<f64> {
    let n = d.n();
    let steps = run.y.steps();
    let (mut filt, mut pred) = (vec![0.0; steps * n * n], vec![0.0; steps * n * n]);
    let mut store = FactorStore { filt: &mut filt, pred: &mut pred };
    let loglik = drive::<D, SquareRoot<D>>(d, run, out, Some(&mut store))?;
    let SquareRootSmootherOutputs { x_filt, mut p_smooth, mut p_lag1 } = smooth;
    let (x_pred, x_smooth) = (out.x_pred.as_deref().unwrap_or_default(), out.x_filt.as_deref_mut().unwrap_or_default());
    if let Some(xf) = x_filt {
        xf.copy_from_slice(x_smooth);
    }
    let mut back = Backward::new(d, run);
    let nn = n * n;
    // S(T−1|T−1) = S(T−1|T−1); then backwards.
    let mut s_next = filt[(steps - 1) * nn..][..nn].to_vec();
    if let Some(p) = p_smooth.as_deref_mut() {
        lower_product(&s_next, &mut p[(steps - 1) * nn..][..nn], n);
    }
    if let Some(l) = p_lag1.as_deref_mut() {
        l[..nn].fill(0.0);
    }
    for t in (0..steps.saturating_sub(1)).rev() {
        let (s_filt, s_pred) = (&filt[t * nn..][..nn], &pred[(t + 1) * nn..][..nn]);
        back.gain(run, t, s_filt, s_pred)?;
        // x̂(t|T−1) = x̂(t|t) + J (x̂(t+1|T−1) − x̂(t+1|t))
        let (x_cur, x_next) = x_smooth[t * n..(t + 2) * n].split_at_mut(n);
        for (i, x) in x_cur.iter_mut().enumerate() {
            *x += (0..n).map(|k| back.j[i * n + k] * (x_next[k] - x_pred[(t + 1) * n + k])).sum::<f64>();
        }
        if let Some(l) = p_lag1.as_deref_mut() {
            // Cov(x(t+1), x(t) | all) = P(t+1|T−1) J(t)'.
            let p_next = &mut back.p_scratch;
            lower_product(&s_next, p_next, n);
            for i in 0..n {
                for k in 0..n {
                    l[(t + 1) * nn + i * n + k] = (0..n).map(|c| p_next[i * n + c] * back.j[k * n + c]).sum();
                }
            }
        }
        back.factor(s_filt, &mut s_next);
        if let Some(p) = p_smooth.as_deref_mut() {
            lower_product(&s_next, &mut p[t * nn..][..nn], n);
        }
    }
    Ok(loglik)
}

/// The backward pass's per-step state: F̃, √Q̃ (refactored when they change) and J.
struct Backward {
    n: usize,
    meas: Measurement,
    constant: bool,
    q_factor: Vec<f64>,
    j: Vec<f64>,
    /// Scratch: F̃ S(t|t), W, the pre-array's blocks.
    fs: Vec<f64>,
    w: Vec<f64>,
    left: Vec<f64>,
    right: Vec<f64>,
    f_tilde: Vec<f64>,
    /// P(t+1|T−1) formed for the lag-one covariance.
    p_scratch: Vec<f64>,
}

impl Backward {
    fn new<D: Dims>(d: D, run: &Run<'_>) -> Self {
        let n = d.n();
        Backward {
            n,
            meas: Measurement::new(n, run.model.n_obs(), run.model.n_inputs()),
            constant: run.model.steps().is_none(),
            q_factor: vec![0.0; n * n],
            j: vec![0.0; n * n],
            fs: vec![0.0; n * n],
            w: vec![0.0; n * n],
            left: vec![0.0; n * n],
            right: vec![0.0; 2 * n * n],
            f_tilde: vec![0.0; n * n],
            p_scratch: vec![0.0; n * n],
        }
    }

    /// F̃(t), √Q̃(t) and J(t) from S(t|t) and S(t+1|t).
    fn gain(&mut self, run: &Run<'_>, t: usize, s_filt: &[f64], s_pred: &[f64]) -> Result<()> {
        let n = self.n;
        let sys = run.model.at(t);
        let changed = self.meas.prepare(&sys, run.y.row(t), run.u.map(|u| u.row(t)), self.constant, t)?;
        if changed {
            psd_cholesky(&mut self.q_factor, self.meas.q_tilde(&sys), n)
                .map_err(|_| not_psd("Q", Some(t), "Q − N R⁻¹ N' (or Q)"))?;
            self.f_tilde.copy_from_slice(self.meas.f_tilde(&sys));
        }
        let f = &self.f_tilde;
        // F̃ S(t|t) (S lower triangular).
        for i in 0..n {
            for c in 0..n {
                self.fs[i * n + c] = (c..n).map(|k| f[i * n + k] * s_filt[k * n + c]).sum();
            }
        }
        let p_pred_diag = (0..n).map(|i| (0..=i).map(|k| s_pred[i * n + k] * s_pred[i * n + k]).sum::<f64>());
        let floor = 32.0 * n as f64 * f64::EPSILON * p_pred_diag.fold(0.0, f64::max);
        if (0..n).any(|i| s_pred[i * n + i] * s_pred[i * n + i] <= floor) {
            return self.gain_by_pseudo_inverse(t, s_filt, s_pred);
        }
        // W = S(t+1|t)⁻¹ F̃ S(t|t); M = S(t|t) W'; J = M S(t+1|t)⁻¹, i.e. S(t+1|t)' J' = M'.
        self.w.copy_from_slice(&self.fs);
        solve_lower(s_pred, &mut self.w, n, n);
        // J' (in `left` as scratch) = M' = W S(t|t)'.
        for r in 0..n {
            for c in 0..n {
                self.left[r * n + c] = (0..=c).map(|k| self.w[r * n + k] * s_filt[c * n + k]).sum();
            }
        }
        solve_lower_t(s_pred, &mut self.left, n, n);
        for r in 0..n {
            for c in 0..n {
                self.j[r * n + c] = self.left[c * n + r];
            }
        }
        Ok(())
    }

    /// J' = P(t+1|t)⁺ F̃ P(t|t) with the covariances formed (a singular P(t+1|t)).
    #[cold]
    fn gain_by_pseudo_inverse(&mut self, t: usize, s_filt: &[f64], s_pred: &[f64]) -> Result<()> {
        let n = self.n;
        let mut p_pred = vec![0.0; n * n];
        lower_product(s_pred, &mut p_pred, n);
        // F̃ P(t|t) = (F̃ S) S'.
        let mut jt: Vec<f64> = (0..n * n)
            .map(|rc| {
                let (r, c) = (rc / n, rc % n);
                (0..=c).map(|k| self.fs[r * n + k] * s_filt[c * n + k]).sum()
            })
            .collect();
        let mut factor = vec![0.0; n * n];
        solve_psd::<Dyn>(&p_pred, &mut jt, &mut factor, n).map_err(|e| pseudo_inverse_failed(e, t))?;
        for r in 0..n {
            for c in 0..n {
                self.j[r * n + c] = jt[c * n + r];
            }
        }
        Ok(())
    }

    /// S(t|T−1) from the pre-array [(I − J F̃) S(t|t)  J √Q̃  J S(t+1|T−1)], into `s_next`.
    fn factor(&mut self, s_filt: &[f64], s_next: &mut [f64]) {
        let n = self.n;
        let j = &self.j;
        // (I − J F̃) S(t|t) = S(t|t) − J (F̃ S(t|t)).
        for r in 0..n {
            for c in 0..n {
                let jfs: f64 = (0..n).map(|k| j[r * n + k] * self.fs[k * n + c]).sum();
                self.left[r * n + c] = s_filt[r * n + c] - jfs;
            }
        }
        for r in 0..n {
            for c in 0..n {
                self.right[r * 2 * n + c] = (c..n).map(|k| j[r * n + k] * self.q_factor[k * n + c]).sum();
                self.right[r * 2 * n + n + c] = (c..n).map(|k| j[r * n + k] * s_next[k * n + c]).sum();
            }
        }
        lq_lower(&mut self.left, &mut self.right, n, 2 * n);
        positive_diagonal(&mut self.left, n);
        s_next.copy_from_slice(&self.left);
    }
}
