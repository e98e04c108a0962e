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

use crate::core::dense::{ldl, ldl_solve, ldl_solve_quad, mul, mul_bt, mul_bt_sym, mul_sym, mul_vec_add, transpose};
use crate::core::dims::{Buf, Dims};
#[cfg(target_arch = "x86_64")]
use crate::core::rows4::{self, Avx2Fma, Row, Rows};
use crate::error::{Error, Result};

/// ln 2π.
pub(crate) const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// `ln det S` of one update, held as the product of the pivots of S's L D L' factor so that a
/// time loop can take one logarithm at the end ([`LoglikSum`]) instead of one per step (a
/// logarithm is ~10% of a step at n = 4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LogDet {
    /// `Π d_j` when that is a normal number, else 1.
    det: f64,
    /// `Σ ln d_j` when the product is not normal (it over- or underflowed), else 0.
    log_rest: f64,
}

impl LogDet {
    /// `ln det = 0` (nothing observed).
    pub const ZERO: LogDet = LogDet { det: 1.0, log_rest: 0.0 };

    /// From the determinant `det` that [`ldl`] returned with its factor `f[n×n]`, whose
    /// diagonal holds the reciprocal pivots.
    #[inline(always)]
    fn of_factor(det: f64, f: &[f64], n: usize) -> LogDet {
        if det.is_normal() {
            LogDet { det, log_rest: 0.0 }
        } else {
            LogDet { det: 1.0, log_rest: (0..n).map(|i| -f[i * n + i].ln()).sum() }
        }
    }

    /// `ln det S`.
    #[inline(always)]
    pub fn ln(self) -> f64 {
        self.det.ln() + self.log_rest
    }
}

/// The total log-likelihood of a series, `Σ_t log p(y(t) | y(0..t−1)) = −½ Σ_t (m_t ln 2π +
/// ln det S_t + e_t' S_t⁻¹ e_t)` (Söderström (6.142)), summed with one logarithm at the end:
/// the determinants are multiplied, and each step moves the product's binary exponent into an
/// integer, so the product neither overflows nor underflows. The rounding error is that of
/// summing the logarithms (relative ε per step).
#[derive(Debug, Clone, Copy)]
pub(crate) struct LoglikSum {
    observed: usize,
    /// `Π det S_t = det_mantissa · 2^det_exponent · exp(log_rest)`, `det_mantissa` in
    /// [2⁻⁵⁰⁰, 2⁵⁰⁰] (split into [1, 2) and the exponent when it leaves that range).
    det_mantissa: f64,
    det_exponent: i64,
    log_rest: f64,
    quad: f64,
}

impl Default for LoglikSum {
    fn default() -> Self {
        LoglikSum { observed: 0, det_mantissa: 1.0, det_exponent: 0, log_rest: 0.0, quad: 0.0 }
    }
}

impl LoglikSum {
    /// Adds the term of the last update (nothing for a step with nothing observed).
    #[inline(always)]
    pub fn add<D: Dims>(&mut self, update: &GaussianUpdate<D>) {
        self.observed += update.observed;
        self.quad += update.quad;
        self.log_rest += update.log_det.log_rest;
        // The running product is renormalized only when it leaves [2⁻⁵⁰⁰, 2⁵⁰⁰]: a power of
        // two is exact, so the product's bits are those of renormalizing at every step, for
        // one multiply and a compare instead of three exponent splits.
        let product = self.det_mantissa * update.log_det.det;
        if (RENORMALIZE_BELOW..=RENORMALIZE_ABOVE).contains(&product) {
            self.det_mantissa = product;
        } else {
            self.renormalize(update.log_det.det);
        }
    }

    /// `det_mantissa · det` as a mantissa in [1, 2) and a binary exponent (out of line: rare).
    #[cold]
    #[inline(never)]
    fn renormalize(&mut self, det: f64) {
        let (m1, e1) = split_exponent(self.det_mantissa);
        let (m2, e2) = split_exponent(det);
        let (m, e) = split_exponent(m1 * m2);
        self.det_mantissa = m;
        self.det_exponent += e1 + e2 + e;
    }

    /// Adds a step's term given as a number (the robust update forms' streaming filter).
    pub fn add_term(&mut self, loglik_t: f64) {
        // −½ (−2 ℓ) is ℓ exactly.
        self.quad -= 2.0 * loglik_t;
    }

    /// A sum that starts from the total `loglik` (of steps whose terms are no longer known).
    #[cfg_attr(not(feature = "python"), allow(dead_code))] // for pickling in Python
    pub fn carrying(loglik: f64) -> LoglikSum {
        // −½ (−2 loglik) is loglik exactly.
        LoglikSum { quad: -2.0 * loglik, ..LoglikSum::default() }
    }

    /// The state of the sum as five numbers (for pickling a streaming filter), the product
    /// of the determinants with its mantissa in [1, 2).
    #[cfg_attr(not(feature = "python"), allow(dead_code))] // for pickling in Python
    pub fn parts(&self) -> [f64; 5] {
        let (m, e) = split_exponent(self.det_mantissa);
        [self.observed as f64, m, (self.det_exponent + e) as f64, self.log_rest, self.quad]
    }

    /// The sum of [`parts`](Self::parts); `None` when they cannot be such a state.
    #[cfg_attr(not(feature = "python"), allow(dead_code))] // for pickling in Python
    pub fn from_parts(parts: [f64; 5]) -> Option<LoglikSum> {
        let [observed, det_mantissa, det_exponent, log_rest, quad] = parts;
        let whole = |v: f64| v.is_finite() && v.fract() == 0.0 && v.abs() < 2f64.powi(53);
        let valid = whole(observed)
            && observed >= 0.0
            && (1.0..2.0).contains(&det_mantissa)
            && whole(det_exponent)
            && log_rest.is_finite()
            && quad.is_finite();
        valid.then_some(LoglikSum {
            observed: observed as usize,
            det_mantissa,
            det_exponent: det_exponent as i64,
            log_rest,
            quad,
        })
    }

    /// The total.
    pub fn total(&self) -> f64 {
        let (m, e) = split_exponent(self.det_mantissa);
        let log_det = m.ln() + (self.det_exponent + e) as f64 * std::f64::consts::LN_2 + self.log_rest;
        -0.5 * (self.observed as f64 * LN_2PI + log_det + self.quad)
    }
}

/// The range in which [`LoglikSum`] keeps its running product without splitting it: a
/// product of it and a normal determinant neither over- nor underflows unnoticed (it lands
/// outside, and is then recomputed from the split factors).
const RENORMALIZE_BELOW: f64 = 3.054936363499605e-151; // 2⁻⁵⁰⁰
const RENORMALIZE_ABOVE: f64 = 3.273390607896142e150; // 2⁵⁰⁰

/// A positive normal `x` as `(m, e)` with `x = m · 2^e`, `m` in [1, 2), by its bits.
#[inline(always)]
fn split_exponent(x: f64) -> (f64, i64) {
    const EXPONENT: u64 = 0x7ff << 52;
    let bits = x.to_bits();
    let e = ((bits & EXPONENT) >> 52) as i64 - 1023;
    (f64::from_bits((bits & !EXPONENT) | (1023 << 52)), e)
}

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
    /// The square-root (array) filter: a Cholesky factor of P moved by orthogonal
    /// transformations, P never formed (Söderström Sec. 6.8.1; linear models only).
    SquareRoot,
    /// P = U D U' with Bierman's measurement update and Thornton's time update (Bierman
    /// (1977); Söderström (6.115); linear models only).
    UD,
    /// The information filter on Y = P⁻¹, ŷ = P⁻¹ x̂ (linear models only; needs F and R
    /// invertible).
    Information,
    /// P updated one decorrelated scalar component at a time, no matrix inverted (Söderström
    /// Sec. 6.8.1; linear models only).
    Sequential,
}

impl UpdateForm {
    /// Whether this is one of the covariance forms (Joseph, standard) that every filter offers;
    /// the others are the linear filter's update forms (`linear::filter::forms`).
    pub fn is_covariance_form(self) -> bool {
        matches!(self, UpdateForm::Joseph | UpdateForm::Standard)
    }

    /// An error unless this is a covariance form (`what`: the estimator that needs one).
    pub(crate) fn require_covariance_form(self, what: &str) -> crate::error::Result<()> {
        if self.is_covariance_form() {
            return Ok(());
        }
        Err(crate::error::Error::arg(
            "form",
            format!("{what} offers the Joseph and standard forms only; the square-root, U-D, information and sequential forms are for filter, loglik and smooth"),
        ))
    }
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
    /// L D L' factor of S (mo × mo, as `dense::ldl` leaves it: unit L below the diagonal, D⁻¹ on it).
    s_factor: D::ObsSquare,
    /// S⁻¹ e (mo).
    s_inv_e: D::Obs,
    /// K' = S⁻¹ C' (mo × n).
    gain_t: D::StateObs,
    /// The last update's log-likelihood term `−½ (mo ln 2π + ln det S + e' S⁻¹ e)`, in parts:
    /// `mo` (0: no update), ln det S (of the last full update when gains are frozen) and
    /// `e' S⁻¹ e`.
    observed: usize,
    log_det: LogDet,
    quad: f64,
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
            observed: 0,
            log_det: LogDet::ZERO,
            quad: 0.0,
            gain: d.state_obs(),
            r_gain_t: d.state_obs(),
            nn_a: d.square(),
            nn_b: d.square(),
        }
    }

    /// Makes this a copy of `other` without allocating (see `Workspace::copy_from`).
    #[inline(always)]
    pub fn copy_from(&mut self, other: &Self) {
        let GaussianUpdate { s_factor, s_inv_e, gain_t, observed, log_det, quad, gain, r_gain_t, nn_a, nn_b } = other;
        (self.observed, self.log_det, self.quad) = (*observed, *log_det, *quad);
        self.s_factor.clone_from(s_factor);
        self.s_inv_e.clone_from(s_inv_e);
        self.gain_t.clone_from(gain_t);
        self.gain.clone_from(gain);
        self.r_gain_t.clone_from(r_gain_t);
        self.nn_a.clone_from(nn_a);
        self.nn_b.clone_from(nn_b);
    }

    /// Takes the results of an update done with other sizes (the factor of S, S⁻¹ e, K' and
    /// the log-likelihood parts), for `mo` observed components and n states.
    #[inline(always)]
    pub fn copy_results_of<E: Dims>(&mut self, other: &GaussianUpdate<E>, mo: usize, n: usize) {
        self.s_factor.get_mut()[..mo * mo].copy_from_slice(&other.s_factor.get()[..mo * mo]);
        self.s_inv_e.get_mut()[..mo].copy_from_slice(&other.s_inv_e.get()[..mo]);
        self.gain_t.get_mut()[..mo * n].copy_from_slice(&other.gain_t.get()[..mo * n]);
        (self.observed, self.log_det, self.quad) = (other.observed, other.log_det, other.quad);
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
        self.factor(mo, pred.innov, pred.innov_cov, t)?;
        let s_factor = &self.s_factor.get()[..mo * mo];
        let s_inv_e = &self.s_inv_e.get()[..mo];

        // K' = S⁻¹ C' by solves with the factor of S (never S⁻¹ itself).
        let cross_cov = &pred.cross_cov[..n * mo];
        let gain_t = &mut self.gain_t.get_mut()[..mo * n];
        transpose(gain_t, cross_cov, n, mo);
        ldl_solve::<D>(s_factor, gain_t, mo, n);
        let gain_t = &self.gain_t.get()[..mo * n];

        // x̂(t|t) = x̂(t|t−1) + C S⁻¹ e
        x_filt.copy_from_slice(x_pred);
        mul_vec_add::<D>(x_filt, cross_cov, s_inv_e, n, mo);

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

    /// The L D L' factor of S (mo × mo), ln det S, S⁻¹ e and e' S⁻¹ e: the part of the update
    /// that does not depend on n. Fails (naming step `t`) when S is not positive definite.
    #[inline(always)]
    fn factor(&mut self, mo: usize, innov: &[f64], innov_cov: &[f64], t: usize) -> Result<()> {
        let s_factor = &mut self.s_factor.get_mut()[..mo * mo];
        let det = match ldl::<D>(s_factor, &innov_cov[..mo * mo], mo) {
            Ok(det) => det,
            Err(j) => return Err(not_positive_definite(t, j, mo)),
        };
        let s_factor = &self.s_factor.get()[..mo * mo];
        self.log_det = LogDet::of_factor(det, s_factor, mo);
        let s_inv_e = &mut self.s_inv_e.get_mut()[..mo];
        s_inv_e.copy_from_slice(&innov[..mo]);
        self.quad = ldl_solve_quad::<D>(s_factor, s_inv_e, mo);
        self.observed = mo;
        Ok(())
    }

    /// [`apply`](Self::apply) for three or four states on AVX2 registers ([`rows4`]), every component
    /// observed: the same operations in the same order, so the same bits. `cols` are the m
    /// columns of `C = P H'` (`pred.cross_cov` holds the same numbers row-major).
    #[cfg(target_arch = "x86_64")]
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn apply_rows4(
        &mut self,
        cpu: Avx2Fma,
        m: usize,
        pred: &MeasurementPrediction<'_>,
        cols: &[Row; 4],
        x_pred: &[f64],
        p_pred: &[f64],
        x_filt: &mut [f64],
        p_filt: &mut [f64],
        t: usize,
    ) -> Result<()> {
        self.factor(m, pred.innov, pred.innov_cov, t)?;
        let f = &self.s_factor.get()[..m * m];
        // K' = S⁻¹ C': its rows are C's columns.
        let mut gain_rows = *cols;
        rows4::ldl_solve(f, &mut gain_rows, m);
        let gain_t = self.gain_t.get_mut();
        for (i, row) in gain_rows.iter().enumerate().take(m) {
            rows4::store(cpu, &mut gain_t[cpu.n() * i..], *row);
        }

        // x̂(t|t) = x̂(t|t−1) + C S⁻¹ e
        let s_inv_e = &self.s_inv_e.get()[..m];
        rows4::store(cpu, x_filt, rows4::add(rows4::load(cpu, x_pred), rows4::mul_vec_cols(cols, s_inv_e, m)));

        let p = Rows::load(cpu, p_pred);
        let p_filt_rows = match pred.joseph {
            // P − C K'
            None => p.sub(&rows4::mul_cols(cols, &gain_rows, m).mirror_upper()),
            Some((h, r)) => {
                // A = I − K H (K's columns are the rows of K')
                let h_rows: [Row; 4] = rows4::each(
                    #[inline(always)]
                    |l| rows4::load_row_or_zero(cpu, h, l, m),
                );
                let a = rows4::mul_cols(&gain_rows, &h_rows, m).identity_minus();
                // A P = P − K C'
                let ap = p.sub(&rows4::mul_cols(&gain_rows, cols, m));
                let apa = rows4::mul_rows(cpu, &ap, &a.transpose()).mirror_upper();
                // K R K' = K (R K')
                let r_gain_t = rows4::mul_mem(r, m, &gain_rows, m);
                apa.add(&rows4::mul_cols(&gain_rows, &r_gain_t.0, m).mirror_upper())
            }
        };
        p_filt_rows.store(cpu, p_filt);
        Ok(())
    }

    /// The update of the mean alone with the S factor and ln det S of an earlier update kept
    /// (frozen gains, all `m` components observed): `x̂(t|t) = x̂(t|t−1) + C S⁻¹ e`.
    #[inline(always)]
    pub fn apply_mean(&mut self, d: D, innov: &[f64], cross_cov: &[f64], x_pred: &[f64], x_filt: &mut [f64]) {
        let (n, m) = (d.n(), d.m());
        let s_inv_e = &mut self.s_inv_e.get_mut()[..m];
        s_inv_e.copy_from_slice(&innov[..m]);
        self.quad = ldl_solve_quad::<D>(&self.s_factor.get()[..m * m], s_inv_e, m);
        self.observed = m;
        x_filt.copy_from_slice(x_pred);
        mul_vec_add::<D>(x_filt, &cross_cov[..n * m], s_inv_e, n, m);
    }

    /// Loads the factor of S and ln det S recorded from another update (see
    /// [`s_factor`](Self::s_factor)), for [`apply_mean`](Self::apply_mean).
    pub fn load_factor(&mut self, s_factor: &[f64], log_det: LogDet) {
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
    pub fn log_det(&self) -> LogDet {
        self.log_det
    }

    /// The log-likelihood term of the last update (0 when nothing was observed).
    #[inline(always)]
    pub fn loglik_t(&self) -> f64 {
        if self.observed == 0 {
            return 0.0;
        }
        -0.5 * (self.observed as f64 * LN_2PI + self.log_det.ln() + self.quad)
    }

    /// Whether the last update's `e' S⁻¹ e` is NaN: the state or the data left float64's
    /// range.
    #[inline(always)]
    pub fn overflowed(&self) -> bool {
        self.quad.is_nan()
    }

    /// Records a step with nothing observed (its log-likelihood term is 0).
    pub fn skip(&mut self) {
        (self.observed, self.log_det, self.quad) = (0, LogDet::ZERO, 0.0);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::dims::Fixed;

    /// An update with nothing but its log-likelihood term's parts set.
    fn term(observed: usize, pivots: &[f64], quad: f64) -> GaussianUpdate<Fixed<3, 3>> {
        let mut u = GaussianUpdate::new(Fixed::<3, 3>);
        let n = pivots.len();
        let mut f = [0.0; 9];
        for (i, d) in pivots.iter().enumerate() {
            f[i * n + i] = 1.0 / *d;
        }
        let det = pivots.iter().product();
        (u.observed, u.log_det, u.quad) = (observed, LogDet::of_factor(det, &f[..n * n], n), quad);
        u
    }

    #[test]
    fn the_sum_with_one_logarithm_equals_the_sum_of_the_terms() {
        let mut state = 11u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        // Determinants from 1e-300 to 1e300, and pivots whose product over- or underflows.
        let (mut sum, mut terms) = (LoglikSum::default(), 0.0);
        for t in 0..20_000 {
            let pivots = match t % 5 {
                0 => vec![10f64.powf(600.0 * next() - 300.0)],
                1 => vec![1e200, 1e200, next()],
                2 => vec![1e-200, 1e-200],
                3 => vec![],
                _ => vec![next() + 0.5, next() + 0.5],
            };
            let u = term(pivots.len(), &pivots, if pivots.is_empty() { 0.0 } else { 3.0 * next() });
            terms += u.loglik_t();
            sum.add(&u);
        }
        let total = sum.total();
        assert!((total - terms).abs() <= 1e-12 * terms.abs(), "{total} vs {terms}");
        let again = LoglikSum::from_parts(sum.parts()).unwrap();
        assert_eq!(again.total().to_bits(), total.to_bits());
        assert_eq!(LoglikSum::carrying(total).total(), total);
        assert_eq!(LoglikSum::default().total(), 0.0);
    }

    #[test]
    fn parts_that_are_not_a_sum_are_refused() {
        for parts in [
            [-1.0, 1.0, 0.0, 0.0, 0.0],
            [0.5, 1.0, 0.0, 0.0, 0.0],
            [1.0, 2.0, 0.0, 0.0, 0.0],
            [1.0, 1.0, 0.5, 0.0, 0.0],
            [1.0, 1.0, 0.0, f64::NAN, 0.0],
            [1.0, 1.0, 0.0, 0.0, f64::INFINITY],
            [1e300, 1.0, 0.0, 0.0, 0.0],
        ] {
            assert!(LoglikSum::from_parts(parts).is_none(), "{parts:?}");
        }
    }
}
