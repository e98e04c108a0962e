//! Sigma-point sets and the unscented transform (Julier & Uhlmann 1997; Julier 2002; Wan & van
//! der Merwe 2000; Arasaratnam & Haykin 2009).

use std::sync::Arc;

use crate::error::{Error, Result};

/// A sigma-point set: where the points of a Gaussian (x̂, P) sit and how they are weighted.
///
/// The points are `x̂` (unless the set has no centre) and `x̂ ± c a_i` for the columns `a_i` of
/// the lower Cholesky factor of P, in the order [centre, +1 … +n, −1 … −n]:
///
/// | set | c | weights |
/// |---|---|---|
/// | [`Merwe`](Self::Merwe) (α, β, κ) | √(n + λ), λ = α²(n + κ) − n | W⁰ₘ = λ/(n+λ), W⁰꜀ = W⁰ₘ + 1 − α² + β, Wᵢ = 1/2(n+λ) |
/// | [`Julier`](Self::Julier) (κ) | √(n + κ) | W⁰ = κ/(n+κ), Wᵢ = 1/2(n+κ) |
/// | [`Cubature`](Self::Cubature) | √n | no centre, Wᵢ = 1/2n |
/// | [`Custom`](Self::Custom) | the user's unit points ξᵢ: Xᵢ = x̂ + L ξᵢ | the user's Wₘ, W꜀ |
#[derive(Debug, Clone, PartialEq)]
pub enum SigmaPoints {
    /// Scaled points (Julier 2002; Wan & van der Merwe 2000).
    Merwe {
        /// Spread, usually small (1e-3 … 1).
        alpha: f64,
        /// Prior knowledge of the distribution (2 is optimal for a Gaussian).
        beta: f64,
        /// Secondary scaling (0, or 3 − n).
        kappa: f64,
    },
    /// Julier & Uhlmann (1997).
    Julier {
        /// Scaling; n + κ must be > 0.
        kappa: f64,
    },
    /// Third-degree spherical-radial cubature (Arasaratnam & Haykin 2009).
    Cubature,
    /// A set of the user's for one state size ([`CustomPoints`]).
    Custom(Arc<CustomPoints>),
}

/// A user's sigma-point set for state size n: unit points ξᵢ (k × n), placed at
/// `Xᵢ = x̂ + L ξᵢ` with L the lower Cholesky factor of P, mean weights Wₘ (summing to 1) and
/// covariance weights W꜀. The unscented transform takes the plain sums about the mean
/// (`z̄ = Σ Wₘᵢ Zᵢ`, `Cov = Σ W꜀ᵢ (Zᵢ − z̄)(Zᵢ − z̄)'`), angles relative to the first point.
#[derive(Debug, Clone, PartialEq)]
pub struct CustomPoints {
    n: usize,
    unit: Vec<f64>,
    mean: Vec<f64>,
    cov: Vec<f64>,
}

impl CustomPoints {
    /// Checks the set: `unit` is k × n (k ≥ 1) and finite, `mean` and `cov` have k finite
    /// weights, and the mean weights sum to 1 (to 1e-9 of their absolute sum).
    pub fn new(unit: Vec<f64>, n: usize, mean: Vec<f64>, cov: Vec<f64>) -> Result<Self> {
        let k = mean.len();
        let bad = |problem: String| Err(Error::arg("points", problem));
        if n == 0 || k == 0 || unit.len() != k * n {
            return bad(format!(
                "expected k >= 1 unit points of n = {n} numbers and k weights, got {} numbers and {k} weights",
                unit.len()
            ));
        }
        if cov.len() != k {
            return bad(format!("expected {k} covariance weights (one per point), got {}", cov.len()));
        }
        if let Some(v) = unit.iter().chain(&mean).chain(&cov).find(|v| !v.is_finite()) {
            return bad(format!("points and weights must be finite, got {v}"));
        }
        let (sum, size) = mean.iter().fold((0.0, 0.0), |(s, a), w| (s + w, a + w.abs()));
        if (sum - 1.0).abs() > 1e-9 * size.max(1.0) {
            return bad(format!("the mean weights must sum to 1, got {sum}"));
        }
        Ok(CustomPoints { n, unit, mean, cov })
    }
}

/// The numbers of a set for a dimension n: the spread c and the weights.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Weights {
    /// `x̂ ± c a_i`.
    pub spread: f64,
    /// Whether the first point is the centre x̂.
    pub centre: bool,
    /// Mean weights, one per point.
    pub mean: Vec<f64>,
    /// A custom set's unit points (k × n) and covariance weights; `None` for the built-in sets.
    pub unit: Option<Vec<f64>>,
    pub cov: Option<Vec<f64>>,
    /// `W⁰꜀ − W⁰ₘ` (0 without a centre): the covariance weights are the mean weights but for
    /// the centre's.
    pub centre_excess: f64,
}

impl SigmaPoints {
    /// Checks the parameters (for the state size n).
    pub fn validate(&self, n: usize) -> Result<()> {
        let finite = |name: &'static str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(Error::arg("points", format!("{name} must be finite, got {v}")))
            }
        };
        match *self {
            SigmaPoints::Merwe { alpha, beta, kappa } => {
                finite("alpha", alpha)?;
                finite("beta", beta)?;
                finite("kappa", kappa)?;
                if alpha <= 0.0 || n as f64 + kappa <= 0.0 {
                    return Err(Error::arg(
                        "points",
                        format!("Merwe points need alpha > 0 and n + kappa > 0 (n = {n}), got alpha = {alpha}, kappa = {kappa}"),
                    ));
                }
            }
            SigmaPoints::Julier { kappa } => {
                finite("kappa", kappa)?;
                if n as f64 + kappa <= 0.0 {
                    return Err(Error::arg(
                        "points",
                        format!("Julier points need n + kappa > 0 (n = {n}), got kappa = {kappa}"),
                    ));
                }
            }
            SigmaPoints::Cubature => {}
            SigmaPoints::Custom(ref p) => {
                if p.n != n {
                    return Err(Error::arg(
                        "points",
                        format!("the set is for n = {} states, the model has n = {n}", p.n),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The number of points for state size n.
    pub fn count(&self, n: usize) -> usize {
        match self {
            SigmaPoints::Cubature => 2 * n,
            SigmaPoints::Custom(p) => p.mean.len(),
            _ => 2 * n + 1,
        }
    }

    pub(crate) fn weights(&self, n: usize) -> Weights {
        let nf = n as f64;
        let (spread2, w0m, excess) = match self {
            &SigmaPoints::Merwe { alpha, beta, kappa } => {
                let lambda = alpha * alpha * (nf + kappa) - nf;
                (nf + lambda, lambda / (nf + lambda), 1.0 - alpha * alpha + beta)
            }
            &SigmaPoints::Julier { kappa } => (nf + kappa, kappa / (nf + kappa), 0.0),
            SigmaPoints::Cubature => {
                let mean = vec![0.5 / nf; 2 * n];
                return Weights { spread: nf.sqrt(), centre: false, mean, centre_excess: 0.0, unit: None, cov: None };
            }
            SigmaPoints::Custom(p) => {
                let (unit, cov) = (Some(p.unit.clone()), Some(p.cov.clone()));
                return Weights { spread: 1.0, centre: false, mean: p.mean.clone(), centre_excess: 0.0, unit, cov };
            }
        };
        let mut mean = vec![0.5 / spread2; 2 * n + 1];
        mean[0] = w0m;
        Weights { spread: spread2.sqrt(), centre: true, mean, centre_excess: excess, unit: None, cov: None }
    }
}

/// `$body` with `$n` bound to the literal `1..=6` when `$size` is one of them (so that the
/// `#[inline(always)]` loops it calls are compiled for that size and unrolled), else to `$size`.
macro_rules! with_small {
    ($size:expr, |$n:ident| $body:expr) => {
        match $size {
            1 => {
                let $n = 1;
                $body
            }
            2 => {
                let $n = 2;
                $body
            }
            3 => {
                let $n = 3;
                $body
            }
            4 => {
                let $n = 4;
                $body
            }
            5 => {
                let $n = 5;
                $body
            }
            6 => {
                let $n = 6;
                $body
            }
            $n => $body,
        }
    };
}

/// The lower Cholesky factor of the symmetric `a[n×n]` into `l` (upper part zero); `Err(j)`
/// when pivot j is not positive (P not positive definite to working precision).
pub(crate) fn cholesky(l: &mut [f64], a: &[f64], n: usize) -> std::result::Result<(), usize> {
    let (l, a) = (&mut l[..n * n], &a[..n * n]);
    match n {
        1 => cholesky_fixed::<1>(l, a),
        2 => cholesky_fixed::<2>(l, a),
        3 => cholesky_fixed::<3>(l, a),
        4 => cholesky_fixed::<4>(l, a),
        5 => cholesky_fixed::<5>(l, a),
        6 => cholesky_fixed::<6>(l, a),
        _ => cholesky_any(l, a, n),
    }
}

/// `1/d` for a pivot that is positive and finite with a finite reciprocal (a subnormal d has
/// none): `None` when the matrix is not positive definite to working precision.
#[inline(always)]
fn pivot_reciprocal(d: f64) -> Option<f64> {
    let inv = 1.0 / d;
    (d > 0.0 && d.is_finite() && inv.is_finite()).then_some(inv)
}

/// [`cholesky_any`] at a compile-time size, in local arrays (registers): the same arithmetic
/// in the same order, so the same bits. (Index loops on purpose: they unroll at the constant
/// size.)
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn cholesky_fixed<const N: usize>(l: &mut [f64], a: &[f64]) -> std::result::Result<(), usize> {
    let mut u = [[0.0; N]; N];
    for (i, row) in u.iter_mut().enumerate() {
        row.copy_from_slice(&a[i * N..][..N]);
    }
    let mut inv = [0.0; N];
    for j in 0..N {
        for i in j..N {
            let mut s = u[i][j];
            for k in 0..j {
                s -= u[i][k] * u[k][j];
            }
            u[i][j] = s;
        }
        inv[j] = pivot_reciprocal(u[j][j]).ok_or(j)?;
        for i in j + 1..N {
            u[j][i] = u[i][j] * inv[j];
        }
    }
    for (i, row) in u.iter().enumerate() {
        let out = &mut l[i * N..][..N];
        for j in 0..N {
            out[j] = if j <= i { row[j] * inv[j].sqrt() } else { 0.0 };
        }
    }
    Ok(())
}

/// The lower Cholesky factor at any size, computed as L D L' first (Golub & Van Loan, Matrix
/// Computations, the L D L' factorization): column j holds u_ij = a_ij − Σ_k u_ik v_jk (k < j),
/// with the pivot d_j = u_jj and v_ij = u_ij / d_j kept in the upper triangle (at (j, i)); then
/// l_ij = u_ij √(1/d_j). The chain from one pivot to the next runs through a division only; the
/// square roots, which take longer, are off it.
fn cholesky_any(l: &mut [f64], a: &[f64], n: usize) -> std::result::Result<(), usize> {
    for j in 0..n {
        for i in j..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[k * n + j];
            }
            l[i * n + j] = s;
        }
        let inv = pivot_reciprocal(l[j * n + j]).ok_or(j)?;
        for i in j + 1..n {
            l[j * n + i] = l[i * n + j] * inv;
        }
    }
    for j in 0..n {
        let scale = (1.0 / l[j * n + j]).sqrt();
        for i in j..n {
            l[i * n + j] *= scale;
        }
        for i in j + 1..n {
            l[j * n + i] = 0.0;
        }
    }
    Ok(())
}

/// The lower factor L (L L' = a) of the symmetric positive *semi*definite `a[n×n]` into `l`:
/// a pivot at rounding level (≤ n ε max aᵢᵢ) leaves its column zero, which is exact for a
/// positive semidefinite matrix (its Schur complement's column is then zero too), so a
/// singular covariance (a noise of lower rank, even 0) has a factor.
pub(crate) fn semidefinite_cholesky(l: &mut [f64], a: &[f64], n: usize) {
    let tol = n as f64 * f64::EPSILON * (0..n).map(|i| a[i * n + i]).fold(0.0, f64::max);
    l.fill(0.0);
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= l[j * n + k] * l[j * n + k];
        }
        if d <= tol {
            continue;
        }
        let d = d.sqrt();
        l[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = s / d;
        }
    }
}

/// The points of (x, P) into `out` (`count × n`), given the lower factor `l` of P.
pub(crate) fn place(w: &Weights, x: &[f64], l: &[f64], out: &mut [f64]) {
    with_small!(x.len(), |n| place_sized(w, &x[..n], &l[..n * n], out, n))
}

#[inline(always)]
fn place_sized(w: &Weights, x: &[f64], l: &[f64], out: &mut [f64], n: usize) {
    if let Some(unit) = &w.unit {
        // X_i = x + L ξ_i (L lower triangular)
        for (row, xi) in out.chunks_exact_mut(n).zip(unit.chunks_exact(n)) {
            for j in 0..n {
                let mut v = x[j];
                for c in 0..=j {
                    v += l[j * n + c] * xi[c];
                }
                row[j] = v;
            }
        }
        return;
    }
    let first = usize::from(w.centre);
    if w.centre {
        out[..n].copy_from_slice(x);
    }
    for (half, sign) in [1.0, -1.0].into_iter().enumerate() {
        let scale = sign * w.spread;
        for i in 0..n {
            // column i of L, scaled
            let row = &mut out[(first + half * n + i) * n..][..n];
            for j in 0..n {
                row[j] = x[j] + scale * l[j * n + i];
            }
        }
    }
}

/// What [`unscented_transform`] computes for points of an n-vector mapped to an r-vector, with
/// its scratch: allocated once per call of a filter.
#[derive(Debug, Clone)]
pub(crate) struct Transformed {
    /// The mean of z (r).
    pub mean: Vec<f64>,
    /// `Cov(z)` (r × r).
    pub cov: Vec<f64>,
    /// `Cov(x, z)` (n × r).
    pub cross: Vec<f64>,
    dev: Vec<f64>,
    d: Vec<f64>,
    e: Vec<f64>,
}

impl Transformed {
    /// The deviations Dᵢ of the transformed points (k × r; from the centre point, or from the
    /// mean for a set without one) and `d = Σ Wᵢ Dᵢ` (i ≥ 1 with a centre), as the last
    /// transform left them: `Cov(z) = Σ W꜀ᵢ Dᵢ Dᵢ' + (W⁰꜀ − W⁰ₘ − 1) d d'` (the last term with a
    /// centre only).
    pub fn deviations(&self) -> (&[f64], &[f64]) {
        (&self.dev, &self.d)
    }

    pub fn new(points: usize, n: usize, r: usize) -> Self {
        Transformed {
            mean: vec![0.0; r],
            cov: vec![0.0; r * r],
            cross: vec![0.0; n * r],
            dev: vec![0.0; points * r],
            d: vec![0.0; r],
            e: vec![0.0; n],
        }
    }
}

/// The unscented transform of points `x_pts` (`k × n`) mapped to `z_pts` (`k × r`) into `out`:
/// the mean of z, `Cov(z)` and `Cov(x, z)`.
///
/// With a centre point it uses the centred form: with `D_i = Z_i − Z_0`, `E_i = X_i − X_0`
/// (i ≥ 1), `d = Σ W_i D_i`, `e = Σ W_i E_i` and `δ = W⁰꜀ − W⁰ₘ`,
/// `z̄ = Z_0 + d`, `Cov(z) = Σ W_i D_i D_i' + (δ − 1) d d'`, `Cov(x, z) = Σ W_i E_i D_i' +
/// (δ − 1) e d'` — the plain sums rearranged exactly, with every remaining weight positive,
/// so that a small α (W⁰ₘ ≈ −10⁶ at α = 10⁻³) does not cancel the digits away. Components of
/// z listed in `angles` are differenced to the centre and wrapped, so their mean is the
/// circular mean about the centre point (without a centre: about the first point).
///
/// `Cov(x, z)` is computed only when `want_cross` (a time update needs it only for a smoother).
///
/// The loops run over whole rows (`chunks_exact`), so they carry no index arithmetic or bounds
/// checks; each entry sums the same products in the same order as the plain loops.
pub(crate) fn unscented_transform(
    w: &Weights,
    x_pts: &[f64],
    z_pts: &[f64],
    angles: &[usize],
    want_cross: bool,
    out: &mut Transformed,
) {
    // Small (n, r) get a copy of the loops compiled for their sizes, unrolled: at run-time
    // sizes the loop control of these short rows cost more than their arithmetic (CT model,
    // n = 5: 9,500 instructions a step for the two transforms, by callgrind).
    macro_rules! sized {
        ($(($n:literal, $r:literal)),*) => {
            match (out.e.len(), out.mean.len()) {
                $(($n, $r) => transform_sized($n, $r, w, x_pts, z_pts, angles, want_cross, out),)*
                (n, r) => transform_sized(n, r, w, x_pts, z_pts, angles, want_cross, out),
            }
        };
    }
    sized!(
        (1, 1),
        (2, 1),
        (2, 2),
        (3, 1),
        (3, 2),
        (3, 3),
        (4, 1),
        (4, 2),
        (4, 3),
        (4, 4),
        (5, 1),
        (5, 2),
        (5, 3),
        (5, 5),
        (6, 1),
        (6, 2),
        (6, 3),
        (6, 6)
    )
}

/// [`unscented_transform`] for `n` and `r` (constants where inlined into a sized arm).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn transform_sized(
    n: usize,
    r: usize,
    w: &Weights,
    x_pts: &[f64],
    z_pts: &[f64],
    angles: &[usize],
    want_cross: bool,
    out: &mut Transformed,
) {
    use super::function::wrap_angle;
    let k = w.mean.len();
    let Transformed { dev, d: d_out, e: e_out, mean: z_mean, cov: cov_out, cross: cross_out } = out;
    // The sums accumulate in local arrays where they fit (every sized arm): the compiler then
    // keeps them in registers across the loop over the points, which it cannot do for `out`'s
    // buffers (it cannot rule out that they overlap the points). Every slice is cut to its size
    // and every row taken as `[i * len..][..len]`, so that a sized arm knows every length and
    // keeps no bounds checks.
    let local = n <= SMALL && r <= SMALL;
    let (mut d_local, mut e_local) = ([0.0; SMALL], [0.0; SMALL]);
    let (mut cov_local, mut cross_local) = ([0.0; SMALL * SMALL], [0.0; SMALL * SMALL]);
    // (otherwise `out`'s buffers, moved out meanwhile: no allocation)
    let take = |v: &mut Vec<f64>| if local { Vec::new() } else { std::mem::take(v) };
    let (mut d_heap, mut e_heap, mut cov_heap, mut cross_heap) =
        (take(d_out), take(e_out), take(cov_out), take(cross_out));
    let (d, e, cov, cross): (&mut [f64], &mut [f64], &mut [f64], &mut [f64]) = if local {
        (&mut d_local[..r], &mut e_local[..n], &mut cov_local[..r * r], &mut cross_local[..n * r])
    } else {
        (&mut d_heap[..r], &mut e_heap[..n], &mut cov_heap[..r * r], &mut cross_heap[..n * r])
    };
    let z_mean = &mut z_mean[..r];
    let (x_pts, z_pts, dev) = (&x_pts[..k * n], &z_pts[..k * r], &mut dev[..k * r]);
    let (z0, x0) = (&z_pts[..r], &x_pts[..n]);
    // deviations from the first point (the centre, if any), angles wrapped
    for i in 0..k {
        let (dev_i, z_i) = (&mut dev[i * r..][..r], &z_pts[i * r..][..r]);
        for c in 0..r {
            dev_i[c] = z_i[c] - z0[c];
        }
        for &a in angles {
            dev_i[a] = wrap_angle(dev_i[a]);
        }
    }
    let first = usize::from(w.centre);
    d.fill(0.0);
    e.fill(0.0);
    for i in first..k {
        let (wi, dev_i, x_i) = (w.mean[i], &dev[i * r..][..r], &x_pts[i * n..][..n]);
        for c in 0..r {
            d[c] += wi * dev_i[c];
        }
        if want_cross {
            for c in 0..n {
                e[c] += wi * (x_i[c] - x0[c]);
            }
        }
    }
    if !w.centre {
        // plain sums about the mean, all weights positive: shift the deviations to the mean
        for i in 0..k {
            let dev_i = &mut dev[i * r..][..r];
            for c in 0..r {
                dev_i[c] -= d[c];
            }
        }
        // and take the x deviations below from the mean x0 + e (kept in e)
        for c in 0..n {
            e[c] += x0[c];
        }
    }
    for c in 0..r {
        z_mean[c] = z0[c] + d[c];
    }
    cov.fill(0.0);
    cross.fill(0.0);
    let x_ref: &[f64] = if w.centre { x0 } else { e };
    // the covariance weights: a custom set's own, else the mean weights (the centre's excess
    // is added below)
    let cov_weights = w.cov.as_deref().unwrap_or(&w.mean);
    for i in first..k {
        let (wi, dev_i, x_i) = (cov_weights[i], &dev[i * r..][..r], &x_pts[i * n..][..n]);
        add_outer_upper(cov, r, wi, dev_i);
        if want_cross {
            for a in 0..n {
                let s = wi * (x_i[a] - x_ref[a]);
                let row = &mut cross[a * r..][..r];
                for b in 0..r {
                    row[b] += s * dev_i[b];
                }
            }
        }
    }
    if w.centre {
        let g = w.centre_excess - 1.0;
        add_outer_upper(cov, r, g, d);
        if want_cross {
            for a in 0..n {
                let s = g * e[a];
                let row = &mut cross[a * r..][..r];
                for b in 0..r {
                    row[b] += s * d[b];
                }
            }
        }
    }
    for a in 0..r {
        for b in 0..a {
            cov[a * r + b] = cov[b * r + a];
        }
    }
    if local {
        d_out[..r].copy_from_slice(d);
        cov_out[..r * r].copy_from_slice(cov);
        if want_cross {
            cross_out[..n * r].copy_from_slice(cross);
        }
    } else {
        (*d_out, *e_out, *cov_out, *cross_out) = (d_heap, e_heap, cov_heap, cross_heap);
    }
}

/// The largest n and r whose transform sums stay in local arrays.
const SMALL: usize = 6;

/// `cov += w v v'` on and above the diagonal (`cov` is r × r, `v` an r-vector).
#[inline(always)]
fn add_outer_upper(cov: &mut [f64], r: usize, w: f64, v: &[f64]) {
    for a in 0..r {
        let s = w * v[a];
        let row = &mut cov[a * r..][..r];
        for b in a..r {
            row[b] += s * v[b];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Numbers in (−2, 2), reproducible.
    fn numbers(seed: u64, len: usize) -> Vec<f64> {
        let mut s = seed;
        (0..len)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
            })
            .collect()
    }

    #[test]
    fn cholesky_rejects_pivots_without_a_finite_reciprocal() {
        for n in [2, 7] {
            let mut a = vec![0.0; n * n];
            for i in 0..n {
                a[i * n + i] = 1.0;
            }
            a[n + 1] = 1e-310; // subnormal: 1/d overflows
            let mut l = vec![0.0; n * n];
            assert_eq!(cholesky(&mut l, &a, n), Err(1), "n = {n}");
            a[n + 1] = 1e-300;
            assert_eq!(cholesky(&mut l, &a, n), Ok(()), "n = {n}");
            assert!(l.iter().all(|v| v.is_finite()));
        }
    }

    /// The loops compiled for small sizes give the bits of the run-time-size loops, for every
    /// kind of point set (with a centre or not) and with angles (in an optimized build the sized
    /// arms are unrolled copies; the Python tests run those against the NumPy reference).
    #[test]
    fn sized_loops_give_the_bits_of_run_time_sizes() {
        let sets = [
            SigmaPoints::Merwe { alpha: 0.5, beta: 2.0, kappa: 0.0 },
            SigmaPoints::Julier { kappa: 1.0 },
            SigmaPoints::Cubature,
        ];
        for (n, r) in [(1, 1), (3, 2), (5, 2), (5, 5), (6, 3)] {
            for points in sets.clone() {
                let w = points.weights(n);
                let k = w.mean.len();
                let x = numbers(n as u64, n);
                let a = numbers(7 + n as u64, n * n);
                // a positive definite P = A A' + I
                let mut p = vec![0.0; n * n];
                for i in 0..n {
                    for j in 0..n {
                        p[i * n + j] = (0..n).map(|l| a[i * n + l] * a[j * n + l]).sum::<f64>() + f64::from(i == j);
                    }
                }
                let (mut l, mut l_dyn) = (vec![0.0; n * n], vec![0.0; n * n]);
                cholesky(&mut l, &p, n).unwrap();
                cholesky_any(&mut l_dyn, &p, std::hint::black_box(n)).unwrap();
                assert_eq!(l, l_dyn);
                let (mut pts, mut pts_dyn) = (vec![0.0; k * n], vec![0.0; k * n]);
                place(&w, &x, &l, &mut pts);
                place_sized(&w, &x, &l, &mut pts_dyn, std::hint::black_box(n));
                assert_eq!(pts, pts_dyn);
                let z: Vec<f64> = numbers(3, k * r).iter().zip(pts.iter().cycle()).map(|(e, x)| x * x + e).collect();
                let angles: &[usize] = if r > 1 { &[1] } else { &[] };
                let (mut out, mut out_dyn) = (Transformed::new(k, n, r), Transformed::new(k, n, r));
                unscented_transform(&w, &pts, &z, angles, true, &mut out);
                let (nd, rd) = (std::hint::black_box(n), std::hint::black_box(r));
                transform_sized(nd, rd, &w, &pts, &z, angles, true, &mut out_dyn);
                assert_eq!(
                    (&out.mean, &out.cov, &out.cross),
                    (&out_dyn.mean, &out_dyn.cov, &out_dyn.cross),
                    "({n}, {r})"
                );
            }
        }
    }
}
