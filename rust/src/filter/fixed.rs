//! The filter loop for the common small sizes (compile-time n, m) on fully observed steps.
//!
//! The general step ([`super::step`]) keeps its matrices in the heap buffers of a
//! [`Workspace`]; at n = 4 a step is then bound by loads and stores through them (the
//! compiler cannot keep a matrix in registers across buffers that may alias the outputs).
//! Here the state and every intermediate are local fixed-size arrays, which the compiler
//! keeps in registers, and the model's matrices are copied once per call.
//!
//! The arithmetic is **the same, in the same order**, as [`Workspace::update`] and
//! [`Workspace::predict`] on a fully observed step (the same kernels of [`crate::dense`] run on
//! the local arrays), so results are bit-for-bit those of the general step, on which
//! `filter_batch`'s shared recursion relies. A step with a missing value, or whose S is not
//! positive definite, runs the general step instead (which reports the error).
//!
//! Used for constant models without N and without `converge_tol`; everything else runs the
//! general loop.

use super::step::{UpdateForm, Workspace, LN_2PI};
use super::{FilterOutputs, Run, StepStore};
use crate::dense::{
    ldl, ldl_log_det, ldl_solve, ldl_solve_quad, mul, mul_bt, mul_bt_sym, mul_sym, mul_vec, mul_vec_add,
};
use crate::dense::{symmetrize, transpose};
use crate::error::Result;
use crate::filter::step::Fixed;
use crate::model::StepView;

/// The constant model's matrices as local arrays (B and D stay slices: they only touch the
/// mean).
struct Model<'a, const N: usize, const M: usize> {
    f: [[f64; N]; N],
    h: [[f64; N]; M],
    q: [[f64; N]; N],
    r: [[f64; M]; M],
    b: Option<&'a [f64]>,
    d: Option<&'a [f64]>,
    k: usize,
}

fn array<const R: usize, const C: usize>(a: &[f64]) -> [[f64; C]; R] {
    let mut out = [[0.0; C]; R];
    out.as_flattened_mut().copy_from_slice(&a[..R * C]);
    out
}

/// One filter's state and intermediates, named as the [`Workspace`] fields they mirror.
#[derive(Clone, Copy)]
struct Local<const N: usize, const M: usize> {
    x_pred: [f64; N],
    p_pred: [[f64; N]; N],
    x_filt: [f64; N],
    p_filt: [[f64; N]; N],
    innov: [f64; M],
    s_full: [[f64; M]; M],
    pht: [[f64; M]; N],
    s_factor: [[f64; M]; M],
    s_inv_e: [f64; M],
    gain_t: [[f64; N]; M],
    gain: [[f64; M]; N],
    gain_pred: [[f64; M]; N],
    loglik_t: f64,
}

impl<const N: usize, const M: usize> Local<N, M> {
    fn new(ws: &Workspace) -> Self {
        let zn = [0.0; N];
        let (znn, zm, zmm, znm, zmn) = ([zn; N], [0.0; M], [[0.0; M]; M], [[0.0; M]; N], [zn; M]);
        let mut st = Local {
            x_pred: zn,
            p_pred: znn,
            x_filt: zn,
            p_filt: znn,
            innov: zm,
            s_full: zmm,
            pht: znm,
            s_factor: zmm,
            s_inv_e: zm,
            gain_t: zmn,
            gain: znm,
            gain_pred: znm,
            loglik_t: 0.0,
        };
        st.load(ws);
        st
    }

    /// Takes x̂(t|t−1), P(t|t−1) from the workspace (after a general step).
    fn load(&mut self, ws: &Workspace) {
        self.x_pred.copy_from_slice(&ws.x_pred);
        self.p_pred.as_flattened_mut().copy_from_slice(&ws.p_pred);
    }

    /// Hands x̂(t|t−1), P(t|t−1) to the workspace (before a general step, and at the end).
    fn save(&self, ws: &mut Workspace) {
        ws.x_pred.copy_from_slice(&self.x_pred);
        ws.p_pred.copy_from_slice(self.p_pred.as_flattened());
    }

    /// The measurement update with every component of `y` observed, as
    /// [`Workspace::update`]; `false` (nothing changed that matters) when S is not positive
    /// definite.
    #[inline(always)]
    fn update(
        &mut self,
        sys: &Model<'_, N, M>,
        y: &[f64],
        u: Option<&[f64]>,
        form: UpdateForm,
        want_gain: bool,
    ) -> bool {
        let (n, m) = (N, M);
        mul_vec(&mut self.innov, sys.h.as_flattened(), &self.x_pred, m, n);
        if let (Some(d), Some(u)) = (sys.d, u) {
            mul_vec_add(&mut self.innov, d, u, m, sys.k);
        }
        for (e, yi) in self.innov.iter_mut().zip(y) {
            *e = yi - *e;
        }
        let p_pred = self.p_pred.as_flattened();
        mul_bt(self.pht.as_flattened_mut(), p_pred, sys.h.as_flattened(), n, n, m);
        mul(self.s_full.as_flattened_mut(), sys.h.as_flattened(), self.pht.as_flattened(), m, n, m);
        for (s, r) in self.s_full.as_flattened_mut().iter_mut().zip(sys.r.as_flattened()) {
            *s += r;
        }
        symmetrize(self.s_full.as_flattened_mut(), m);

        self.s_factor = self.s_full;
        if ldl(self.s_factor.as_flattened_mut(), m).is_err() {
            return false;
        }
        let s_factor = self.s_factor.as_flattened();
        let log_det = ldl_log_det(s_factor, m);
        self.s_inv_e = self.innov;
        let quad = ldl_solve_quad(s_factor, &mut self.s_inv_e, m);
        self.loglik_t = -0.5 * (m as f64 * LN_2PI + log_det + quad);

        let gain_t = self.gain_t.as_flattened_mut();
        transpose(gain_t, self.pht.as_flattened(), n, m);
        ldl_solve(s_factor, gain_t, m, n);
        let gain_t = self.gain_t.as_flattened();

        self.x_filt = self.x_pred;
        mul_vec_add(&mut self.x_filt, self.pht.as_flattened(), &self.s_inv_e, n, m);

        let p_filt = self.p_filt.as_flattened_mut();
        match form {
            UpdateForm::Standard => {
                let mut ksk = [[0.0; N]; N];
                mul_sym(ksk.as_flattened_mut(), self.pht.as_flattened(), gain_t, n, m);
                for ((pf, p), ksk) in p_filt.iter_mut().zip(p_pred).zip(ksk.as_flattened()) {
                    *pf = p - ksk;
                }
            }
            UpdateForm::Joseph => {
                let mut kgain = [[0.0; M]; N];
                transpose(kgain.as_flattened_mut(), gain_t, m, n);
                let mut a = [[0.0; N]; N];
                mul(a.as_flattened_mut(), kgain.as_flattened(), sys.h.as_flattened(), n, m, n);
                for v in a.as_flattened_mut() {
                    *v = -*v;
                }
                for (i, row) in a.iter_mut().enumerate() {
                    row[i] += 1.0;
                }
                let mut ap = [[0.0; N]; N];
                mul_bt(ap.as_flattened_mut(), kgain.as_flattened(), self.pht.as_flattened(), n, m, n);
                for (v, p) in ap.as_flattened_mut().iter_mut().zip(p_pred) {
                    *v = p - *v;
                }
                mul_bt_sym(p_filt, ap.as_flattened(), a.as_flattened(), n, n);
                let mut rk = [[0.0; N]; M];
                mul(rk.as_flattened_mut(), sys.r.as_flattened(), gain_t, m, m, n);
                let mut krk = [[0.0; N]; N];
                mul_sym(krk.as_flattened_mut(), kgain.as_flattened(), rk.as_flattened(), n, m);
                for (pf, krk) in p_filt.iter_mut().zip(krk.as_flattened()) {
                    *pf += krk;
                }
            }
        }
        // P(t|t) is exactly symmetric already: P(t|t−1) is, and both forms add mirrored
        // symmetric products (mul_sym, mul_bt_sym), so no symmetrization here.
        if want_gain {
            transpose(self.gain.as_flattened_mut(), gain_t, m, n);
        }
        true
    }

    /// The time update, as [`Workspace::predict`] after a fully observed update of a model
    /// without N.
    #[inline(always)]
    fn predict(&mut self, sys: &Model<'_, N, M>, u: Option<&[f64]>, want_gain_pred: bool) {
        let (n, m) = (N, M);
        mul_vec(&mut self.x_pred, sys.f.as_flattened(), &self.x_filt, n, n);
        if let (Some(b), Some(u)) = (sys.b, u) {
            mul_vec_add(&mut self.x_pred, b, u, n, sys.k);
        }
        let mut fp = [[0.0; N]; N];
        mul(fp.as_flattened_mut(), sys.f.as_flattened(), self.p_filt.as_flattened(), n, n, n);
        mul_bt_sym(self.p_pred.as_flattened_mut(), fp.as_flattened(), sys.f.as_flattened(), n, n);
        for (p, q) in self.p_pred.as_flattened_mut().iter_mut().zip(sys.q.as_flattened()) {
            *p += q;
        }
        if want_gain_pred {
            let mut kgain = [[0.0; M]; N];
            transpose(kgain.as_flattened_mut(), self.gain_t.as_flattened(), m, n);
            mul(self.gain_pred.as_flattened_mut(), sys.f.as_flattened(), kgain.as_flattened(), n, n, m);
        }
        symmetrize(self.p_pred.as_flattened_mut(), n);
    }
}

impl Run<'_> {
    /// The filter loop on local arrays, or `None` when the model or options need the general
    /// loop (per-step matrices, N, `converge_tol`).
    #[inline(always)]
    pub(crate) fn filter_fixed<const N: usize, const M: usize>(
        &self,
        ws: &mut Workspace,
        out: &mut FilterOutputs<'_>,
    ) -> Option<Result<f64>> {
        if self.model.steps().is_some() || self.model.matrices().n.is_some() || ws.converge_tol.is_some() {
            return None;
        }
        let sys: StepView<'_> = self.model.at(0);
        let mats = Model::<N, M> {
            f: array(sys.f),
            h: array(sys.h),
            q: array(sys.q),
            r: array(sys.r),
            b: sys.b,
            d: sys.d,
            k: self.model.n_inputs(),
        };
        Some(self.fixed_loop(&mats, ws, out))
    }

    #[inline(always)]
    fn fixed_loop<const N: usize, const M: usize>(
        &self,
        mats: &Model<'_, N, M>,
        ws: &mut Workspace,
        out: &mut FilterOutputs<'_>,
    ) -> Result<f64> {
        let (want_gain, want_gain_pred) = (ws.want_gain, ws.want_gain_pred);
        let mut st = Local::<N, M>::new(ws);
        let mut total = 0.0;
        for t in 0..self.y.steps() {
            let y = self.y.row(t);
            let u_t = self.u.map(|u| u.row(t));
            StepStore::prior(out, t, &st.x_pred, st.p_pred.as_flattened());
            if !y.iter().any(|v| v.is_nan()) && st.update(mats, y, u_t, self.form, want_gain) {
                st.predict(mats, u_t, want_gain_pred);
                total += st.loglik_t;
                StepStore {
                    x_filt: &st.x_filt,
                    p_filt: st.p_filt.as_flattened(),
                    innov: &st.innov,
                    innovation_cov: st.s_full.as_flattened(),
                    gain: st.gain.as_flattened(),
                    gain_pred: st.gain_pred.as_flattened(),
                    loglik_t: st.loglik_t,
                }
                .save(out, t);
            } else {
                st.save(ws);
                self.advance(Fixed::<N, M>, ws, t)?;
                total += ws.loglik_t;
                StepStore::of(ws).save(out, t);
                st.load(ws);
            }
        }
        st.save(ws);
        Ok(total)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::step::{Dims, Dyn};
    use crate::filter::{start, FilterResult, Series};
    use crate::model::{LinearGaussian, Matrices, StepMatrix};

    /// A seeded generator of numbers in [−1, 1).
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
        fn fill(&mut self, len: usize) -> Vec<f64> {
            (0..len).map(|_| self.next()).collect()
        }
        /// A A' + I for a random A (r × r).
        fn spd(&mut self, r: usize) -> Vec<f64> {
            let a = self.fill(r * r);
            let mut s = vec![0.0; r * r];
            for i in 0..r {
                for j in 0..r {
                    s[i * r + j] = (0..r).map(|l| a[i * r + l] * a[j * r + l]).sum::<f64>() + f64::from(i == j);
                }
            }
            s
        }
    }

    fn run_with<D: Dims>(d: D, run: &Run<'_>, x0: &[f64], p0: &[f64]) -> FilterResult {
        let (n, m) = (run.model.n_states(), run.model.n_obs());
        let mut res = FilterResult::zeros(run.y.steps(), n, m);
        let mut ws = start(run.model, x0, p0);
        res.loglik = run.filter_loop(d, &mut ws, &mut res.outputs()).unwrap();
        res.x_next.copy_from_slice(&ws.x_pred);
        res
    }

    fn check<const N: usize, const M: usize>(seed: u64) {
        let (n, m, k, steps) = (N, M, 2, 60);
        let mut rng = Lcg(seed);
        let c = |r, c, v| StepMatrix::constant(r, c, v).unwrap();
        let mut mats =
            Matrices::new(c(n, n, rng.fill(n * n)), c(m, n, rng.fill(m * n)), c(n, n, rng.spd(n)), c(m, m, rng.spd(m)));
        mats.b = Some(c(n, k, rng.fill(n * k)));
        mats.d = Some(c(m, k, rng.fill(m * k)));
        let model = LinearGaussian::new(mats).unwrap();
        let mut y = rng.fill(steps * m);
        // Missing values: one component at some steps, all of them at others.
        for t in (3..steps).step_by(7) {
            y[t * m] = f64::NAN;
        }
        for t in (5..steps).step_by(11) {
            y[t * m..(t + 1) * m].fill(f64::NAN);
        }
        let u = rng.fill(steps * k);
        let (x0, p0) = (rng.fill(n), rng.spd(n));
        for form in [UpdateForm::Standard, UpdateForm::Joseph] {
            let run = Run {
                model: &model,
                y: Series::new("y", &y, steps, m).unwrap(),
                u: Some(Series::new("u", &u, steps, k).unwrap()),
                form,
            };
            let fixed = run_with(Fixed::<N, M>, &run, &x0, &p0);
            let general = run_with(Dyn { n, m }, &run, &x0, &p0);
            // Bit for bit (NaN innovations compare through their bits too).
            let bits = |r: &FilterResult| {
                [&r.x_pred, &r.p_pred, &r.x_filt, &r.p_filt, &r.innov, &r.innovation_cov, &r.gain, &r.gain_pred]
                    .iter()
                    .flat_map(|v| v.iter().map(|x| x.to_bits()))
                    .chain(r.loglik_t.iter().chain([&r.loglik]).chain(&r.x_next).map(|x| x.to_bits()))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&fixed), bits(&general), "n = {n}, m = {m}, {form:?}");
        }
    }

    #[test]
    fn fixed_loop_is_bit_identical_to_the_general_step() {
        check::<1, 1>(1);
        check::<2, 1>(2);
        check::<3, 2>(3);
        check::<4, 2>(4);
        check::<4, 4>(5);
        check::<6, 3>(6);
        check::<8, 4>(7);
    }
}
