//! The exact diffuse start of the Kalman filter (Koopman 1997; Durbin & Koopman (2012)
//! Sec. 5.2, in the univariate form of their Sec. 6.4 (Koopman & Durbin 2000)), for states
//! whose initial value is unknown: P(0|−1) = P_* + κ P_∞ with κ → ∞ handled exactly.
//!
//! Each step processes the observed components one at a time (decorrelated by the Cholesky
//! factor L of their R when R is not diagonal: ỹ = L⁻¹ y, z̃ = L⁻¹ H, σ² = 1). For a component
//! with row z and noise variance σ²:
//!
//! ```text
//! v = ỹ − z x        F_∞ = z P_∞ z'     F_* = z P_* z' + σ²     M_∞ = P_∞ z'     M_* = P_* z'
//! F_∞ > 0:  x += M_∞ v / F_∞
//!           P_* += M_∞ M_∞' F_* / F_∞² − (M_∞ M_*' + M_* M_∞') / F_∞
//!           P_∞ −= M_∞ M_∞' / F_∞                       loglik −= ½ (log 2π + log F_∞)
//! F_∞ = 0:  x += M_* v / F_*,  P_* −= M_* M_*' / F_*   loglik −= ½ (log 2π + log F_* + v² / F_*)
//! ```
//!
//! (the limits κ → ∞ of the scalar update with P_* + κ P_∞), then the time update
//! x = F x + B u, P_∞ = F P_∞ F', P_* = F P_* F' + Q. The log-likelihood is the diffuse one of
//! Durbin & Koopman (2012) Sec. 7.2.2, with the log 2π of every observation (statsmodels' value;
//! KFAS leaves it out for the steps where F_∞ > 0). Once P_∞ is zero the ordinary filter takes
//! over from x(d|d−1), P_*(d|d−1): d is the number of diffuse steps.

use super::outputs::FilterOutputs;
use crate::core::dense::{solve_lower, symmetrize};
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::model::{LinearGaussian, StepView};

/// Where the diffuse start left the filter: `steps` = d diffuse steps, then the prior
/// x̂(d|d−1), P(d|d−1) of the ordinary filter, and the log-likelihood of the first d steps.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DiffuseStart {
    /// The number d of diffuse steps (P_∞(d|d−1) = 0).
    pub steps: usize,
    /// x̂(d|d−1).
    pub x: Vec<f64>,
    /// P(d|d−1) (= P_*(d|d−1)).
    pub p: Vec<f64>,
    /// Σ_{t<d} of the diffuse log-likelihood terms.
    pub loglik: f64,
}

/// Runs the diffuse steps from x̂(0|−1) = `x0`, P_*(0|−1) = `p0`, P_∞(0|−1) = `p0_inf` (all
/// validated), storing their outputs (P_pred, P_filt the finite parts P_*; S = H P_* H' + R;
/// K the limit gain) and `p_pred_inf`, P_∞(t|t−1) of each diffuse step when given.
#[allow(clippy::too_many_arguments)]
pub(crate) fn diffuse_start(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    p0_inf: &[f64],
    out: &mut FilterOutputs<'_>,
    mut p_pred_inf: Option<&mut [f64]>,
) -> Result<DiffuseStart> {
    let (n, m) = (model.n_states(), model.n_obs());
    if model.at(0).n.is_some() {
        return Err(Error::arg("P0_inf", "the exact diffuse filter needs N = 0 (uncorrelated w and v)"));
    }
    let mut s = State::new(n, m, x0, p0, p0_inf);
    let mut total = 0.0;
    let mut t = 0;
    while t < y.steps() && s.is_diffuse() {
        let sys = model.at(t);
        let u_t = u.map(|u| u.row(t));
        out.store_prior(t, &s.x, &s.p_star);
        if let Some(buf) = p_pred_inf.as_deref_mut() {
            buf[t * n * n..][..n * n].copy_from_slice(&s.p_inf);
        }
        let loglik_t = s.update(&sys, y.row(t), u_t, t)?;
        out.store_values(t, &s.x_filt, &s.p_filt, &s.innov, &s.s_full, &s.gain, loglik_t);
        s.predict(&sys, u_t);
        out.store_gain_pred(t, &s.gain_pred);
        total += loglik_t;
        t += 1;
    }
    Ok(DiffuseStart { steps: t, x: s.x, p: s.p_star, loglik: total })
}

/// The diffuse filter's state and scratch (dynamic sizes: the diffuse start is a few steps).
struct State {
    n: usize,
    m: usize,
    x: Vec<f64>,
    p_star: Vec<f64>,
    p_inf: Vec<f64>,
    /// max |P_∞(0|−1)|, the scale of the tolerances.
    inf_scale: f64,
    x_filt: Vec<f64>,
    p_filt: Vec<f64>,
    innov: Vec<f64>,
    s_full: Vec<f64>,
    gain: Vec<f64>,
    gain_pred: Vec<f64>,
}

impl State {
    fn new(n: usize, m: usize, x0: &[f64], p0: &[f64], p0_inf: &[f64]) -> Self {
        State {
            n,
            m,
            x: x0.to_vec(),
            p_star: p0.to_vec(),
            p_inf: p0_inf.to_vec(),
            inf_scale: p0_inf.iter().fold(0.0_f64, |a, v| a.max(v.abs())),
            x_filt: vec![0.0; n],
            p_filt: vec![0.0; n * n],
            innov: vec![0.0; m],
            s_full: vec![0.0; m * m],
            gain: vec![0.0; n * m],
            gain_pred: vec![0.0; n * m],
        }
    }

    /// Whether P_∞ still has an entry above rounding (relative to the largest of P_∞(0|−1));
    /// below it is set to zero.
    fn is_diffuse(&mut self) -> bool {
        let tol = 1e-10 * self.inf_scale;
        if self.p_inf.iter().all(|v| v.abs() <= tol) {
            self.p_inf.fill(0.0);
            return false;
        }
        true
    }

    /// The measurement update with y(t), one observed component at a time; returns the
    /// step's log-likelihood term.
    fn update(&mut self, sys: &StepView<'_>, y: &[f64], u: Option<&[f64]>, t: usize) -> Result<f64> {
        let (n, m) = (self.n, self.m);
        let observed: Vec<usize> = (0..m).filter(|&i| !y[i].is_nan()).collect();
        let mo = observed.len();
        // e = y − H x − D u of every component (NaN where missing), and S = H P_* H' + R.
        for i in 0..m {
            let mut pred = dot(&sys.h[i * n..][..n], &self.x);
            if let (Some(d), Some(u)) = (sys.d, u) {
                pred += dot(&d[i * u.len()..][..u.len()], u);
            }
            self.innov[i] = y[i] - pred;
        }
        let hp = mat_mul(sys.h, &self.p_star, m, n, n);
        for i in 0..m {
            for j in 0..m {
                self.s_full[i * m + j] = dot(&hp[i * n..][..n], &sys.h[j * n..][..n]) + sys.r[i * m + j];
            }
        }
        // The observed components, decorrelated when R_oo is not diagonal: rows z̃ = L⁻¹ H_o,
        // innovations ẽ = L⁻¹ e_o, unit variances; `log_det_l` = log det L for the Jacobian.
        let r_oo: Vec<f64> = observed.iter().flat_map(|&i| observed.iter().map(move |&j| sys.r[i * m + j])).collect();
        let diagonal = (0..mo).all(|a| (0..mo).all(|b| a == b || r_oo[a * mo + b] == 0.0));
        let mut rows: Vec<f64> = observed.iter().flat_map(|&i| sys.h[i * n..][..n].to_vec()).collect();
        let mut e: Vec<f64> = observed.iter().map(|&i| self.innov[i]).collect();
        let (variances, l_factor, log_det_l) = if diagonal {
            ((0..mo).map(|a| r_oo[a * mo + a]).collect::<Vec<_>>(), None, 0.0)
        } else {
            let l = cholesky(&r_oo, mo).ok_or_else(|| {
                Error::arg_at("R", t, "the exact diffuse filter processes the observed components one at a time and needs their R positive definite (or diagonal)")
            })?;
            solve_lower(&l, &mut rows, mo, n);
            solve_lower(&l, &mut e, mo, 1);
            let log_det = (0..mo).map(|a| l[a * mo + a].ln()).sum::<f64>();
            (vec![1.0; mo], Some(l), log_det)
        };
        // C (n × mo): x(t|t) − x(t|t−1) as a linear map of ẽ, built one component at a time.
        let mut c = vec![0.0; n * mo];
        let mut loglik = -log_det_l;
        let half_log_2pi = 0.5 * (2.0 * std::f64::consts::PI).ln();
        let x_pred = self.x.clone();
        for a in 0..mo {
            let z = &rows[a * n..][..n];
            // ẽ_a is relative to x̂(t|t−1); the components before moved the state since.
            let moved: f64 = (0..n).map(|i| z[i] * (self.x[i] - x_pred[i])).sum();
            let v = e[a] - moved;
            let m_inf = mat_vec(&self.p_inf, z, n);
            let m_star = mat_vec(&self.p_star, z, n);
            let f_inf = dot(z, &m_inf);
            let f_star = dot(z, &m_star) + variances[a];
            // Relative to P_∞(0|−1), not to the current P_∞, which after the update that removed
            // its last direction is rounding whose F_∞ must not count as information.
            let k: Vec<f64> = if f_inf > 1e-8 * dot(z, z) * self.inf_scale {
                for i in 0..n {
                    for j in 0..n {
                        self.p_star[i * n + j] += m_inf[i] * m_inf[j] * f_star / (f_inf * f_inf)
                            - (m_inf[i] * m_star[j] + m_star[i] * m_inf[j]) / f_inf;
                        self.p_inf[i * n + j] -= m_inf[i] * m_inf[j] / f_inf;
                    }
                }
                loglik -= half_log_2pi + 0.5 * f_inf.ln();
                m_inf.iter().map(|v| v / f_inf).collect()
            } else if f_star > 0.0 {
                for i in 0..n {
                    for j in 0..n {
                        self.p_star[i * n + j] -= m_star[i] * m_star[j] / f_star;
                    }
                }
                loglik -= half_log_2pi + 0.5 * (f_star.ln() + v * v / f_star);
                m_star.iter().map(|v| v / f_star).collect()
            } else if f_star == 0.0 {
                // An exactly known component: nothing to learn.
                vec![0.0; n]
            } else {
                return Err(Error::InnovationCovariance {
                    step: t,
                    problem: format!(
                        "the variance of observed component {} is {f_star} (< 0) in the exact diffuse filter",
                        observed[a]
                    ),
                });
            };
            for (xi, ki) in self.x.iter_mut().zip(&k) {
                *xi += ki * v;
            }
            // C ← C + k (ε_a' − z C): component a's innovation is ẽ_a − z (x − x(t|t−1)).
            let zc: Vec<f64> = (0..mo).map(|b| (0..n).map(|i| z[i] * c[i * mo + b]).sum()).collect();
            for i in 0..n {
                for b in 0..mo {
                    c[i * mo + b] += k[i] * (if a == b { 1.0 } else { 0.0 } - zc[b]);
                }
            }
            symmetrize(&mut self.p_star, n);
            symmetrize(&mut self.p_inf, n);
        }
        if !loglik.is_finite() || self.x.iter().any(|v| !v.is_finite()) {
            return Err(Error::InnovationCovariance { step: t, problem: "the exact diffuse update overflowed".into() });
        }
        // K = C L⁻¹ on the observed columns (C itself when R_oo is diagonal), zero elsewhere.
        if let Some(l) = &l_factor {
            // C L⁻¹: solve X L = C, i.e. L' X' = C'.
            for i in 0..n {
                let row = &mut c[i * mo..][..mo];
                for b in (0..mo).rev() {
                    let mut s = row[b];
                    for a in b + 1..mo {
                        s -= row[a] * l[a * mo + b];
                    }
                    row[b] = s / l[b * mo + b];
                }
            }
        }
        self.gain.fill(0.0);
        for (b, &j) in observed.iter().enumerate() {
            for i in 0..n {
                self.gain[i * m + j] = c[i * mo + b];
            }
        }
        self.x_filt.copy_from_slice(&self.x);
        self.p_filt.copy_from_slice(&self.p_star);
        Ok(loglik)
    }

    /// x = F x + B u, P_∞ = F P_∞ F', P_* = F P_* F' + Q; K_pred = F K (N = 0).
    fn predict(&mut self, sys: &StepView<'_>, u: Option<&[f64]>) {
        let (n, m) = (self.n, self.m);
        let mut x = mat_vec(sys.f, &self.x, n);
        if let (Some(b), Some(u)) = (sys.b, u) {
            for (i, xi) in x.iter_mut().enumerate() {
                *xi += dot(&b[i * u.len()..][..u.len()], u);
            }
        }
        self.x = x;
        self.p_inf = congruence(sys.f, &self.p_inf, n);
        self.p_star = congruence(sys.f, &self.p_star, n);
        for (p, q) in self.p_star.iter_mut().zip(sys.q) {
            *p += q;
        }
        self.gain_pred = mat_mul(sys.f, &self.gain, n, n, m);
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn mat_vec(a: &[f64], x: &[f64], n: usize) -> Vec<f64> {
    (0..n).map(|i| dot(&a[i * x.len()..][..x.len()], x)).collect()
}

/// `a (r × k) · b (k × c)`.
fn mat_mul(a: &[f64], b: &[f64], r: usize, k: usize, c: usize) -> Vec<f64> {
    let mut out = vec![0.0; r * c];
    for i in 0..r {
        for l in 0..k {
            let ail = a[i * k + l];
            for j in 0..c {
                out[i * c + j] += ail * b[l * c + j];
            }
        }
    }
    out
}

/// `F P F'`, symmetrized.
fn congruence(f: &[f64], p: &[f64], n: usize) -> Vec<f64> {
    let fp = mat_mul(f, p, n, n, n);
    let mut out = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            out[i * n + j] = dot(&fp[i * n..][..n], &f[j * n..][..n]);
        }
    }
    symmetrize(&mut out, n);
    out
}

/// The lower Cholesky factor of `a (n × n)`, or `None` if not positive definite.
fn cholesky(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; n * n];
    crate::nonlinear::cholesky(&mut l, a, n).ok()?;
    Some(l)
}
