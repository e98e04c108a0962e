//! The sequential (univariate) filter: P itself, updated one decorrelated scalar component at a
//! time (Söderström Sec. 6.8.1; Durbin & Koopman (2012) Sec. 6.4). For component (z, σ²):
//!
//! ```text
//! v = ỹ − z x̂     c = P z'     f = z c + σ²     x̂ ← x̂ + c v / f     P ← P − c c' / f
//! ```
//!
//! No matrix is inverted: each update divides by the scalar f. The time update is
//! P ← F̃ P F̃' + Q̃.

use super::{innovation_variance, Measurement, Recursion, HALF_LOG_2PI};
use crate::core::dense::{mul, mul_bt_sym};
use crate::core::dims::{Buf, Dims};
use crate::error::Result;

#[derive(Debug, Clone)]
pub(super) struct Sequential<D: Dims> {
    d: D,
    x: D::Vector,
    p: D::Square,
    /// P z' of the current component, and F̃ P.
    c: D::Vector,
    fp: D::Square,
    q: D::Square,
}

impl<D: Dims> Recursion<D> for Sequential<D> {
    fn new(d: D, x0: &[f64], p0: &[f64]) -> Result<Self> {
        let mut s = Sequential { d, x: d.vector(), p: d.square(), c: d.vector(), fp: d.square(), q: d.square() };
        s.x.get_mut().copy_from_slice(x0);
        s.p.get_mut().copy_from_slice(p0);
        crate::core::dense::symmetrize(s.p.get_mut(), d.n());
        Ok(s)
    }

    #[inline(always)]
    fn x(&self) -> &[f64] {
        self.x.get()
    }

    fn covariance(&self, p: &mut [f64]) {
        p.copy_from_slice(self.p.get());
    }

    #[inline(always)]
    fn update(&mut self, meas: &Measurement, t: usize) -> Result<f64> {
        let n = self.d.n();
        let mut loglik = 0.0;
        for (z, target, var) in meas.components() {
            let (x, p, c) = (self.x.get_mut(), self.p.get_mut(), self.c.get_mut());
            let z = &z[..n];
            let mut v = target;
            for i in 0..n {
                v -= z[i] * x[i];
            }
            for i in 0..n {
                c[i] = (0..n).map(|j| p[i * n + j] * z[j]).sum();
            }
            let f = var + (0..n).map(|i| z[i] * c[i]).sum::<f64>();
            if f.is_nan() || f <= 0.0 {
                // An exactly known component that P cannot move (f = 0): nothing to learn.
                if f == 0.0 && v == 0.0 {
                    continue;
                }
                return Err(innovation_variance(t, f));
            }
            let inv = 1.0 / f;
            for i in 0..n {
                x[i] += c[i] * (v * inv);
            }
            // The lower triangle, mirrored: P stays exactly symmetric.
            for i in 0..n {
                let ci = c[i] * inv;
                for j in 0..=i {
                    p[i * n + j] -= ci * c[j];
                }
            }
            for i in 0..n {
                for j in i + 1..n {
                    p[i * n + j] = p[j * n + i];
                }
            }
            loglik -= HALF_LOG_2PI + 0.5 * (f.ln() + v * v * inv);
        }
        Ok(loglik)
    }

    fn set_dynamics(&mut self, _f: &[f64], q: &[f64], _t: usize) -> Result<()> {
        self.q.get_mut().copy_from_slice(q);
        Ok(())
    }

    #[inline(always)]
    fn predict(&mut self, f: &[f64], shift: &[f64], _t: usize) -> Result<()> {
        let n = self.d.n();
        let x = self.x.get_mut();
        let c = self.c.get_mut();
        for i in 0..n {
            c[i] = (0..n).map(|j| f[i * n + j] * x[j]).sum::<f64>() + shift[i];
        }
        x.copy_from_slice(&c[..n]);
        mul::<D>(self.fp.get_mut(), f, self.p.get(), n, n, n);
        let p = self.p.get_mut();
        mul_bt_sym::<D>(p, self.fp.get(), f, n, n);
        for (p, q) in p.iter_mut().zip(&self.q.get()[..n * n]) {
            *p += q;
        }
        Ok(())
    }
}
