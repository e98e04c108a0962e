//! Rauch–Tung–Striebel fixed-interval smoother (ALGORITHMS.md §5.2–5.3), run backwards over
//! the stored filter outputs:
//!
//! ```text
//! J(t)      = (P(t|t) F' − K(t) N') P(t+1|t)⁻¹
//! x̂(t|T−1)  = x̂(t|t) + J(t) (x̂(t+1|T−1) − x̂(t+1|t))
//! P(t|T−1)  = P(t|t) + J(t) (P(t+1|T−1) − P(t+1|t)) J(t)'
//! P(t+1, t|T−1) = P(t+1|T−1) J(t)'                   (lag-one covariance)
//! ```
//!
//! Correlated noise: P(t|t) F' − K N' is Cov(x̃(t|t), x̃(t+1|t)) when w and v are correlated.
//! It is the N = 0 formula applied to the decorrelated model of Söderström Lemma 6.4
//! (F̄ = F − N R⁻¹ H, so P(t|t) F̄' = P(t|t) F' − K N' because K = P(t|t) H' R⁻¹), written so
//! that it needs no R⁻¹ and holds for singular R too. Missing data need nothing extra: K has
//! zero columns for missing components.

use crate::dense::{cholesky, mul, mul_bt, mul_vec_add, solve_lower, solve_lower_t, symmetrize, transpose};
use crate::error::{Error, Result};
use crate::model::LinearGaussian;

/// The filter outputs the backward pass reads (row-major, sizes as in [`crate::FilterResult`]).
#[derive(Debug, Clone, Copy)]
pub struct FilteredView<'a> {
    pub x_pred: &'a [f64],
    pub p_pred: &'a [f64],
    pub x_filt: &'a [f64],
    pub p_filt: &'a [f64],
    pub gain: &'a [f64],
}

/// Output buffers of [`rts_into`]: x_smooth `(T, n)`, p_smooth and p_lag1 `(T, n, n)`.
#[derive(Debug)]
pub struct SmootherOutputs<'a> {
    pub x_smooth: &'a mut [f64],
    pub p_smooth: &'a mut [f64],
    pub p_lag1: &'a mut [f64],
}

/// The backward RTS pass over filter outputs for `steps` steps. `p_lag1[t]` is
/// Cov(x[t], x[t−1] | all data) for t ≥ 1; `p_lag1[0]` is zero (there is no x[−1]).
pub fn rts_into(model: &LinearGaussian, steps: usize, filt: FilteredView<'_>, out: SmootherOutputs<'_>) -> Result<()> {
    let (n, m) = (model.n_states(), model.n_obs());
    let nn = n * n;
    for (arg, got, want) in [
        ("x_smooth", out.x_smooth.len(), steps * n),
        ("P_smooth", out.p_smooth.len(), steps * nn),
        ("P_lag1", out.p_lag1.len(), steps * nn),
        ("x_filt", filt.x_filt.len(), steps * n),
        ("P_filt", filt.p_filt.len(), steps * nn),
        ("x_pred", filt.x_pred.len(), steps * n),
        ("P_pred", filt.p_pred.len(), steps * nn),
        ("K", filt.gain.len(), steps * n * m),
    ] {
        if got != want {
            return Err(Error::arg(arg, format!("buffer has {got} entries, needs {want}")));
        }
    }
    if steps == 0 {
        return Ok(());
    }
    let last = steps - 1;
    out.x_smooth[last * n..].copy_from_slice(&filt.x_filt[last * n..]);
    out.p_smooth[last * nn..].copy_from_slice(&filt.p_filt[last * nn..]);
    out.p_lag1[..nn].fill(0.0);
    let mut sc = Backward::new(n);
    for t in (0..last).rev() {
        let sys = model.at(t);
        let (cur, next) = (t * nn..(t + 1) * nn, (t + 1) * nn..(t + 2) * nn);
        // Jt = J' = P(t+1|t)⁻¹ (F P(t|t) − N K')
        mul(&mut sc.jt, sys.f, &filt.p_filt[cur.clone()], n, n, n);
        if let Some(nmat) = sys.n {
            mul_bt(&mut sc.tmp, nmat, &filt.gain[t * n * m..(t + 1) * n * m], n, m, n);
            for (j, d) in sc.jt.iter_mut().zip(&sc.tmp) {
                *j -= d;
            }
        }
        solve_psd(&filt.p_pred[next.clone()], &mut sc.jt, &mut sc.chol, n)
            .map_err(|p| Error::arg("P_pred", p).at_step(Some(t + 1)))?;
        transpose(&mut sc.j, &sc.jt, n, n);
        // x̂(t|T−1) = x̂(t|t) + J (x̂(t+1|T−1) − x̂(t+1|t))
        for i in 0..n {
            sc.dx[i] = out.x_smooth[(t + 1) * n + i] - filt.x_pred[(t + 1) * n + i];
        }
        let xs = &mut out.x_smooth[t * n..(t + 1) * n];
        xs.copy_from_slice(&filt.x_filt[t * n..(t + 1) * n]);
        mul_vec_add(xs, &sc.j, &sc.dx, n, n);
        // P(t|T−1) = P(t|t) + J (P(t+1|T−1) − P(t+1|t)) J'
        for (d, (ps, pp)) in sc.dp.iter_mut().zip(out.p_smooth[next.clone()].iter().zip(&filt.p_pred[next.clone()])) {
            *d = ps - pp;
        }
        mul(&mut sc.tmp, &sc.dp, &sc.jt, n, n, n);
        mul(&mut sc.dp, &sc.j, &sc.tmp, n, n, n);
        let ps = &mut out.p_smooth[cur.clone()];
        for (p, (pf, d)) in ps.iter_mut().zip(filt.p_filt[cur].iter().zip(&sc.dp)) {
            *p = pf + d;
        }
        symmetrize(ps, n);
        // P(t+1, t | T−1) = P(t+1|T−1) J'
        mul(&mut out.p_lag1[next.clone()], &out.p_smooth[next], &sc.jt, n, n, n);
    }
    Ok(())
}

struct Backward {
    j: Vec<f64>,
    jt: Vec<f64>,
    chol: Vec<f64>,
    tmp: Vec<f64>,
    dp: Vec<f64>,
    dx: Vec<f64>,
}

impl Backward {
    fn new(n: usize) -> Self {
        let z = |len| vec![0.0; len];
        Backward { j: z(n * n), jt: z(n * n), chol: z(n * n), tmp: z(n * n), dp: z(n * n), dx: z(n) }
    }
}

/// Solves `A X = B` in place for the symmetric PSD `a[n×n]` and `b[n×n]`: by Cholesky, or,
/// when A is singular (e.g. Q = 0 with a singular F), with the pseudo-inverse, which gives
/// the smoother gain because Cov(x̃(t|t), x̃(t+1|t)) lies in the range of P(t+1|t).
fn solve_psd(a: &[f64], b: &mut [f64], chol: &mut [f64], n: usize) -> std::result::Result<(), String> {
    chol.copy_from_slice(a);
    if cholesky(chol, n).is_ok() {
        solve_lower(chol, b, n, n);
        solve_lower_t(chol, b, n, n);
        return Ok(());
    }
    let mat = faer::Mat::<f64>::from_fn(n, n, |i, j| a[i * n + j]);
    let eig = mat.self_adjoint_eigen(faer::Side::Lower).map_err(|_| "eigendecomposition failed".to_string())?;
    let (u, s) = (eig.U(), eig.S().column_vector());
    let top = (0..n).map(|i| s[i].abs()).fold(0.0, f64::max);
    let cutoff = 1e-12 * top.max(f64::MIN_POSITIVE);
    // X = U diag(1/λ) U' B over the eigenvalues above the cutoff.
    let mut x = vec![0.0; n * n];
    for k in 0..n {
        if s[k] <= cutoff {
            continue;
        }
        for c in 0..n {
            let proj: f64 = (0..n).map(|i| u[(i, k)] * b[i * n + c]).sum::<f64>() / s[k];
            for r in 0..n {
                x[r * n + c] += u[(r, k)] * proj;
            }
        }
    }
    b.copy_from_slice(&x);
    Ok(())
}
