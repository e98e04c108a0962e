//! Sigma-point sets and the unscented transform (Julier & Uhlmann 1997; Julier 2002; Wan & van
//! der Merwe 2000; Arasaratnam & Haykin 2009).

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
#[derive(Debug, Clone, Copy, PartialEq)]
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
        }
        Ok(())
    }

    /// The number of points for state size n.
    pub fn count(&self, n: usize) -> usize {
        match self {
            SigmaPoints::Cubature => 2 * n,
            _ => 2 * n + 1,
        }
    }

    pub(crate) fn weights(&self, n: usize) -> Weights {
        let nf = n as f64;
        let (spread2, w0m, excess) = match *self {
            SigmaPoints::Merwe { alpha, beta, kappa } => {
                let lambda = alpha * alpha * (nf + kappa) - nf;
                (nf + lambda, lambda / (nf + lambda), 1.0 - alpha * alpha + beta)
            }
            SigmaPoints::Julier { kappa } => (nf + kappa, kappa / (nf + kappa), 0.0),
            SigmaPoints::Cubature => {
                return Weights { spread: nf.sqrt(), centre: false, mean: vec![0.5 / nf; 2 * n], centre_excess: 0.0 };
            }
        };
        let mut mean = vec![0.5 / spread2; 2 * n + 1];
        mean[0] = w0m;
        Weights { spread: spread2.sqrt(), centre: true, mean, centre_excess: excess }
    }
}

/// The lower Cholesky factor of the symmetric `a[n×n]` into `l` (upper part zero); `Err(j)`
/// when pivot j is not positive (P not positive definite to working precision).
pub(crate) fn cholesky(l: &mut [f64], a: &[f64], n: usize) -> std::result::Result<(), usize> {
    l[..n * n].fill(0.0);
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= l[j * n + k] * l[j * n + k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return Err(j);
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
    Ok(())
}

/// The points of (x, P) into `out` (`count × n`), given the lower factor `l` of P.
pub(crate) fn place(w: &Weights, x: &[f64], l: &[f64], out: &mut [f64]) {
    let n = x.len();
    let mut rows = out.chunks_exact_mut(n);
    if w.centre {
        rows.next().unwrap_or_default().copy_from_slice(x);
    }
    for sign in [1.0, -1.0] {
        for i in 0..n {
            let row = rows.next().unwrap_or_default();
            for (j, r) in row.iter_mut().enumerate() {
                // column i of L, scaled
                *r = x[j] + sign * w.spread * l[j * n + i];
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
pub(crate) fn unscented_transform(w: &Weights, x_pts: &[f64], z_pts: &[f64], angles: &[usize], out: &mut Transformed) {
    use super::function::wrap_angle;
    let (n, r, k) = (out.e.len(), out.mean.len(), w.mean.len());
    let Transformed { dev, d, e, mean: z_mean, cov, cross } = out;
    let (z0, x0) = (&z_pts[..r], &x_pts[..n]);
    // deviations from the first point (the centre, if any), angles wrapped
    for i in 0..k {
        for c in 0..r {
            let mut d = z_pts[i * r + c] - z0[c];
            if angles.contains(&c) {
                d = wrap_angle(d);
            }
            dev[i * r + c] = d;
        }
    }
    let first = usize::from(w.centre);
    d.fill(0.0);
    e.fill(0.0);
    for i in first..k {
        for c in 0..r {
            d[c] += w.mean[i] * dev[i * r + c];
        }
        for c in 0..n {
            e[c] += w.mean[i] * (x_pts[i * n + c] - x0[c]);
        }
    }
    if !w.centre {
        // plain sums about the mean, all weights positive: shift the deviations to the mean
        for i in 0..k {
            for c in 0..r {
                dev[i * r + c] -= d[c];
            }
        }
    }
    for c in 0..r {
        z_mean[c] = z0[c] + d[c];
    }
    cov[..r * r].fill(0.0);
    cross[..n * r].fill(0.0);
    for i in first..k {
        let wi = w.mean[i];
        let di = &dev[i * r..(i + 1) * r];
        for a in 0..r {
            for b in a..r {
                cov[a * r + b] += wi * di[a] * di[b];
            }
        }
        for a in 0..n {
            let ea = x_pts[i * n + a] - if w.centre { x0[a] } else { x0[a] + e[a] };
            for b in 0..r {
                cross[a * r + b] += wi * ea * di[b];
            }
        }
    }
    if w.centre {
        let g = w.centre_excess - 1.0;
        for a in 0..r {
            for b in a..r {
                cov[a * r + b] += g * d[a] * d[b];
            }
        }
        for a in 0..n {
            for b in 0..r {
                cross[a * r + b] += g * e[a] * d[b];
            }
        }
    }
    for a in 0..r {
        for b in 0..a {
            cov[a * r + b] = cov[b * r + a];
        }
    }
}
