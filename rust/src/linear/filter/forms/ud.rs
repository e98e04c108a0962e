//! The U-D filter: P = U D U' with U unit upper triangular and D diagonal (Bierman 1977;
//! Söderström Sec. 6.8.1, (6.115)). The measurement update is Bierman's, one
//! component (z, σ²) at a time; the time update is Thornton's modified weighted Gram–Schmidt
//! on the rows of W = [F̃ U  U_q] with weights diag(D, D_q), where Q̃ = U_q D_q U_q'. D stays
//! nonnegative by construction.

use super::{innovation_variance, not_psd, Measurement, Recursion, HALF_LOG_2PI};
use crate::core::dims::{Buf, Dims};
use crate::error::Result;

#[derive(Debug, Clone)]
pub(super) struct UD<D: Dims> {
    d: D,
    x: D::Vector,
    /// U (unit upper triangular, stored whole) and the diagonal of D.
    u: D::Square,
    diag: D::Vector,
    /// Q̃ = U_q D_q U_q'.
    q_u: D::Square,
    q_diag: D::Vector,
    /// Scratch: U' z and D U' z; the rows of W = [F̃ U  U_q].
    f: D::Vector,
    g: D::Vector,
    w_left: D::Square,
    w_right: D::Square,
}

impl<D: Dims> Recursion<D> for UD<D> {
    fn new(d: D, x0: &[f64], p0: &[f64]) -> Result<Self> {
        let n = d.n();
        let mut s = UD {
            d,
            x: d.vector(),
            u: d.square(),
            diag: d.vector(),
            q_u: d.square(),
            q_diag: d.vector(),
            f: d.vector(),
            g: d.vector(),
            w_left: d.square(),
            w_right: d.square(),
        };
        s.x.get_mut().copy_from_slice(x0);
        ud_factor(s.u.get_mut(), s.diag.get_mut(), p0, n).map_err(|_| not_psd("P0", None, "P0"))?;
        Ok(s)
    }

    #[inline(always)]
    fn x(&self) -> &[f64] {
        self.x.get()
    }

    fn covariance(&self, p: &mut [f64]) {
        let (n, u, dg) = (self.d.n(), self.u.get(), self.diag.get());
        for i in 0..n {
            for j in 0..=i {
                // Σ_k U_ik D_k U_jk over k ≥ max(i, j) = i.
                let v: f64 = (i..n).map(|k| u[i * n + k] * dg[k] * u[j * n + k]).sum();
                p[i * n + j] = v;
                p[j * n + i] = v;
            }
        }
    }

    /// Bierman's (1977) scalar measurement update.
    #[inline(always)]
    fn update(&mut self, meas: &Measurement, t: usize) -> Result<f64> {
        let n = self.d.n();
        let mut loglik = 0.0;
        for (z, target, var) in meas.components() {
            let (x, u, dg, f, g) =
                (self.x.get_mut(), self.u.get_mut(), self.diag.get_mut(), self.f.get_mut(), self.g.get_mut());
            let z = &z[..n];
            let mut v = target;
            for i in 0..n {
                v -= z[i] * x[i];
            }
            // f = U' z, g = D f.
            for j in 0..n {
                f[j] = z[j] + (0..j).map(|i| u[i * n + j] * z[i]).sum::<f64>();
                g[j] = dg[j] * f[j];
            }
            let mut alpha = var;
            for j in 0..n {
                let prev = alpha;
                alpha += f[j] * g[j];
                if alpha <= 0.0 {
                    // Nothing learned so far (σ² = 0 and f_i g_i = 0 for i ≤ j): D_j is
                    // unchanged and every g_i (i < j) is zero.
                    continue;
                }
                dg[j] *= prev / alpha;
                // prev = 0 (an exact component): every g_i (i < j) is zero, so U is unchanged.
                let lambda = if prev > 0.0 { -f[j] / prev } else { 0.0 };
                let g_j = g[j];
                for i in 0..j {
                    let u_ij = u[i * n + j];
                    u[i * n + j] = u_ij + g[i] * lambda;
                    g[i] += g_j * u_ij;
                }
            }
            if alpha.is_nan() || alpha <= 0.0 || !alpha.is_finite() {
                if alpha == 0.0 && v == 0.0 {
                    continue;
                }
                return Err(innovation_variance(t, alpha));
            }
            let inv = 1.0 / alpha;
            for i in 0..n {
                x[i] += g[i] * (v * inv);
            }
            loglik -= HALF_LOG_2PI + 0.5 * (alpha.ln() + v * v * inv);
        }
        Ok(loglik)
    }

    fn set_dynamics(&mut self, _f: &[f64], q: &[f64], t: usize) -> Result<()> {
        let n = self.d.n();
        ud_factor(self.q_u.get_mut(), self.q_diag.get_mut(), q, n)
            .map_err(|_| not_psd("Q", Some(t), "Q − N R⁻¹ N' (or Q)"))
    }

    /// Thornton's (1976) modified weighted Gram–Schmidt time update.
    #[inline(always)]
    fn predict(&mut self, f: &[f64], shift: &[f64], _t: usize) -> Result<()> {
        let n = self.d.n();
        let (x, tmp) = (self.x.get_mut(), self.f.get_mut());
        for i in 0..n {
            tmp[i] = (0..n).map(|j| f[i * n + j] * x[j]).sum::<f64>() + shift[i];
        }
        x.copy_from_slice(&tmp[..n]);
        // W = [F̃ U  U_q].
        let (u, left) = (self.u.get(), self.w_left.get_mut());
        for i in 0..n {
            for j in 0..n {
                left[i * n + j] = f[i * n + j] + (0..j).map(|k| f[i * n + k] * u[k * n + j]).sum::<f64>();
            }
        }
        self.w_right.get_mut().copy_from_slice(self.q_u.get());
        let (wl, wr) = (self.w_left.get_mut(), self.w_right.get_mut());
        let (dg, qd) = (self.diag.get(), self.q_diag.get());
        let (u, new_d) = (self.u.get_mut(), self.g.get_mut());
        u.fill(0.0);
        for k in (0..n).rev() {
            // c = D̃ w_k; d_k = w_k' D̃ w_k.
            let mut d_k = 0.0;
            for j in 0..n {
                d_k += wl[k * n + j] * wl[k * n + j] * dg[j] + wr[k * n + j] * wr[k * n + j] * qd[j];
            }
            u[k * n + k] = 1.0;
            new_d[k] = d_k.max(0.0);
            if d_k <= 0.0 {
                continue;
            }
            let inv = 1.0 / d_k;
            for i in 0..k {
                let mut s = 0.0;
                for j in 0..n {
                    s += wl[i * n + j] * wl[k * n + j] * dg[j] + wr[i * n + j] * wr[k * n + j] * qd[j];
                }
                let u_ik = s * inv;
                u[i * n + k] = u_ik;
                for j in 0..n {
                    wl[i * n + j] -= u_ik * wl[k * n + j];
                    wr[i * n + j] -= u_ik * wr[k * n + j];
                }
            }
        }
        self.diag.get_mut().copy_from_slice(&self.g.get()[..n]);
        Ok(())
    }
}

/// P = U D U' for a symmetric positive semidefinite `p`: U unit upper triangular, D ≥ 0
/// (pivots below rounding taken as zero, their columns of U zero above the diagonal); `Err(j)`
/// when pivot j is clearly negative.
fn ud_factor(u: &mut [f64], dg: &mut [f64], p: &[f64], n: usize) -> std::result::Result<(), usize> {
    let scale = (0..n).fold(0.0_f64, |s, i| s.max(p[i * n + i].abs()));
    let floor = 64.0 * n as f64 * f64::EPSILON * scale;
    u[..n * n].fill(0.0);
    for j in (0..n).rev() {
        let d = p[j * n + j] - (j + 1..n).map(|k| dg[k] * u[j * n + k] * u[j * n + k]).sum::<f64>();
        if d < -floor || d.is_nan() {
            return Err(j);
        }
        u[j * n + j] = 1.0;
        if d <= floor {
            dg[j] = 0.0;
            continue;
        }
        dg[j] = d;
        for i in 0..j {
            let s = p[i * n + j] - (j + 1..n).map(|k| dg[k] * u[i * n + k] * u[j * n + k]).sum::<f64>();
            u[i * n + j] = s / d;
        }
    }
    Ok(())
}
