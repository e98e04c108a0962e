//! Sample paths of the model from given noise: the deterministic half of simulation.
//!
//! The caller draws `x[0] ~ N(x0, P0)` and the noise `(w[t], v[t]) ~ N(0, [[Q, N], [N', R]])`
//! (kfast's Python layer does so with NumPy's seeded generators); this runs the recursion
//!
//! ```text
//! y[t]   = H x[t] + D u[t] + v[t]
//! x[t+1] = F x[t] + B u[t] + w[t]
//! ```

use crate::core::dense::{mul_vec, mul_vec_add};
use crate::core::dims::Dyn;
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::model::LinearGaussian;

/// States `(T, n)` and outputs `(T, m)` driven by `w` `(T, n)`, `v` `(T, m)` and `u` `(T, k)`.
pub fn propagate(
    model: &LinearGaussian,
    x_init: &[f64],
    w: Series<'_>,
    v: Series<'_>,
    u: Option<Series<'_>>,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let (n, m, k, steps) = (model.n_states(), model.n_obs(), model.n_inputs(), w.steps());
    if x_init.len() != n {
        return Err(Error::arg("x_init", format!("expected {n} entries, got {}", x_init.len())));
    }
    if let Some(v) = x_init.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg("x_init", format!("contains a non-finite value ({v})")));
    }
    if steps == 0 {
        return Err(Error::arg("w", "has no steps (T must be ≥ 1)"));
    }
    for (arg, noise, width) in [("w", w, n), ("v", v, m)] {
        if noise.width() != width {
            return Err(Error::arg(arg, format!("expected {width} columns, got {}", noise.width())));
        }
        if noise.steps() != steps {
            return Err(Error::arg(arg, format!("has {} steps but w has {steps}", noise.steps())));
        }
        for t in 0..steps {
            if let Some(v) = noise.row(t).iter().find(|v| !v.is_finite()) {
                return Err(Error::arg_at(arg, t, format!("contains a non-finite value ({v})")));
            }
        }
    }
    if let Some(t) = model.steps() {
        if t != steps {
            return Err(Error::arg("T", format!("is {steps} but the model's per-step matrices have {t}")));
        }
    }
    crate::linear::validate::check_input_series(model, u, steps)?;
    let (mut xs, mut ys) = (vec![0.0; steps * n], vec![0.0; steps * m]);
    xs[..n].copy_from_slice(x_init);
    let mut next = vec![0.0; n];
    for t in 0..steps {
        let sys = model.at(t);
        let u_t = u.map(|u| u.row(t));
        let (x_t, y_t) = (&xs[t * n..(t + 1) * n], &mut ys[t * m..(t + 1) * m]);
        y_t.copy_from_slice(v.row(t));
        mul_vec_add::<Dyn>(y_t, sys.h, x_t, m, n);
        if let (Some(d), Some(u)) = (sys.d, u_t) {
            mul_vec_add::<Dyn>(y_t, d, u, m, k);
        }
        if t + 1 < steps {
            mul_vec::<Dyn>(&mut next, sys.f, x_t, n, n);
            for (a, wv) in next.iter_mut().zip(w.row(t)) {
                *a += wv;
            }
            if let (Some(b), Some(u)) = (sys.b, u_t) {
                mul_vec_add::<Dyn>(&mut next, b, u, n, k);
            }
            xs[(t + 1) * n..(t + 2) * n].copy_from_slice(&next);
        }
    }
    Ok((xs, ys))
}
