//! One step of the Kalman filter: the measurement update and the time update, on a workspace
//! allocated once per sequence so that the time loop allocates nothing.
//!
//! Söderström Lemma 6.1, (6.22)–(6.27), in kfast notation (docs/algorithms.md, "Filter recursion"):
//!
//! ```text
//! e = y − H x̂(t|t−1) − D u            S = H P(t|t−1) H' + R
//! K = P(t|t−1) H' S⁻¹                  x̂(t|t) = x̂(t|t−1) + K e
//! P(t|t) = P − K S K'                   (standard, symmetrized)
//!        = (I − K H) P (I − K H)' + K R K'    (Joseph form, valid for any gain)
//! x̂(t+1|t) = F x̂(t|t) + B u + N S⁻¹ e
//! P(t+1|t) = F P(t|t) F' + Q − N S⁻¹ N' − F K N' − N K' F'
//! K_pred  = F K + N S⁻¹ = (F P H' + N) S⁻¹
//! ```
//!
//! Missing data: only the observed components of y update (their rows of H, D, R and columns of
//! N); a step with nothing observed skips the update and its time update has no N term.

use crate::dense::{
    ldl, ldl_log_det, ldl_solve, ldl_solve_quad, mul, mul_bt, mul_bt_sym, mul_sym, mul_vec, mul_vec_add, symmetrize,
    transpose,
};
use crate::error::{Error, Result};
use crate::model::StepView;

use super::{FilterOutputs, Run};

/// How the filtered covariance `P(t|t)` is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UpdateForm {
    /// `(I − K H) P (I − K H)' + K R K'`: a sum of congruences, stays symmetric PSD under
    /// rounding (docs/algorithms.md, "Joseph form"). The default.
    #[default]
    Joseph,
    /// `P − K S K'`, symmetrized: cheaper, can lose definiteness when S is ill-conditioned.
    Standard,
}

pub(crate) const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// The state and output sizes (n, m) of a step. [`Fixed`] makes them compile-time constants so
/// that the small dense loops are unrolled for the common sizes (chosen once per call by the
/// drivers); [`Dyn`] serves every other size. The arithmetic is identical.
pub(crate) trait Dims: Copy {
    /// Scratch for an n × n matrix and an n-vector: local arrays for [`Fixed`] sizes (which
    /// the compiler can keep in registers), heap vectors for [`Dyn`].
    type Square: Buf;
    type Vector: Buf;

    fn n(self) -> usize;
    fn m(self) -> usize;

    fn square(self) -> Self::Square {
        Buf::zeroed(self.n() * self.n())
    }
    fn vector(self) -> Self::Vector {
        Buf::zeroed(self.n())
    }

    /// The filter loop on local fixed-size arrays ([`super::fixed`]) when the sizes are
    /// compile-time ones and the model allows it; `None` runs the general loop.
    #[inline(always)]
    fn filter_fixed(self, _run: &Run<'_>, _ws: &mut Workspace, _out: &mut FilterOutputs<'_>) -> Option<Result<f64>> {
        None
    }
}

/// Sizes known at run time.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Dyn {
    pub n: usize,
    pub m: usize,
}

impl Dims for Dyn {
    type Square = Vec<f64>;
    type Vector = Vec<f64>;

    #[inline(always)]
    fn n(self) -> usize {
        self.n
    }
    #[inline(always)]
    fn m(self) -> usize {
        self.m
    }
}

/// Sizes known at compile time.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fixed<const N: usize, const M: usize>;

impl<const N: usize, const M: usize> Dims for Fixed<N, M> {
    type Square = [[f64; N]; N];
    type Vector = [[f64; N]; 1];

    #[inline(always)]
    fn n(self) -> usize {
        N
    }
    #[inline(always)]
    fn m(self) -> usize {
        M
    }
    #[inline(always)]
    fn filter_fixed(self, run: &Run<'_>, ws: &mut Workspace, out: &mut FilterOutputs<'_>) -> Option<Result<f64>> {
        run.filter_fixed::<N, M>(ws, out)
    }
}

/// A scratch buffer of `f64`s seen as one slice.
pub(crate) trait Buf {
    /// `len` zeros (a fixed-size buffer ignores `len`: its size is its type's).
    fn zeroed(len: usize) -> Self;
    fn get(&self) -> &[f64];
    fn get_mut(&mut self) -> &mut [f64];
}

impl Buf for Vec<f64> {
    fn zeroed(len: usize) -> Self {
        vec![0.0; len]
    }
    #[inline(always)]
    fn get(&self) -> &[f64] {
        self
    }
    #[inline(always)]
    fn get_mut(&mut self) -> &mut [f64] {
        self
    }
}

impl<const R: usize, const C: usize> Buf for [[f64; C]; R] {
    #[inline(always)]
    fn zeroed(_len: usize) -> Self {
        [[0.0; C]; R]
    }
    #[inline(always)]
    fn get(&self) -> &[f64] {
        self.as_flattened()
    }
    #[inline(always)]
    fn get_mut(&mut self) -> &mut [f64] {
        self.as_flattened_mut()
    }
}

/// Buffers for one filter; sizes fixed by (n, m, k) at construction.
#[derive(Debug, Clone)]
pub(crate) struct Workspace {
    pub n: usize,
    pub m: usize,
    pub k: usize,
    /// x̂(t|t−1), P(t|t−1): the state before the update (and after the time update).
    pub x_pred: Vec<f64>,
    pub p_pred: Vec<f64>,
    /// x̂(t|t), P(t|t).
    pub x_filt: Vec<f64>,
    pub p_filt: Vec<f64>,
    /// Innovation of every component (NaN where missing), and the full S (m × m).
    pub innov: Vec<f64>,
    pub s_full: Vec<f64>,
    /// Filter gain and predictor gain, n × m, zero columns for missing components.
    pub gain: Vec<f64>,
    pub gain_pred: Vec<f64>,
    pub loglik_t: f64,
    /// Freeze the covariance recursion once ‖P(t+1|t) − P(t|t−1)‖ ≤ tol · max(1, ‖P‖)
    /// (max norms) at a fully observed step; a missing value unfreezes it.
    pub converge_tol: Option<f64>,
    /// Whether the covariances and gains are frozen (then a step costs O(n² + nm + m²)).
    pub frozen: bool,
    /// Whether to compute the predictor gain when the model has no N (it is then only an
    /// output; with N it enters the time update anyway).
    pub want_gain_pred: bool,
    /// Whether to fill `gain` (the filter gain with zero columns for missing components): only
    /// an output.
    pub want_gain: bool,
    /// log det S of the last full update (used while frozen).
    log_det: f64,
    /// Components observed at this step, and how many (0 = no update).
    pub obs: Vec<usize>,
    pub m_obs: usize,
    // Observed-block buffers (m_obs ≤ m): P H' (n × m_obs), L D L' factor of S_o,
    // H_o, R_o, N_o, K_o' (m_obs × n), e_o, S_o⁻¹ e_o.
    pht_full: Vec<f64>,
    pht: Vec<f64>,
    pub s_factor: Vec<f64>,
    pub h_o: Vec<f64>,
    r_o: Vec<f64>,
    n_o: Vec<f64>,
    gain_t: Vec<f64>,
    pub e_o: Vec<f64>,
    pub s_inv_e: Vec<f64>,
    // n × n and n × m scratch.
    nn_a: Vec<f64>,
    nn_b: Vec<f64>,
    nm_a: Vec<f64>,
    nm_b: Vec<f64>,
    mn_a: Vec<f64>,
    /// P(t|t−1) before the time update, for the convergence test.
    p_prev: Vec<f64>,
}

impl Workspace {
    pub fn new(n: usize, m: usize, k: usize) -> Self {
        let z = |len: usize| vec![0.0; len];
        Workspace {
            n,
            m,
            k,
            x_pred: z(n),
            p_pred: z(n * n),
            x_filt: z(n),
            p_filt: z(n * n),
            innov: z(m),
            s_full: z(m * m),
            gain: z(n * m),
            gain_pred: z(n * m),
            loglik_t: 0.0,
            converge_tol: None,
            frozen: false,
            want_gain_pred: true,
            want_gain: true,
            log_det: 0.0,
            obs: vec![0; m],
            m_obs: 0,
            pht_full: z(n * m),
            pht: z(n * m),
            s_factor: z(m * m),
            h_o: z(m * n),
            r_o: z(m * m),
            n_o: z(n * m),
            gain_t: z(m * n),
            e_o: z(m),
            s_inv_e: z(m),
            nn_a: z(n * n),
            nn_b: z(n * n),
            nm_a: z(n * m),
            nm_b: z(n * m),
            mn_a: z(m * n),
            p_prev: z(n * n),
        }
    }

    /// The data-independent part of the last fully observed update: P H' (n × m), the
    /// L D L' factor of S (m × m) and log det S.
    pub fn gains(&self) -> (&[f64], &[f64], f64) {
        (&self.pht[..self.n * self.m], &self.s_factor[..self.m * self.m], self.log_det)
    }

    /// Loads gains recorded by [`gains`](Self::gains) (and N at that step) and freezes the
    /// covariance recursion: the next fully observed update and time update then move only
    /// the state, with exactly the operations of the full recursion.
    pub fn load_gains(&mut self, pht: &[f64], s_factor: &[f64], log_det: f64, n_mat: Option<&[f64]>) {
        let (n, m) = (self.n, self.m);
        self.pht[..n * m].copy_from_slice(pht);
        self.s_factor[..m * m].copy_from_slice(s_factor);
        self.log_det = log_det;
        if let Some(nn) = n_mat {
            self.n_o[..n * m].copy_from_slice(nn);
        }
        self.m_obs = m;
        for (i, o) in self.obs.iter_mut().enumerate() {
            *o = i;
        }
        self.frozen = true;
    }

    /// The run-time sizes.
    pub fn dims(&self) -> Dyn {
        Dyn { n: self.n, m: self.m }
    }

    /// Measurement update with `y` (NaN = missing), from (x_pred, p_pred) to (x_filt, p_filt).
    #[inline(always)]
    pub fn update<D: Dims>(
        &mut self,
        d: D,
        sys: &StepView<'_>,
        y: &[f64],
        u: Option<&[f64]>,
        form: UpdateForm,
        t: usize,
    ) -> Result<()> {
        let (n, m) = (d.n(), d.m());
        // Innovation of every component: e = y − H x − D u (NaN where y is missing).
        mul_vec(&mut self.innov, sys.h, &self.x_pred, m, n);
        if let (Some(d), Some(u)) = (sys.d, u) {
            mul_vec_add(&mut self.innov, d, u, m, self.k);
        }
        for (e, yi) in self.innov.iter_mut().zip(y) {
            *e = yi - *e;
        }
        if self.frozen {
            if y.iter().all(|v| !v.is_nan()) {
                self.update_frozen(d);
                return Ok(());
            }
            self.frozen = false;
        }
        // S = H P H' + R for all components: the forecast error covariance of y(t).
        mul_bt(&mut self.pht_full, &self.p_pred, sys.h, n, n, m);
        mul(&mut self.s_full, sys.h, &self.pht_full, m, n, m);
        for (s, r) in self.s_full.iter_mut().zip(sys.r) {
            *s += r;
        }
        symmetrize(&mut self.s_full, m);

        self.m_obs = 0;
        for (i, yi) in y.iter().enumerate() {
            if !yi.is_nan() {
                self.obs[self.m_obs] = i;
                self.m_obs += 1;
            }
        }
        if self.want_gain {
            self.gain.fill(0.0);
        }
        if self.m_obs == 0 {
            self.x_filt.copy_from_slice(&self.x_pred);
            self.p_filt.copy_from_slice(&self.p_pred);
            self.loglik_t = 0.0;
            return Ok(());
        }
        self.gather_observed(d, sys);
        // The fully observed case gets the compile-time m.
        if self.m_obs == m {
            self.update_observed(d, m, form, t)
        } else {
            self.update_observed(d, self.m_obs, form, t)
        }
    }

    /// The update from the gathered blocks of the `mo` observed components.
    #[inline(always)]
    fn update_observed<D: Dims>(&mut self, d: D, mo: usize, form: UpdateForm, t: usize) -> Result<()> {
        let (n, m) = (d.n(), d.m());
        ldl(&mut self.s_factor[..mo * mo], mo).map_err(|j| Error::InnovationCovariance {
            step: t,
            problem: format!(
                "not positive definite (pivot {j} of the {mo} observed components fails); \
                 R may be singular where H P H' is too"
            ),
        })?;
        let s_factor = &self.s_factor[..mo * mo];
        let log_det = ldl_log_det(s_factor, mo);
        self.log_det = log_det;
        let s_inv_e = &mut self.s_inv_e[..mo];
        s_inv_e.copy_from_slice(&self.e_o[..mo]);
        let quad = ldl_solve_quad(s_factor, s_inv_e, mo);
        self.loglik_t = -0.5 * (mo as f64 * LN_2PI + log_det + quad);

        // K' = S⁻¹ (P H')' by solves with the factor of S (never S⁻¹ itself).
        let pht = &self.pht[..n * mo];
        let gain_t = &mut self.gain_t[..mo * n];
        transpose(gain_t, pht, n, mo);
        ldl_solve(s_factor, gain_t, mo, n);

        // x̂(t|t) = x̂(t|t−1) + P H' S⁻¹ e
        self.x_filt.copy_from_slice(&self.x_pred);
        mul_vec_add(&mut self.x_filt, pht, s_inv_e, n, mo);

        match form {
            UpdateForm::Standard => {
                // P − K S K' = P − (P H') K'
                mul_sym(&mut self.nn_a, pht, gain_t, n, mo);
                for ((pf, p), ksk) in self.p_filt.iter_mut().zip(&self.p_pred).zip(&self.nn_a) {
                    *pf = p - ksk;
                }
            }
            UpdateForm::Joseph => {
                // A = I − K H_o;  P(t|t) = (A P) A' + K R_o K'
                let kgain = &mut self.nm_a[..n * mo];
                transpose(kgain, gain_t, mo, n);
                mul(&mut self.nn_a, kgain, &self.h_o[..mo * n], n, mo, n);
                for v in self.nn_a.iter_mut() {
                    *v = -*v;
                }
                for i in 0..n {
                    self.nn_a[i * n + i] += 1.0;
                }
                // A P = P − K (H P) with H P = (P H')': n² m multiply-adds instead of n³
                mul_bt(&mut self.nn_b, kgain, pht, n, mo, n);
                for (v, p) in self.nn_b.iter_mut().zip(&self.p_pred) {
                    *v = p - *v;
                }
                mul_bt_sym(&mut self.p_filt, &self.nn_b, &self.nn_a, n, n);
                // K R_o K' = K (R_o K') with R_o K' = r_o · gain_t (mo × n)
                mul(&mut self.mn_a[..mo * n], &self.r_o[..mo * mo], gain_t, mo, mo, n);
                mul_sym(&mut self.nn_b, kgain, &self.mn_a[..mo * n], n, mo);
                for (pf, krk) in self.p_filt.iter_mut().zip(&self.nn_b) {
                    *pf += krk;
                }
            }
        }
        // P(t|t) is exactly symmetric already: P(t|t−1) is, and both forms add mirrored
        // symmetric products (mul_sym, mul_bt_sym), so no symmetrization here.
        if self.want_gain {
            for (j, &i) in self.obs[..mo].iter().enumerate() {
                for r in 0..n {
                    self.gain[r * m + i] = gain_t[j * n + r];
                }
            }
        }
        Ok(())
    }

    /// The update with frozen gains (all components observed, as at the step that froze):
    /// only the state moves; S, K, P(t|t) are those of that step.
    #[inline(always)]
    fn update_frozen<D: Dims>(&mut self, d: D) {
        let (n, m) = (d.n(), d.m());
        self.e_o[..m].copy_from_slice(&self.innov);
        let s_inv_e = &mut self.s_inv_e[..m];
        s_inv_e.copy_from_slice(&self.innov);
        let quad = ldl_solve_quad(&self.s_factor[..m * m], s_inv_e, m);
        self.loglik_t = -0.5 * (m as f64 * LN_2PI + self.log_det + quad);
        self.x_filt.copy_from_slice(&self.x_pred);
        mul_vec_add(&mut self.x_filt, &self.pht[..n * m], s_inv_e, n, m);
    }

    /// Copies the observed components' blocks (all of them when nothing is missing).
    #[inline(always)]
    fn gather_observed<D: Dims>(&mut self, d: D, sys: &StepView<'_>) {
        let (n, m, mo) = (d.n(), d.m(), self.m_obs);
        if mo == m {
            self.e_o[..m].copy_from_slice(&self.innov[..m]);
            self.h_o[..m * n].copy_from_slice(&sys.h[..m * n]);
            self.s_factor[..m * m].copy_from_slice(&self.s_full[..m * m]);
            self.r_o[..m * m].copy_from_slice(&sys.r[..m * m]);
            self.pht[..n * m].copy_from_slice(&self.pht_full[..n * m]);
            if let Some(nn) = sys.n {
                self.n_o[..n * m].copy_from_slice(&nn[..n * m]);
            }
            return;
        }
        let obs = &self.obs[..mo];
        for (a, &i) in obs.iter().enumerate() {
            self.e_o[a] = self.innov[i];
            self.h_o[a * n..(a + 1) * n].copy_from_slice(&sys.h[i * n..(i + 1) * n]);
            for (b, &j) in obs.iter().enumerate() {
                self.s_factor[a * mo + b] = self.s_full[i * m + j];
                self.r_o[a * mo + b] = sys.r[i * m + j];
            }
        }
        for r in 0..n {
            for (a, &i) in obs.iter().enumerate() {
                self.pht[r * mo + a] = self.pht_full[r * m + i];
                if let Some(nn) = sys.n {
                    self.n_o[r * mo + a] = nn[r * m + i];
                }
            }
        }
    }

    /// Skips the measurement update (nothing observed, as for an all-NaN y).
    pub fn skip_update(&mut self) {
        self.frozen = false;
        self.m_obs = 0;
        self.innov.fill(f64::NAN);
        self.gain.fill(0.0);
        self.loglik_t = 0.0;
        self.x_filt.copy_from_slice(&self.x_pred);
        self.p_filt.copy_from_slice(&self.p_pred);
    }

    /// Time update from (x_filt, p_filt) to the next (x_pred, p_pred), and the predictor gain
    /// `K_pred = F K + N S⁻¹` of the update just made.
    #[inline(always)]
    pub fn predict<D: Dims>(&mut self, d: D, sys: &StepView<'_>, u: Option<&[f64]>) {
        let (n, m, mo) = (d.n(), d.m(), self.m_obs);
        mul_vec(&mut self.x_pred, sys.f, &self.x_filt, n, n);
        if let (Some(b), Some(u)) = (sys.b, u) {
            mul_vec_add(&mut self.x_pred, b, u, n, self.k);
        }
        if self.frozen {
            if sys.n.is_some() {
                mul_vec_add(&mut self.x_pred, &self.n_o[..n * m], &self.s_inv_e[..m], n, m);
            }
            return;
        }
        if self.converge_tol.is_some() {
            self.p_prev.copy_from_slice(&self.p_pred);
        }
        mul(&mut self.nn_a, sys.f, &self.p_filt, n, n, n);
        mul_bt_sym(&mut self.p_pred, &self.nn_a, sys.f, n, n);
        for (p, q) in self.p_pred.iter_mut().zip(sys.q) {
            *p += q;
        }
        if !self.want_gain_pred && sys.n.is_none() {
            // (gain_pred keeps its zeros)
        } else if mo == m {
            self.gain_pred.fill(0.0);
            self.predictor_gain(d, m, sys);
        } else {
            self.gain_pred.fill(0.0);
            if mo > 0 {
                self.predictor_gain(d, mo, sys);
            }
        }
        symmetrize(&mut self.p_pred, n);
        if let (Some(tol), true) = (self.converge_tol, mo == m) {
            let change = self.p_pred.iter().zip(&self.p_prev).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            let size = self.p_pred.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            self.frozen = change <= tol * size;
        }
    }

    /// K_pred = F K + N S⁻¹ over the `mo` observed components, and the N terms of the time
    /// update (Söderström (6.25), (6.26)).
    #[inline(always)]
    fn predictor_gain<D: Dims>(&mut self, d: D, mo: usize, sys: &StepView<'_>) {
        let (n, m) = (d.n(), d.m());
        // F K (n × mo), with K = gain_t'.
        let kgain = &mut self.nm_a[..n * mo];
        transpose(kgain, &self.gain_t[..mo * n], mo, n);
        let fk = &mut self.nm_b[..n * mo];
        mul(fk, sys.f, kgain, n, n, mo);
        if sys.n.is_some() {
            let n_o = &self.n_o[..n * mo];
            // x̂(t+1|t) += N S⁻¹ e
            mul_vec_add(&mut self.x_pred, n_o, &self.s_inv_e[..mo], n, mo);
            // G' = S⁻¹ N' (mo × n); K_pred = F K + G.
            let g_t = &mut self.mn_a[..mo * n];
            transpose(g_t, n_o, n, mo);
            ldl_solve(&self.s_factor[..mo * mo], g_t, mo, n);
            // P(t+1|t) −= K_pred N' + N (F K)'
            for r in 0..n {
                for c in 0..n {
                    let mut acc = 0.0;
                    for a in 0..mo {
                        let kp = fk[r * mo + a] + g_t[a * n + r];
                        acc += kp * n_o[c * mo + a] + n_o[r * mo + a] * fk[c * mo + a];
                    }
                    self.p_pred[r * n + c] -= acc;
                }
            }
            for r in 0..n {
                for a in 0..mo {
                    fk[r * mo + a] += g_t[a * n + r];
                }
            }
        }
        for (a, &i) in self.obs[..mo].iter().enumerate() {
            for r in 0..n {
                self.gain_pred[r * m + i] = fk[r * mo + a];
            }
        }
    }
}
