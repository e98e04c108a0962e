//! k-step forecasts of the state and the output (Söderström (6.38)–(6.42); docs/algorithms.md, "Forecasting").
//!
//! Start from a one-step prediction `(x, P) = x̂(t|t−1), P(t|t−1)` (e.g. the filter's
//! `x_next, P_next`); row j of the result is the forecast of step t + j, j = 0..steps:
//!
//! ```text
//! x̂(t+j+1|t−1) = F x̂(t+j|t−1) + B u(t+j)       P(t+j+1|t−1) = F P F' + Q
//! ŷ(t+j|t−1)   = H x̂(t+j|t−1) + D u(t+j)       cov = H P H' + R
//! ```
//!
//! No data enter after the start, so N plays no part. Only constant models can be forecast
//! (per-step matrices cover only the data).

use crate::core::alloc::check_f64_arrays;
use crate::core::dense::{mul, mul_bt, mul_vec, mul_vec_add, symmetrize};
use crate::core::dims::Dyn;
use crate::core::validate::check_prior;
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::model::LinearGaussian;

/// Forecast means and covariances, row-major.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Forecast {
    /// State means, `(steps, n)`.
    pub x: Vec<f64>,
    /// State covariances, `(steps, n, n)`.
    pub p: Vec<f64>,
    /// Output means, `(steps, m)`.
    pub y: Vec<f64>,
    /// Output covariances `H P H' + R`, `(steps, m, m)`.
    pub y_cov: Vec<f64>,
}

/// Forecasts `steps` steps from the one-step prediction `(x, p)`; `u` is `(steps, k)`.
pub fn forecast(model: &LinearGaussian, x: &[f64], p: &[f64], steps: usize, u: Option<Series<'_>>) -> Result<Forecast> {
    let (n, m, k) = (model.n_states(), model.n_obs(), model.n_inputs());
    if let Some(t) = model.steps() {
        return Err(Error::arg(
            "model",
            format!("forecasting needs constant matrices; this model's per-step matrices cover only its {t} steps"),
        ));
    }
    check_prior(n, x, p).map_err(|e| match e {
        Error::InvalidArgument { arg: "x0", step, problem } => Error::InvalidArgument { arg: "x", step, problem },
        Error::InvalidArgument { arg: "P0", step, problem } => Error::InvalidArgument { arg: "P", step, problem },
        other => other,
    })?;
    crate::linear::validate::check_input_series(model, u, steps)?;
    check_f64_arrays("steps", &[&[steps, n], &[steps, n, n], &[steps, m], &[steps, m, m]])?;
    let sys = model.at(0);
    let mut out = Forecast {
        x: vec![0.0; steps * n],
        p: vec![0.0; steps * n * n],
        y: vec![0.0; steps * m],
        y_cov: vec![0.0; steps * m * m],
    };
    let (mut xc, mut pc) = (x.to_vec(), p.to_vec());
    let (mut tmp_n, mut tmp_nn, mut tmp_nm) = (vec![0.0; n], vec![0.0; n * n], vec![0.0; n * m]);
    for j in 0..steps {
        let u_j = u.map(|u| u.row(j));
        out.x[j * n..(j + 1) * n].copy_from_slice(&xc);
        out.p[j * n * n..(j + 1) * n * n].copy_from_slice(&pc);
        let yj = &mut out.y[j * m..(j + 1) * m];
        mul_vec::<Dyn>(yj, sys.h, &xc, m, n);
        if let (Some(d), Some(u)) = (sys.d, u_j) {
            mul_vec_add::<Dyn>(yj, d, u, m, k);
        }
        let sj = &mut out.y_cov[j * m * m..(j + 1) * m * m];
        mul_bt::<Dyn>(&mut tmp_nm, &pc, sys.h, n, n, m);
        mul::<Dyn>(sj, sys.h, &tmp_nm, m, n, m);
        for (s, r) in sj.iter_mut().zip(sys.r) {
            *s += r;
        }
        symmetrize(sj, m);
        mul_vec::<Dyn>(&mut tmp_n, sys.f, &xc, n, n);
        if let (Some(b), Some(u)) = (sys.b, u_j) {
            mul_vec_add::<Dyn>(&mut tmp_n, b, u, n, k);
        }
        xc.copy_from_slice(&tmp_n);
        mul::<Dyn>(&mut tmp_nn, sys.f, &pc, n, n, n);
        mul_bt::<Dyn>(&mut pc, &tmp_nn, sys.f, n, n, n);
        for (pv, q) in pc.iter_mut().zip(sys.q) {
            *pv += q;
        }
        symmetrize(&mut pc, n);
    }
    Ok(out)
}
