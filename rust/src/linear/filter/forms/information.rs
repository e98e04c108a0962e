//! The information filter: Y = P⁻¹ and ŷ = P⁻¹ x̂ (Söderström Sec. 6.8.1; Anderson & Moore (1979)
//! Sec. 6.3). A measurement adds information: for each decorrelated component (z, ỹ, σ²)
//!
//! ```text
//! Y ← Y + z' z / σ²        ŷ ← ŷ + z' ỹ / σ²
//! ```
//!
//! and the time update, with A = F̃⁻¹, M = A' Y A and Q̃ = G G' (G the lower Cholesky factor),
//!
//! ```text
//! C = G' M G + I      Y ← M − M G C⁻¹ G' M      ŷ ← (I − M G C⁻¹ G') A' ŷ + Y (B u + …)
//! ```
//!
//! so it needs F̃ invertible and R positive definite (σ² > 0). The state estimate x̂ = Y⁻¹ ŷ
//! (a Cholesky solve) is kept for the outputs and the innovations; the log-likelihood term
//! uses det S = det R · det Y(t|t) / det Y(t|t−1) and
//! e' S⁻¹ e = e' R⁻¹ e − b' Y(t|t)⁻¹ b with b = H' R⁻¹ e.
//!
//! The diffuse case P0⁻¹ = 0 comes through `P0_inf`: the exact diffuse steps (`diffuse.rs`)
//! give the outputs while Y is singular, and this recursion continues from P(d|d−1); the
//! result is the information filter run from Y0 = lim (P_* + κ P_∞)⁻¹ (docs/algorithms.md,
//! "Update forms").

use super::{not_psd, psd_cholesky, Measurement, Recursion, HALF_LOG_2PI};
use crate::core::dense::{lu_in_place, lu_solve};
use crate::core::dims::{Buf, Dims};
use crate::error::{Error, Result};

#[derive(Debug, Clone)]
pub(super) struct Information<D: Dims> {
    d: D,
    /// Y and ŷ.
    info: D::Square,
    info_vec: D::Vector,
    /// x̂ = Y⁻¹ ŷ, the lower Cholesky factor of Y, and log det Y.
    x: D::Vector,
    chol: D::Square,
    log_det: f64,
    /// A = F̃⁻¹ and G = √Q̃.
    f_inv: D::Square,
    g: D::Square,
    /// Scratch.
    m: D::Square,
    mg: D::Square,
    c: D::Square,
    b: D::Vector,
    v: D::Vector,
    piv: Vec<usize>,
}

impl<D: Dims> Information<D> {
    /// Factors Y (its Cholesky factor and log det Y) and solves x̂ = Y⁻¹ ŷ.
    fn factor(&mut self, t: usize, what: &'static str) -> Result<()> {
        let n = self.d.n();
        crate::nonlinear::cholesky(self.chol.get_mut(), self.info.get(), n).map_err(|_| {
            Error::NotPositiveDefinite {
                what,
                step: t,
                problem: "the information matrix Y = P⁻¹ is not positive definite to working precision".into(),
            }
        })?;
        let l = self.chol.get();
        self.log_det = 2.0 * (0..n).map(|i| l[i * n + i].ln()).sum::<f64>();
        let x = self.x.get_mut();
        x.copy_from_slice(self.info_vec.get());
        chol_solve(l, x, n);
        Ok(())
    }
}

impl<D: Dims> Recursion<D> for Information<D> {
    fn new(d: D, x0: &[f64], p0: &[f64]) -> Result<Self> {
        let n = d.n();
        let mut s = Information {
            d,
            info: d.square(),
            info_vec: d.vector(),
            x: d.vector(),
            chol: d.square(),
            log_det: 0.0,
            f_inv: d.square(),
            g: d.square(),
            m: d.square(),
            mg: d.square(),
            c: d.square(),
            b: d.vector(),
            v: d.vector(),
            piv: vec![0; n],
        };
        // Y0 = P0⁻¹ column by column from the Cholesky factor of P0.
        let mut l = vec![0.0; n * n];
        crate::nonlinear::cholesky(&mut l, p0, n).map_err(|_| {
            Error::arg("P0", "form=\"information\" needs P0 positive definite (P0_inf gives a diffuse start)")
        })?;
        let info = s.info.get_mut();
        for j in 0..n {
            let mut e = vec![0.0; n];
            e[j] = 1.0;
            chol_solve(&l, &mut e, n);
            for i in 0..n {
                info[i * n + j] = e[i];
            }
        }
        crate::core::dense::symmetrize(info, n);
        let (info, yv) = (s.info.get(), s.info_vec.get_mut());
        for i in 0..n {
            yv[i] = (0..n).map(|j| info[i * n + j] * x0[j]).sum();
        }
        s.factor(0, "P(t|t-1)")?;
        Ok(s)
    }

    #[inline(always)]
    fn x(&self) -> &[f64] {
        self.x.get()
    }

    /// P = Y⁻¹ = L'⁻¹ L⁻¹ in place: L⁻¹ in the lower triangle of `p`, then the products.
    fn covariance(&self, p: &mut [f64]) {
        let (n, l) = (self.d.n(), self.chol.get());
        for j in 0..n {
            p[j * n + j] = 1.0 / l[j * n + j];
            for i in j + 1..n {
                let s: f64 = (j..i).map(|k| l[i * n + k] * p[k * n + j]).sum();
                p[i * n + j] = -s / l[i * n + i];
            }
        }
        // P_ij = Σ_{k ≥ j} L⁻¹_ki L⁻¹_kj: the strict upper triangle first (it reads only the
        // lower one), then the diagonal (each reads only its own column), then the mirror.
        for i in 0..n {
            for j in i + 1..n {
                p[i * n + j] = (j..n).map(|k| p[k * n + i] * p[k * n + j]).sum();
            }
        }
        for i in 0..n {
            p[i * n + i] = (i..n).map(|k| p[k * n + i] * p[k * n + i]).sum();
        }
        for i in 0..n {
            for j in 0..i {
                p[i * n + j] = p[j * n + i];
            }
        }
    }

    #[inline(always)]
    fn update(&mut self, meas: &Measurement, t: usize) -> Result<f64> {
        let n = self.d.n();
        let log_det_pred = self.log_det;
        let (mut quad, mut log_det_r) = (0.0, 0.0);
        self.b.get_mut().fill(0.0);
        for (z, target, var) in meas.components() {
            if var.is_nan() || var <= 0.0 {
                return Err(Error::arg_at("R", t, "form=\"information\" needs R positive definite"));
            }
            let z = &z[..n];
            let inv = 1.0 / var;
            let e = target - (0..n).map(|i| z[i] * self.x.get()[i]).sum::<f64>();
            let (info, yv, b) = (self.info.get_mut(), self.info_vec.get_mut(), self.b.get_mut());
            for i in 0..n {
                let zi = z[i] * inv;
                for j in 0..n {
                    info[i * n + j] += zi * z[j];
                }
                yv[i] += zi * target;
                b[i] += zi * e;
            }
            quad += e * e * inv;
            log_det_r += var.ln();
        }
        self.factor(t, "P(t|t)")?;
        // b' Y(t|t)⁻¹ b.
        let v = self.v.get_mut();
        v.copy_from_slice(self.b.get());
        chol_solve(self.chol.get(), v, n);
        quad -= (0..n).map(|i| self.b.get()[i] * v[i]).sum::<f64>();
        let mo = meas.mo as f64;
        Ok(-(mo * HALF_LOG_2PI) - 0.5 * (log_det_r + self.log_det - log_det_pred + quad))
    }

    fn set_dynamics(&mut self, f: &[f64], q: &[f64], t: usize) -> Result<()> {
        let n = self.d.n();
        let lu = self.c.get_mut();
        lu.copy_from_slice(f);
        lu_in_place(lu, &mut self.piv, n);
        let scale = f.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
        let smallest = (0..n).fold(f64::INFINITY, |s, k| s.min(lu[k * n + k].abs()));
        if smallest.is_nan() || smallest <= 1e3 * n as f64 * f64::EPSILON * scale {
            return Err(Error::arg_at(
                "F",
                t,
                "form=\"information\" needs F (F − N R⁻¹ H with N) invertible: the time update maps Y through F⁻¹",
            ));
        }
        let a = self.f_inv.get_mut();
        a.fill(0.0);
        for i in 0..n {
            a[i * n + i] = 1.0;
        }
        lu_solve(self.c.get(), &self.piv, a, n, n);
        psd_cholesky(self.g.get_mut(), q, n).map_err(|_| not_psd("Q", Some(t), "Q − N R⁻¹ N' (or Q)"))
    }

    #[inline(always)]
    fn predict(&mut self, _f: &[f64], shift: &[f64], t: usize) -> Result<()> {
        let n = self.d.n();
        let (a, g) = (self.f_inv.get(), self.g.get());
        // M = A' Y A (via mg = Y A as scratch), and v = A' ŷ.
        {
            let (info, ya) = (self.info.get(), self.mg.get_mut());
            for i in 0..n {
                for j in 0..n {
                    ya[i * n + j] = (0..n).map(|k| info[i * n + k] * a[k * n + j]).sum();
                }
            }
            let m = self.m.get_mut();
            for i in 0..n {
                for j in 0..=i {
                    let v: f64 = (0..n).map(|k| a[k * n + i] * ya[k * n + j]).sum();
                    m[i * n + j] = v;
                    m[j * n + i] = v;
                }
            }
            let (yv, v) = (self.info_vec.get(), self.v.get_mut());
            for i in 0..n {
                v[i] = (0..n).map(|k| a[k * n + i] * yv[k]).sum();
            }
        }
        // MG and C = G' M G + I, factored.
        let (m, mg) = (self.m.get(), self.mg.get_mut());
        for i in 0..n {
            for j in 0..n {
                mg[i * n + j] = (j..n).map(|k| m[i * n + k] * g[k * n + j]).sum();
            }
        }
        let c = self.c.get_mut();
        for i in 0..n {
            for j in 0..=i {
                let v: f64 = (i..n).map(|k| g[k * n + i] * mg[k * n + j]).sum::<f64>() + if i == j { 1.0 } else { 0.0 };
                c[i * n + j] = v;
                c[j * n + i] = v;
            }
        }
        let chol = self.chol.get_mut();
        crate::nonlinear::cholesky(chol, self.c.get(), n).map_err(|_| Error::NotPositiveDefinite {
            what: "P(t|t-1)",
            step: t,
            problem: "G' M G + I of the information time update is not positive definite".into(),
        })?;
        // Y ← M − MG C⁻¹ (MG)';  ŷ ← v − MG C⁻¹ G' v + Y shift.
        let (mg, chol) = (self.mg.get(), self.chol.get());
        let info = self.info.get_mut();
        let b = self.b.get_mut();
        // b = C⁻¹ G' v.
        let v = self.v.get();
        for j in 0..n {
            b[j] = (j..n).map(|k| g[k * n + j] * v[k]).sum();
        }
        chol_solve(chol, b, n);
        let yv = self.info_vec.get_mut();
        for i in 0..n {
            yv[i] = v[i] - (0..n).map(|j| mg[i * n + j] * b[j]).sum::<f64>();
        }
        // Rows of MG C⁻¹ one at a time: w = C⁻¹ (MG)'_i.
        let w = self.x.get_mut();
        for i in 0..n {
            w.copy_from_slice(&mg[i * n..][..n]);
            chol_solve(chol, w, n);
            for j in 0..=i {
                let v: f64 = m[i * n + j] - (0..n).map(|k| mg[j * n + k] * w[k]).sum::<f64>();
                info[i * n + j] = v;
                info[j * n + i] = v;
            }
        }
        for i in 0..n {
            yv[i] += (0..n).map(|j| info[i * n + j] * shift[j]).sum::<f64>();
        }
        self.factor(t, "P(t|t-1)")
    }
}

/// `b ← (L L')⁻¹ b` for a vector b, L lower triangular.
#[inline(always)]
fn chol_solve(l: &[f64], b: &mut [f64], n: usize) {
    for i in 0..n {
        let s: f64 = (0..i).map(|k| l[i * n + k] * b[k]).sum();
        b[i] = (b[i] - s) / l[i * n + i];
    }
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|k| l[k * n + i] * b[k]).sum();
        b[i] = (b[i] - s) / l[i * n + i];
    }
}
