//! Rauch–Tung–Striebel fixed-interval smoother (docs/algorithms.md, "RTS"), run backwards over
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

use crate::core::dense::{ldl, ldl_solve, mul, mul_bt, mul_sym, mul_vec_add, symmetrize, transpose};
use crate::core::dims::with_dims;
use crate::core::dims::Fused;
use crate::core::dims::{Buf, Dims};
use crate::core::isa::{kernel, Kernel};
#[cfg(target_arch = "x86_64")]
use crate::core::rows4::{self, Avx2Fma, Rows};
use crate::error::{Error, Result};
use crate::linear::model::LinearGaussian;

/// The filter outputs the backward pass reads (row-major, sizes as in [`crate::FilterResult`]).
#[derive(Debug, Clone, Copy)]
pub struct FilteredView<'a> {
    /// x̂(t|t−1), `(T, n)`.
    pub x_pred: &'a [f64],
    /// P(t|t−1), `(T, n, n)`.
    pub p_pred: &'a [f64],
    /// x̂(t|t), `(T, n)`.
    pub x_filt: &'a [f64],
    /// P(t|t), `(T, n, n)`.
    pub p_filt: &'a [f64],
    /// The filter gain K(t), `(T, n, m)` (used only when the model has N).
    pub gain: &'a [f64],
}

/// Output buffers of [`rts_into`]: x_smooth `(T, n)`, p_smooth and p_lag1 `(T, n, n)`.
#[derive(Debug)]
pub struct RtsOutputs<'a> {
    /// x̂(t|T−1), `(T, n)`.
    pub x_smooth: &'a mut [f64],
    /// P(t|T−1), `(T, n, n)`.
    pub p_smooth: &'a mut [f64],
    /// Cov(x(t), x(t−1) | all data), `(T, n, n)`; row 0 is zero.
    pub p_lag1: &'a mut [f64],
}

/// The backward RTS pass over filter outputs for `steps` steps. `p_lag1[t]` is
/// Cov(x(t), x(t−1) | all data) for t ≥ 1; `p_lag1[0]` is zero (there is no x(−1)).
pub fn rts_into(model: &LinearGaussian, steps: usize, filt: FilteredView<'_>, out: RtsOutputs<'_>) -> Result<()> {
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
    out.x_smooth.copy_from_slice(filt.x_filt);
    out.p_smooth.copy_from_slice(filt.p_filt);
    let priors = Priors { x_pred: filt.x_pred, p_pred: filt.p_pred, gain: filt.gain };
    rts_in_place(model, priors, out.x_smooth, out.p_smooth, Some(out.p_lag1))
}

/// What the backward pass reads besides the filtered moments: x̂(t|t−1), P(t|t−1) and, when
/// the model has N, the filter gain K(t).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Priors<'a> {
    pub x_pred: &'a [f64],
    pub p_pred: &'a [f64],
    pub gain: &'a [f64],
}

/// The backward pass in place: `x`, `p` hold x̂(t|t), P(t|t) `(T, n)`, `(T, n, n)` on entry
/// and x̂(t|T−1), P(t|T−1) on return (the C-style smoother: no copy of the filtered moments).
/// Sizes are the caller's to check.
pub(crate) fn rts_in_place(
    model: &LinearGaussian,
    priors: Priors<'_>,
    x: &mut [f64],
    p: &mut [f64],
    mut p_lag1: Option<&mut [f64]>,
) -> Result<()> {
    let (n, m) = (model.n_states(), model.n_obs());
    if x.is_empty() {
        return Ok(());
    }
    if let Some(l) = p_lag1.as_deref_mut() {
        l[..n * n].fill(0.0);
    }
    let pass = Backward { model, priors };
    let kernel = kernel();
    with_dims!(kernel, n, m, |d| pass.run(d, kernel, x, p, p_lag1))
}

struct Backward<'a> {
    model: &'a LinearGaussian,
    priors: Priors<'a>,
}

/// Scratch of one backward step.
struct Scratch<D: Dims> {
    j: D::Square,
    jt: D::Square,
    factor: D::Square,
    tmp: D::Square,
    dp: D::Square,
    dx: D::Vector,
}

impl Backward<'_> {
    /// All steps t = T−2 … 0, compiled for the loops of `core::isa` like the filter's (in
    /// methods of their own: through a closure the arrays would lose their no-alias facts).
    /// (`d` from `with_dims!` for `kernel`: compile-time sizes on x86-64 only with AVX2 + FMA.)
    fn run<D: Dims>(
        &self,
        d: D,
        kernel: Kernel,
        x: &mut [f64],
        p: &mut [f64],
        p_lag1: Option<&mut [f64]>,
    ) -> Result<()> {
        match kernel {
            // SAFETY: kernel() returns these only on CPUs with the instruction sets enabled.
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2Fma => unsafe { self.run_avx2_fma(Fused(d), x, p, p_lag1) },
            // Compile-time sizes reach this only with the unfused-sizes feature, unfused: one
            // baseline instance for both unfused kernels (the same bits).
            _ if cfg!(target_arch = "x86_64") && D::FIXED => {
                if !crate::core::isa::UNFUSED_SIZES {
                    crate::core::isa::not_compiled();
                }
                self.run_loop(d, x, p, p_lag1)
            }
            Kernel::BaselineFma => self.run_loop(Fused(d), x, p, p_lag1),
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 => unsafe { self.run_avx2(d, x, p, p_lag1) },
            #[cfg(target_arch = "x86_64")]
            _ => self.run_loop(d, x, p, p_lag1),
            #[cfg(not(target_arch = "x86_64"))]
            _ => unreachable!("every loop is fused on this target"),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2<D: Dims>(&self, d: D, x: &mut [f64], p: &mut [f64], p_lag1: Option<&mut [f64]>) -> Result<()> {
        self.run_loop(d, x, p, p_lag1)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn run_avx2_fma<D: Dims>(
        &self,
        d: D,
        x: &mut [f64],
        p: &mut [f64],
        p_lag1: Option<&mut [f64]>,
    ) -> Result<()> {
        self.run_loop(d, x, p, p_lag1)
    }

    #[inline(always)]
    fn run_loop<D: Dims>(&self, d: D, x: &mut [f64], p: &mut [f64], mut p_lag1: Option<&mut [f64]>) -> Result<()> {
        let n = d.n();
        let steps = x.len() / n;
        let mut sc: Scratch<D> = Scratch {
            j: d.square(),
            jt: d.square(),
            factor: d.square(),
            tmp: d.square(),
            dp: d.square(),
            dx: d.vector(),
        };
        for t in (0..steps.saturating_sub(1)).rev() {
            self.step(d, t, x, p, p_lag1.as_deref_mut(), &mut sc)?;
        }
        Ok(())
    }

    /// One step back, from t + 1 to t.
    #[inline(always)]
    fn step<D: Dims>(
        &self,
        d: D,
        t: usize,
        x: &mut [f64],
        p: &mut [f64],
        p_lag1: Option<&mut [f64]>,
        sc: &mut Scratch<D>,
    ) -> Result<()> {
        let (n, m) = (d.n(), d.m());
        let nn = n * n;
        let sys = self.model.at(t);
        #[cfg(target_arch = "x86_64")]
        if let (Some(cpu), None) = (rows4::for_sizes(d), sys.n) {
            return self.step_rows4(cpu, sys.f, t, x, p, p_lag1, sc);
        }
        let (p_cur, p_next) = p[t * nn..(t + 2) * nn].split_at_mut(nn);
        let p_pred = &self.priors.p_pred[(t + 1) * nn..(t + 2) * nn];
        // Jt = J' = P(t+1|t)⁻¹ (F P(t|t) − N K')
        let jt = sc.jt.get_mut();
        mul::<D>(jt, sys.f, p_cur, n, n, n);
        if let Some(nmat) = sys.n {
            let tmp = sc.tmp.get_mut();
            mul_bt::<D>(tmp, nmat, &self.priors.gain[t * n * m..(t + 1) * n * m], n, m, n);
            for (j, d) in jt.iter_mut().zip(tmp.iter()) {
                *j -= d;
            }
        }
        solve_psd::<D>(p_pred, jt, sc.factor.get_mut(), n).map_err(|e| pseudo_inverse_failed(e, t))?;
        let (j, jt) = (sc.j.get_mut(), sc.jt.get());
        transpose(j, jt, n, n);
        // x̂(t|T−1) = x̂(t|t) + J (x̂(t+1|T−1) − x̂(t+1|t))
        let (x_cur, x_next) = x[t * n..(t + 2) * n].split_at_mut(n);
        let dx = sc.dx.get_mut();
        for ((d, xs), xp) in dx.iter_mut().zip(x_next.iter()).zip(&self.priors.x_pred[(t + 1) * n..(t + 2) * n]) {
            *d = xs - xp;
        }
        mul_vec_add::<D>(x_cur, j, dx, n, n);
        // P(t|T−1) = P(t|t) + J (P(t+1|T−1) − P(t+1|t)) J'   (a symmetric product)
        let dp = sc.dp.get_mut();
        for (d, (ps, pp)) in dp.iter_mut().zip(p_next.iter().zip(p_pred)) {
            *d = ps - pp;
        }
        let tmp = sc.tmp.get_mut();
        mul::<D>(tmp, dp, jt, n, n, n);
        mul_sym::<D>(dp, j, tmp, n, n);
        for (p, d) in p_cur.iter_mut().zip(dp.iter()) {
            *p += d;
        }
        symmetrize(p_cur, n);
        // P(t+1, t | T−1) = P(t+1|T−1) J'
        if let Some(l) = p_lag1 {
            mul::<D>(&mut l[(t + 1) * nn..(t + 2) * nn], p_next, jt, n, n, n);
        }
        Ok(())
    }

    /// [`step`](Self::step) for three or four states on AVX2 registers (`core::rows4`), a model
    /// without N (`f` is the step's F): the same operations in the same order, so the same bits.
    #[cfg(target_arch = "x86_64")]
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn step_rows4<D: Dims>(
        &self,
        cpu: Avx2Fma,
        f: &[f64],
        t: usize,
        x: &mut [f64],
        p: &mut [f64],
        p_lag1: Option<&mut [f64]>,
        sc: &mut Scratch<D>,
    ) -> Result<()> {
        let (n, nn) = (cpu.n(), cpu.n() * cpu.n());
        let (p_cur, p_next) = p[t * nn..(t + 2) * nn].split_at_mut(nn);
        let p_pred = &self.priors.p_pred[(t + 1) * nn..(t + 2) * nn];
        // J' = P(t+1|t)⁻¹ F P(t|t)
        let p_filt = Rows::load(cpu, p_cur);
        let mut jt = rows4::mul_mem(f, n, &p_filt.0, n);
        if factor_psd::<D>(p_pred, sc.factor.get_mut(), n) {
            rows4::ldl_solve(sc.factor.get(), &mut jt.0, n);
        } else {
            let buf = sc.jt.get_mut();
            jt.store(cpu, buf);
            solve_pseudo_inverse(p_pred, buf, n).map_err(|e| pseudo_inverse_failed(e, t))?;
            jt = Rows::load(cpu, buf);
        }
        // x̂(t|T−1) = x̂(t|t) + J (x̂(t+1|T−1) − x̂(t+1|t)); J's columns are the rows of J'.
        let (x_cur, x_next) = x[t * n..(t + 2) * n].split_at_mut(n);
        let dx = sc.dx.get_mut();
        for ((d, xs), xp) in dx.iter_mut().zip(x_next.iter()).zip(&self.priors.x_pred[(t + 1) * n..(t + 2) * n]) {
            *d = xs - xp;
        }
        let x_smooth = rows4::add(rows4::load(cpu, x_cur), rows4::mul_vec_cols(&jt.0, dx, n));
        rows4::store(cpu, x_cur, x_smooth);
        // P(t|T−1) = P(t|t) + J (P(t+1|T−1) − P(t+1|t)) J'
        let dp = Rows::load(cpu, p_next).sub(&Rows::load(cpu, p_pred));
        let j_dp_jt = rows4::mul_rows(cpu, &jt.transpose(), &rows4::mul_rows(cpu, &dp, &jt)).mirror_upper();
        p_filt.add(&j_dp_jt).symmetrize().store(cpu, p_cur);
        // P(t+1, t | T−1) = P(t+1|T−1) J'
        if let Some(l) = p_lag1 {
            rows4::mul_rows(cpu, &Rows::load(cpu, p_next), &jt).store(cpu, &mut l[(t + 1) * nn..(t + 2) * nn]);
        }
        Ok(())
    }
}

/// The error for a smoother gain at step `t` that could not be computed.
#[cold]
pub(crate) fn pseudo_inverse_failed(problem: String, t: usize) -> Error {
    Error::arg("P_pred", problem).at_step(Some(t + 1))
}

/// Solves `A X = B` in place for the symmetric PSD `a[n×n]` and `b[n×n]`: by an L D L'
/// factorization, or, when A is singular (e.g. Q = 0 with a singular F, or R = 0), with the
/// pseudo-inverse, which gives the smoother gain because Cov(x̃(t|t), x̃(t+1|t)) lies in the
/// range of P(t+1|t). "Singular" includes a factorization that succeeds with a pivot at
/// rounding level (see [`pivots_above_rounding`]): dividing by it would amplify the rounding
/// errors of B outside that range into an error of order one (issue 9: the WPI AR(3) model
/// with R = 0, whose P(1|0) computed in Joseph form had a pivot of 2e-32).
#[inline(always)]
pub(crate) fn solve_psd<D: Dims>(
    a: &[f64],
    b: &mut [f64],
    factor: &mut [f64],
    n: usize,
) -> std::result::Result<(), String> {
    if factor_psd::<D>(a, factor, n) {
        ldl_solve::<D>(factor, b, n, n);
        return Ok(());
    }
    solve_pseudo_inverse(a, b, n)
}

/// The L D L' factor of the PSD `a[n×n]` into `factor`, and whether it solves systems with
/// `a` ([`solve_psd`]: else the pseudo-inverse does).
#[inline(always)]
fn factor_psd<D: Dims>(a: &[f64], factor: &mut [f64], n: usize) -> bool {
    ldl::<D>(factor, a, n).is_ok() && pivots_above_rounding(a, factor, n)
}

/// Whether every pivot `d_j` of the [`ldl`] factor `factor` of the PSD `a[n×n]` exceeds
/// `32 n ε max_i a_ii`.
///
/// Why this floor: for a PSD matrix every entry is bounded by the largest diagonal entry
/// (|a_ij| ≤ √(a_ii a_jj)), and the computed L D L' factor of a PSD matrix has a backward
/// error bounded by about n ε |L| D |L'| ≤ n ε max_i a_ii entrywise (Higham, *Accuracy and
/// Stability of Numerical Algorithms*, ch. 10): a pivot below that is the factor of a
/// matrix within rounding of a singular one, and its value carries no information. P(t+1|t)
/// also arrives with the filter's own rounding errors; on 3000 random models with exactly
/// singular P(t+1|t) (R = 0, rank-deficient Q, F of spectral radius up to 2, n ≤ 12, both
/// update forms) the stray pivots that the factorization accepted reached 10 n ε max a_ii,
/// so the factor 32 leaves a margin. A genuine pivot that small means a condition number above
/// 1e13, where the L D L' solve has no correct digits to lose either. The floor is relative to
/// the largest diagonal entry, not to each pivot's own, because the rounding errors of
/// P(t+1|t) are relative to its norm.
#[inline(always)]
fn pivots_above_rounding(a: &[f64], factor: &[f64], n: usize) -> bool {
    let largest_diagonal = (0..n).map(|i| a[i * n + i]).fold(0.0, f64::max);
    let floor = 32.0 * n as f64 * f64::EPSILON * largest_diagonal;
    // d_j > floor, with the factor's reciprocal pivots 1 / d_j.
    (0..n).all(|j| factor[j * n + j] * floor < 1.0)
}

#[cold]
fn solve_pseudo_inverse(a: &[f64], b: &mut [f64], n: usize) -> std::result::Result<(), String> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::dims::{Dyn, Fixed};
    use crate::linear::model::{Matrices, StepMatrix};
    use crate::{filter, Series, UpdateForm};

    #[cfg(target_arch = "x86_64")]
    /// The backward pass gives the same bits with compile-time sizes (for n = 3 and 4 with
    /// fused multiply-adds: `core::rows4`) as with run-time sizes, in either arithmetic.
    #[test]
    fn compile_time_and_run_time_sizes_smooth_to_the_same_bits() {
        fn check<const N: usize>(fixed: Fixed<N, 2>)
        where
            Fixed<N, 2>: Dims,
        {
            let c = |r, c, v: Vec<f64>| StepMatrix::constant(r, c, v).unwrap();
            let entry = |i: usize, j: usize, diag: f64, off: f64| if i == j { diag } else { off / (1 + i + j) as f64 };
            let square = |diag: f64, off: f64| (0..N * N).map(|k| entry(k / N, k % N, diag, off)).collect::<Vec<_>>();
            let (f, q) = (square(0.95, 0.1), square(0.05, 0.01));
            let h = (0..2 * N).map(|k| if k % (N + 1) == 0 { 1.0 } else { 0.2 }).collect();
            let r = vec![0.5, 0.1, 0.1, 0.4];
            let model = LinearGaussian::new(Matrices::new(c(N, N, f), c(2, N, h), c(N, N, q), c(2, 2, r))).unwrap();
            let y: Vec<f64> = (0..60).map(|i| (i as f64 * 0.37).sin()).collect();
            let p0 = square(1.0, 0.0);
            let series = Series::new("y", &y, 30, 2).unwrap();
            let res = filter(&model, series, None, &[0.0; N], &p0, UpdateForm::Joseph).unwrap();
            let priors = Priors { x_pred: &res.x_pred, p_pred: &res.p_pred, gain: &[] };
            let pass = Backward { model: &model, priors };
            let smooth = |fixed_sizes: bool, fused: bool| {
                let (mut x, mut p, mut lag) = (res.x_filt.clone(), res.p_filt.clone(), vec![0.0; res.p_filt.len()]);
                let dyn_sizes = Dyn { n: N, m: 2 };
                match (fixed_sizes, fused) {
                    (true, true) => pass.run_loop(Fused(fixed), &mut x, &mut p, Some(&mut lag)),
                    (true, false) => pass.run_loop(fixed, &mut x, &mut p, Some(&mut lag)),
                    (false, true) => pass.run_loop(Fused(dyn_sizes), &mut x, &mut p, Some(&mut lag)),
                    (false, false) => pass.run_loop(dyn_sizes, &mut x, &mut p, Some(&mut lag)),
                }
                .unwrap();
                (x, p, lag)
            };
            let fma = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
            for fused in [false, fma] {
                assert_eq!(smooth(true, fused), smooth(false, fused), "n = {N}, fused: {fused}");
            }
        }
        check(Fixed::<3, 2>);
        check(Fixed::<4, 2>);
    }

    /// [[3, 1], [1, 1/3]] is singular; with 1/3 rounded up by one ulp its second L D L' pivot
    /// is 5.6e-17, at rounding level, which the factorization refuses. The right-hand side lies
    /// in its range up to one rounding error (as Cov(x̃(t|t), x̃(t+1|t)) does up to the
    /// filter's rounding).
    #[test]
    fn a_rounding_level_pivot_uses_the_pseudo_inverse() {
        let third_up = f64::from_bits((1.0f64 / 3.0).to_bits() + 1);
        let a = [3.0, 1.0, 1.0, third_up];
        let mut factor = [0.0; 4];
        assert_eq!(ldl::<Dyn>(&mut factor, &a, 2), Err(1));
        let mut x = [3.0, 6.0, 1.0 + f64::EPSILON, 2.0];
        solve_psd::<Dyn>(&a, &mut x, &mut factor, 2).unwrap();
        // The minimum-norm solution for the exactly singular matrix: A⁺ = (3/100) [3, 1]'[3, 1].
        for (got, want) in x.iter().zip([0.9, 1.8, 0.3, 0.6]) {
            assert!((got - want).abs() < 1e-12, "{x:?}");
        }
    }

    /// Widely different but genuine variances keep the L D L' solve (and its exact bits).
    #[test]
    fn a_well_scaled_nonsingular_matrix_keeps_the_factorization() {
        let a = [1e6, 1e-2, 1e-2, 1e-6];
        let mut factor = [0.0; 4];
        ldl::<Dyn>(&mut factor, &a, 2).unwrap();
        assert!(pivots_above_rounding(&a, &factor, 2));
        let mut expected = [1.0, 2.0, 3.0, 4.0];
        ldl_solve::<Dyn>(&factor, &mut expected, 2, 2);
        let mut x = [1.0, 2.0, 3.0, 4.0];
        solve_psd::<Dyn>(&a, &mut x, &mut factor, 2).unwrap();
        assert_eq!(x, expected);
    }
}
