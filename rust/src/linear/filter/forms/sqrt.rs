//! The square-root (array) filter: a lower triangular factor S with P = S S', moved only by
//! orthogonal transformations, P never formed (Söderström Sec. 6.8.1;
//! Kailath, Sayed & Hassibi (2000), the array algorithms).
//!
//! Measurement update of a component (z, σ²): Givens rotations triangularize the pre-array
//!
//! ```text
//! [ σ   z S ]        [ √f   0  ]
//! [ 0    S  ]  Θ  =  [ k̄   S⁺ ]        f = z P z' + σ²,   k = k̄ / √f,   x̂ ← x̂ + k v
//! ```
//!
//! (rotating column 0 with columns n, …, 1 keeps S⁺ lower triangular). Time update: Householder
//! reflections triangularize `[F̃ S  √Q̃] Θ = [S⁺ 0]` (an LQ factorization), √Q̃ the lower
//! Cholesky factor of Q̃ (semidefinite allowed), factored once per F̃, Q̃.

use super::{innovation_variance, not_psd, psd_cholesky, Measurement, Recursion, HALF_LOG_2PI};
use crate::core::dims::{Buf, Dims};
use crate::error::Result;

#[derive(Debug, Clone)]
pub(super) struct SquareRoot<D: Dims> {
    d: D,
    x: D::Vector,
    /// S, lower triangular with a nonnegative diagonal.
    s: D::Square,
    /// √Q̃.
    q_factor: D::Square,
    /// Scratch: k̄, z S; the pre-array [F̃ S  √Q̃].
    kbar: D::Vector,
    zs: D::Vector,
    left: D::Square,
    right: D::Square,
}

impl<D: Dims> Recursion<D> for SquareRoot<D> {
    fn new(d: D, x0: &[f64], p0: &[f64]) -> Result<Self> {
        let n = d.n();
        let mut s = SquareRoot {
            d,
            x: d.vector(),
            s: d.square(),
            q_factor: d.square(),
            kbar: d.vector(),
            zs: d.vector(),
            left: d.square(),
            right: d.square(),
        };
        s.x.get_mut().copy_from_slice(x0);
        psd_cholesky(s.s.get_mut(), p0, n).map_err(|_| not_psd("P0", None, "P0"))?;
        Ok(s)
    }

    #[inline(always)]
    fn x(&self) -> &[f64] {
        self.x.get()
    }

    fn square_root(&self) -> Option<&[f64]> {
        Some(self.s.get())
    }

    fn covariance(&self, p: &mut [f64]) {
        lower_product(self.s.get(), p, self.d.n());
    }

    #[inline(always)]
    fn update(&mut self, meas: &Measurement, t: usize) -> Result<f64> {
        let n = self.d.n();
        let mut loglik = 0.0;
        for (z, target, var) in meas.components() {
            let (x, s, kbar, zs) = (self.x.get_mut(), self.s.get_mut(), self.kbar.get_mut(), self.zs.get_mut());
            let z = &z[..n];
            let mut v = target;
            for i in 0..n {
                v -= z[i] * x[i];
            }
            // z S (S lower triangular: column j has rows j..n).
            for j in 0..n {
                zs[j] = (j..n).map(|i| z[i] * s[i * n + j]).sum();
            }
            kbar.fill(0.0);
            let mut root = var.sqrt();
            for j in (0..n).rev() {
                let a = zs[j];
                if a == 0.0 {
                    continue;
                }
                let r = root.hypot(a);
                let (c, sn) = (root / r, a / r);
                root = r;
                // Rows j..n: k̄ is still zero above row j + 1, S is zero above row j.
                for i in j..n {
                    let (k_i, s_ij) = (kbar[i], s[i * n + j]);
                    kbar[i] = c * k_i + sn * s_ij;
                    s[i * n + j] = c * s_ij - sn * k_i;
                }
            }
            let f = root * root;
            if f.is_nan() || f <= 0.0 || !f.is_finite() {
                if f == 0.0 && v == 0.0 {
                    continue;
                }
                return Err(innovation_variance(t, f));
            }
            let w = v / root;
            for i in 0..n {
                x[i] += kbar[i] * w;
            }
            positive_diagonal(s, n);
            loglik -= HALF_LOG_2PI + root.ln() + 0.5 * w * w;
        }
        Ok(loglik)
    }

    fn set_dynamics(&mut self, _f: &[f64], q: &[f64], t: usize) -> Result<()> {
        let n = self.d.n();
        psd_cholesky(self.q_factor.get_mut(), q, n).map_err(|_| not_psd("Q", Some(t), "Q − N R⁻¹ N' (or Q)"))
    }

    #[inline(always)]
    fn predict(&mut self, f: &[f64], shift: &[f64], _t: usize) -> Result<()> {
        let n = self.d.n();
        let (x, kbar) = (self.x.get_mut(), self.kbar.get_mut());
        for i in 0..n {
            kbar[i] = (0..n).map(|j| f[i * n + j] * x[j]).sum::<f64>() + shift[i];
        }
        x.copy_from_slice(&kbar[..n]);
        // F̃ S (S lower triangular).
        let (s, left) = (self.s.get(), self.left.get_mut());
        for i in 0..n {
            for j in 0..n {
                left[i * n + j] = (j..n).map(|k| f[i * n + k] * s[k * n + j]).sum();
            }
        }
        self.right.get_mut().copy_from_slice(self.q_factor.get());
        lq_lower(self.left.get_mut(), self.right.get_mut(), n, n);
        self.s.get_mut().copy_from_slice(self.left.get());
        positive_diagonal(self.s.get_mut(), n);
        Ok(())
    }
}

/// Householder reflections from the right reduce `[a b]` (`a` n × n, `b` n × w) to `[l 0]`,
/// l lower triangular, in place in `a` (`b` is zeroed).
#[inline(always)]
pub(super) fn lq_lower(a: &mut [f64], b: &mut [f64], n: usize, w: usize) {
    for i in 0..n {
        // The row's entries a[i, i..n] and b[i, ..].
        let norm2: f64 = (i..n).map(|j| a[i * n + j] * a[i * n + j]).sum::<f64>()
            + (0..w).map(|j| b[i * w + j] * b[i * w + j]).sum::<f64>();
        let tail2 = norm2 - a[i * n + i] * a[i * n + i];
        if tail2 <= 0.0 || norm2 == 0.0 {
            for j in i + 1..n {
                a[i * n + j] = 0.0;
            }
            b[i * w..][..w].fill(0.0);
            continue;
        }
        let norm = norm2.sqrt();
        let head = a[i * n + i];
        // v = row − α e_i with α = −sign(head) ‖row‖ (no cancellation); v_i = head − α.
        let alpha = if head >= 0.0 { -norm } else { norm };
        let v_i = head - alpha;
        let beta = 1.0 / (alpha * v_i); // 2 / (v'v) = −1 / (α v_i)
        for r in i + 1..n {
            let dot = a[r * n + i] * v_i
                + (i + 1..n).map(|j| a[r * n + j] * a[i * n + j]).sum::<f64>()
                + (0..w).map(|j| b[r * w + j] * b[i * w + j]).sum::<f64>();
            let scale = dot * beta;
            a[r * n + i] += scale * v_i;
            for j in i + 1..n {
                a[r * n + j] += scale * a[i * n + j];
            }
            for j in 0..w {
                b[r * w + j] += scale * b[i * w + j];
            }
        }
        a[i * n + i] = alpha;
        for j in i + 1..n {
            a[i * n + j] = 0.0;
        }
        b[i * w..][..w].fill(0.0);
    }
}

/// `p ← S S'` for a lower triangular `s` (n × n): one triangle, mirrored.
#[inline(always)]
pub(super) fn lower_product(s: &[f64], p: &mut [f64], n: usize) {
    for i in 0..n {
        for j in 0..=i {
            let v: f64 = (0..=j).map(|k| s[i * n + k] * s[j * n + k]).sum();
            p[i * n + j] = v;
            p[j * n + i] = v;
        }
    }
}

/// Flips the sign of each column of the lower triangular `s` whose diagonal is negative
/// (S S' is unchanged; the factor is then the Cholesky factor).
#[inline(always)]
pub(super) fn positive_diagonal(s: &mut [f64], n: usize) {
    for j in 0..n {
        if s[j * n + j] < 0.0 {
            for i in j..n {
                s[i * n + j] = -s[i * n + j];
            }
        }
    }
}
