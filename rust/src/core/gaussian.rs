//! The Gaussian measurement update, model-agnostic: every filter that approximates the joint
//! distribution of the state and the measurement as Gaussian ends each step with it.
//!
//! Given the prior `x̂(t|t−1), P(t|t−1)` and what a model predicts about the measurement —
//! the innovation `e = y − ŷ`, the cross-covariance `C = Cov(x, y)` and the innovation
//! covariance `S = Cov(y)` — the update is (Söderström Lemma 6.1, (6.22)–(6.24); the same
//! conditioning of a joint Gaussian that the EKF and the UKF apply to their own `C` and `S`):
//!
//! ```text
//! K = C S⁻¹                             (filter gain)
//! x̂(t|t) = x̂(t|t−1) + K e
//! P(t|t) = P − K S K' = P − C K'         (standard form)
//!        = (I − K H) P (I − K H)' + K R K'   (Joseph form; needs H with C = P H' and R)
//! log p(y(t) | y(0..t−1)) = −½ (m ln 2π + ln det S + e' S⁻¹ e)   (Söderström (6.142))
//! ```
//!
//! A linear model gives `C = P H'` and `S = H P H' + R` ([`crate::linear::filter`]); an
//! extended filter the same with the Jacobian for H; a sigma-point filter `C` and `S` from its
//! points (then only the standard form applies). S is factored as L D L' (no square roots: the
//! factorization sits on the step's latency chain) and never inverted.

use crate::core::dense::{
    ldl, ldl_log_det, ldl_solve, ldl_solve_quad, mul, mul_bt, mul_bt_sym, mul_sym, mul_vec_add, transpose,
};
use crate::core::dims::{Buf, Dims};
use crate::error::{Error, Result};

/// ln 2π.
pub(crate) const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// How the filtered covariance `P(t|t)` is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum UpdateForm {
    /// `(I − K H) P (I − K H)' + K R K'`: a sum of congruences, stays symmetric PSD under
    /// rounding, and is right for any gain (Grewal & Andrews (5.27); Söderström (6.24) with
    /// the suboptimal-gain remark). The default.
    #[default]
    Joseph,
    /// `P − K S K'`: cheaper, can lose definiteness when S is ill-conditioned.
    Standard,
}

/// What the model predicts about the `mo` observed components of y(t), row-major.
pub(crate) struct MeasurementPrediction<'a> {
    /// The innovation `e = y − ŷ` (mo).
    pub innov: &'a [f64],
    /// `C = Cov(x(t), y(t) | y(0..t−1))` (n × mo): `P H'` for a linear(ized) measurement.
    pub cross_cov: &'a [f64],
    /// `S = Cov(y(t) | y(0..t−1))` (mo × mo), symmetric.
    pub innov_cov: &'a [f64],
    /// `H` (mo × n) and `R` (mo × mo) of a linear(ized) measurement, for the Joseph form;
    /// `None` for the standard form.
    pub joseph: Option<(&'a [f64], &'a [f64])>,
}

/// The update's results that later steps read (the gain, the factor of S and S⁻¹ e), and its
/// scratch; sized once for (n, m), used for any `mo ≤ m` observed components.
#[derive(Debug, Clone)]
pub(crate) struct GaussianUpdate<D: Dims> {
    /// L D L' factor of S (mo × mo, unit L below the diagonal, D on it).
    s_factor: D::ObsSquare,
    /// S⁻¹ e (mo).
    s_inv_e: D::Obs,
    /// K' = S⁻¹ C' (mo × n).
    gain_t: D::StateObs,
    /// ln det S of the last full update, and its log-likelihood term.
    log_det: f64,
    loglik_t: f64,
    // Scratch: K (n × mo), R K' (mo × n), two n × n.
    gain: D::StateObs,
    r_gain_t: D::StateObs,
    nn_a: D::Square,
    nn_b: D::Square,
}

impl<D: Dims> GaussianUpdate<D> {
    #[inline(always)]
    pub fn new(d: D) -> Self {
        GaussianUpdate {
            s_factor: d.obs_square(),
            s_inv_e: d.obs(),
            gain_t: d.state_obs(),
            log_det: 0.0,
            loglik_t: 0.0,
            gain: d.state_obs(),
            r_gain_t: d.state_obs(),
            nn_a: d.square(),
            nn_b: d.square(),
        }
    }

    /// Makes this a copy of `other` without allocating (see `Workspace::copy_from`).
    #[inline(always)]
    pub fn copy_from(&mut self, other: &Self) {
        let GaussianUpdate { s_factor, s_inv_e, gain_t, log_det, loglik_t, gain, r_gain_t, nn_a, nn_b } = other;
        (self.log_det, self.loglik_t) = (*log_det, *loglik_t);
        self.s_factor.clone_from(s_factor);
        self.s_inv_e.clone_from(s_inv_e);
        self.gain_t.clone_from(gain_t);
        self.gain.clone_from(gain);
        self.r_gain_t.clone_from(r_gain_t);
        self.nn_a.clone_from(nn_a);
        self.nn_b.clone_from(nn_b);
    }

    /// The update of `(x_pred, p_pred)` by the `mo` observed components predicted in `pred`,
    /// into `(x_filt, p_filt)`. Fails (naming step `t`) when S is not positive definite.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn apply(
        &mut self,
        d: D,
        mo: usize,
        pred: &MeasurementPrediction<'_>,
        x_pred: &[f64],
        p_pred: &[f64],
        x_filt: &mut [f64],
        p_filt: &mut [f64],
        t: usize,
    ) -> Result<()> {
        let n = d.n();
        let s_factor = &mut self.s_factor.get_mut()[..mo * mo];
        if let Err(j) = ldl(s_factor, &pred.innov_cov[..mo * mo], mo) {
            return Err(not_positive_definite(t, j, mo));
        }
        let s_factor = &self.s_factor.get()[..mo * mo];
        self.log_det = ldl_log_det(s_factor, mo);
        let s_inv_e = &mut self.s_inv_e.get_mut()[..mo];
        s_inv_e.copy_from_slice(&pred.innov[..mo]);
        let quad = ldl_solve_quad(s_factor, s_inv_e, mo);
        self.loglik_t = -0.5 * (mo as f64 * LN_2PI + self.log_det + quad);

        // K' = S⁻¹ C' by solves with the factor of S (never S⁻¹ itself).
        let cross_cov = &pred.cross_cov[..n * mo];
        let gain_t = &mut self.gain_t.get_mut()[..mo * n];
        transpose(gain_t, cross_cov, n, mo);
        ldl_solve(s_factor, gain_t, mo, n);
        let gain_t = &self.gain_t.get()[..mo * n];

        // x̂(t|t) = x̂(t|t−1) + C S⁻¹ e
        x_filt.copy_from_slice(x_pred);
        mul_vec_add(x_filt, cross_cov, s_inv_e, n, mo);

        match pred.joseph {
            None => {
                // P − K S K' = P − C K'
                let ksk = self.nn_a.get_mut();
                mul_sym::<D>(ksk, cross_cov, gain_t, n, mo);
                for ((pf, p), ksk) in p_filt.iter_mut().zip(p_pred).zip(ksk.iter()) {
                    *pf = p - ksk;
                }
            }
            Some((h, r)) => {
                // A = I − K H;  P(t|t) = (A P) A' + K R K'
                let gain = &mut self.gain.get_mut()[..n * mo];
                transpose(gain, gain_t, mo, n);
                let a = self.nn_a.get_mut();
                mul::<D>(a, gain, &h[..mo * n], n, mo, n);
                for v in a.iter_mut() {
                    *v = -*v;
                }
                for i in 0..n {
                    a[i * n + i] += 1.0;
                }
                // A P = P − K (H P) with H P = C': n² m multiply-adds instead of n³
                let ap = self.nn_b.get_mut();
                mul_bt::<D>(ap, gain, cross_cov, n, mo, n);
                for (v, p) in ap.iter_mut().zip(p_pred) {
                    *v = p - *v;
                }
                mul_bt_sym::<D>(p_filt, ap, a, n, n);
                // K R K' = K (R K')
                let r_gain_t = &mut self.r_gain_t.get_mut()[..mo * n];
                mul::<D>(r_gain_t, &r[..mo * mo], gain_t, mo, mo, n);
                let krk = self.nn_b.get_mut();
                mul_sym::<D>(krk, gain, r_gain_t, n, mo);
                for (pf, krk) in p_filt.iter_mut().zip(krk.iter()) {
                    *pf += krk;
                }
            }
        }
        // P(t|t) is exactly symmetric already: P(t|t−1) is, and both forms add mirrored
        // symmetric products (mul_sym, mul_bt_sym), so no symmetrization here.
        Ok(())
    }

    /// The update of the mean alone with the S factor and ln det S of an earlier update kept
    /// (frozen gains, all `m` components observed): `x̂(t|t) = x̂(t|t−1) + C S⁻¹ e`.
    #[inline(always)]
    pub fn apply_mean(&mut self, d: D, innov: &[f64], cross_cov: &[f64], x_pred: &[f64], x_filt: &mut [f64]) {
        let (n, m) = (d.n(), d.m());
        let s_inv_e = &mut self.s_inv_e.get_mut()[..m];
        s_inv_e.copy_from_slice(&innov[..m]);
        let quad = ldl_solve_quad(&self.s_factor.get()[..m * m], s_inv_e, m);
        self.loglik_t = -0.5 * (m as f64 * LN_2PI + self.log_det + quad);
        x_filt.copy_from_slice(x_pred);
        mul_vec_add(x_filt, &cross_cov[..n * m], s_inv_e, n, m);
    }

    /// Loads the factor of S and ln det S recorded from another update (see
    /// [`s_factor`](Self::s_factor)), for [`apply_mean`](Self::apply_mean).
    pub fn load_factor(&mut self, s_factor: &[f64], log_det: f64) {
        self.s_factor.get_mut()[..s_factor.len()].copy_from_slice(s_factor);
        self.log_det = log_det;
    }

    /// The L D L' factor of S of the last update (mo × mo).
    #[inline(always)]
    pub fn s_factor(&self, mo: usize) -> &[f64] {
        &self.s_factor.get()[..mo * mo]
    }

    /// S⁻¹ e of the last update (mo).
    #[inline(always)]
    pub fn s_inv_e(&self, mo: usize) -> &[f64] {
        &self.s_inv_e.get()[..mo]
    }

    /// K' = S⁻¹ C' of the last full update (mo × n).
    #[inline(always)]
    pub fn gain_t(&self, mo: usize, n: usize) -> &[f64] {
        &self.gain_t.get()[..mo * n]
    }

    /// ln det S of the last full update.
    pub fn log_det(&self) -> f64 {
        self.log_det
    }

    /// The log-likelihood term of the last update.
    #[inline(always)]
    pub fn loglik_t(&self) -> f64 {
        self.loglik_t
    }

    /// Sets the log-likelihood term (0 for a step with nothing observed).
    pub fn set_loglik_t(&mut self, v: f64) {
        self.loglik_t = v;
    }
}

/// The error for an S whose pivot `j` failed (out of line: the time loop keeps only a branch).
#[cold]
#[inline(never)]
fn not_positive_definite(t: usize, j: usize, mo: usize) -> Error {
    Error::InnovationCovariance {
        step: t,
        problem: format!(
            "not positive definite to working precision (pivot {j} of the {mo} observed \
             components is not above rounding: that component is a linear function of the \
             others); R may be singular where H P H' is too"
        ),
    }
}
