//! The estimate of one past state, x[s], kept up to date as measurements arrive: the building
//! block of the fixed-point and fixed-lag smoothers (Söderström (6.45)–(6.54), (6.70)–(6.75)).
//!
//! Besides `x̂(s|t−1)` and `P(s|t−1)` it carries the cross covariance
//! `C = E[x̃(s|t−1) x̃(t|t−1)']` (Söderström's P12' / P^(i0)), which is all the update needs:
//!
//! ```text
//! K_s      = C H' S⁻¹                        (6.52), (6.70)–(6.73)
//! x̂(s|t)   = x̂(s|t−1) + K_s e(t)              (6.53), (6.64)
//! P(s|t)   = P(s|t−1) − C H' S⁻¹ H C'         (6.49), (6.75)
//! C(t+1)   = C(t) (F − K_pred(t) H)'          (6.48), (6.74)
//! ```
//!
//! With N ≠ 0 only K_pred changes (it includes N), and missing components drop out of H, S
//! and e exactly as in the filter.

use crate::core::dense::{ldl_solve, mul, mul_bt, mul_vec_add, symmetrize, transpose};
use crate::core::dims::Dyn;
use crate::linear::filter::step::LastUpdate;

/// x̂(s|t−1), P(s|t−1) and C = E[x̃(s|t−1) x̃(t|t−1)'] for one past time s.
#[derive(Debug, Clone)]
pub(crate) struct PastState {
    pub x: Vec<f64>,
    pub p: Vec<f64>,
    pub c: Vec<f64>,
}

/// Scratch buffers shared by all the past states of one smoother.
#[derive(Debug, Clone)]
pub(crate) struct Scratch {
    n: usize,
    /// C H_o' (n × m_obs), S⁻¹ H_o C' (m_obs × n), an n × n product.
    cht: Vec<f64>,
    s_inv_hct: Vec<f64>,
    nn: Vec<f64>,
    /// The closed-loop transition F − K_pred H of the last step (n × n).
    pub closed_loop: Vec<f64>,
}

impl Scratch {
    pub fn new(n: usize, m: usize) -> Self {
        Scratch {
            n,
            cht: vec![0.0; n * m],
            s_inv_hct: vec![0.0; m * n],
            nn: vec![0.0; n * n],
            closed_loop: vec![0.0; n * n],
        }
    }

    /// `closed_loop = F − K_pred H` from the filter's step just made (`gain_pred` is n × m).
    pub fn set_closed_loop(&mut self, f: &[f64], h: &[f64], gain_pred: &[f64]) {
        let n = self.n;
        let m = gain_pred.len() / n;
        mul::<Dyn>(&mut self.closed_loop, gain_pred, h, n, m, n);
        for (a, fv) in self.closed_loop.iter_mut().zip(f) {
            *a = fv - *a;
        }
    }
}

impl PastState {
    pub fn new(n: usize) -> Self {
        PastState { x: vec![0.0; n], p: vec![0.0; n * n], c: vec![0.0; n * n] }
    }

    /// Starts tracking s = t from the filter's prediction: x̂(t|t−1), P(t|t−1), C = P(t|t−1).
    pub fn start(&mut self, x_pred: &[f64], p_pred: &[f64]) {
        self.x.copy_from_slice(x_pred);
        self.p.copy_from_slice(p_pred);
        self.c.copy_from_slice(p_pred);
    }

    /// Measurement update with the filter's innovation at t (nothing if nothing was observed).
    pub fn update(&mut self, last: &LastUpdate<'_>, sc: &mut Scratch) {
        let (n, mo) = (sc.n, last.m_obs);
        if mo == 0 {
            return;
        }
        let cht = &mut sc.cht[..n * mo];
        mul_bt::<Dyn>(cht, &self.c, last.h, n, n, mo);
        // x̂(s|t) = x̂(s|t−1) + C H' (S⁻¹ e)
        mul_vec_add::<Dyn>(&mut self.x, cht, last.s_inv_e, n, mo);
        // P(s|t) = P(s|t−1) − (C H') S⁻¹ (C H')'
        let w = &mut sc.s_inv_hct[..mo * n];
        transpose(w, cht, n, mo);
        ldl_solve::<Dyn>(last.s_factor, w, mo, n);
        mul::<Dyn>(&mut sc.nn, cht, w, n, mo, n);
        for (p, d) in self.p.iter_mut().zip(&sc.nn) {
            *p -= d;
        }
        symmetrize(&mut self.p, n);
    }

    /// C(t+1) = C(t) (F − K_pred(t) H)', with `sc.closed_loop` set for step t.
    pub fn advance(&mut self, sc: &mut Scratch) {
        let n = sc.n;
        mul_bt::<Dyn>(&mut sc.nn, &self.c, &sc.closed_loop, n, n, n);
        self.c.copy_from_slice(&sc.nn);
    }
}
