//! The extended and unscented RTS smoothers: a forward EKF or UKF that also stores the
//! cross-covariances `C(t) = Cov(x(t), x(t+1) | y(0..t))`, then the RTS backward pass
//! (docs/algorithms.md, "Nonlinear smoothers"):
//!
//! ```text
//! J(t)        = C(t) P(t+1|t)⁻¹        (EKF: C = P(t|t) F(t)'; UKF: the sigma points' cross-covariance, Särkkä 2008)
//! x̂(t|T−1)   = x̂(t|t) + J (x̂(t+1|T−1) − x̂(t+1|t))
//! P(t|T−1)    = P(t|t) + J (P(t+1|T−1) − P(t+1|t)) J'
//! P_lag1(t+1) = P(t+1|T−1) J(t)'        (Cov(x(t+1), x(t) | all data))
//! ```

use super::filter::{ekf_run, ukf_run, EkfOptions, UkfOptions};
use super::model::NonlinearModel;
use crate::core::dense::{ldl, ldl_solve, mul, mul_bt_sym, symmetrize, transpose};
use crate::core::dims::Dyn;
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::filter::FilterOutputs;
use crate::linear::smoother::SmoothOutputs;

/// Which filter the smoother runs forward.
#[derive(Debug, Clone)]
pub enum SmoothMethod {
    /// The EKF (extended RTS).
    Ekf(EkfOptions),
    /// The UKF with these sigma points and form (unscented RTS).
    Ukf(UkfOptions),
}

/// The smoother over the series `y` from the prior x(0|−1): the forward filter's outputs into
/// `filt` (which must hold x_pred, P_pred, x_filt and P_filt: the backward pass reads them) and
/// x(t|T−1), P(t|T−1) and the lag-one covariances into `out`; returns the log-likelihood of
/// the forward filter.
#[allow(clippy::too_many_arguments)]
pub fn smooth_nonlinear_into(
    model: &NonlinearModel,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
    method: SmoothMethod,
    mut filt: FilterOutputs<'_>,
    out: SmoothOutputs<'_>,
) -> Result<f64> {
    let (n, steps) = (model.n_states(), y.steps());
    let mut cross = vec![0.0; steps * n * n];
    let loglik = match method {
        SmoothMethod::Ekf(options) => ekf_run(model, y, u, x0, p0, options, filt.reborrow(), Some(&mut cross))?,
        SmoothMethod::Ukf(options) => ukf_run(model, y, u, x0, p0, options, filt.reborrow(), Some(&mut cross))?,
    };
    let x_pred = need("x_pred", filt.x_pred)?;
    let p_pred = need("P_pred", filt.p_pred)?;
    let x_filt = need("x_filt", filt.x_filt)?;
    let p_filt = need("P_filt", filt.p_filt)?;
    let xs = need("x_smooth", out.x_smooth)?;
    let ps = need("P_smooth", out.p_smooth)?;
    let lag1 = need("P_lag1", out.p_lag1)?;
    for (arg, buf, want) in
        [("x_smooth", &*xs, steps * n), ("P_smooth", &*ps, steps * n * n), ("P_lag1", &*lag1, steps * n * n)]
    {
        if buf.len() != want {
            return Err(Error::arg(arg, format!("output buffer has {} entries, needs {want}", buf.len())));
        }
    }
    backward(n, steps, x_pred, p_pred, x_filt, p_filt, &cross, xs, ps, lag1)?;
    Ok(loglik)
}

/// A buffer the smoother cannot do without.
fn need<'a>(arg: &'static str, buf: Option<&'a mut [f64]>) -> Result<&'a mut [f64]> {
    buf.ok_or_else(|| Error::arg(arg, "needed by the smoother"))
}

/// The RTS backward pass from the filter's outputs and the cross-covariances.
#[allow(clippy::too_many_arguments)]
fn backward(
    n: usize,
    steps: usize,
    x_pred: &[f64],
    p_pred: &[f64],
    x_filt: &[f64],
    p_filt: &[f64],
    cross: &[f64],
    xs: &mut [f64],
    ps: &mut [f64],
    lag1: &mut [f64],
) -> Result<()> {
    let nn = n * n;
    let last = steps - 1;
    xs[last * n..].copy_from_slice(&x_filt[last * n..]);
    ps[last * nn..].copy_from_slice(&p_filt[last * nn..]);
    lag1[..nn].fill(0.0);
    let (mut factor, mut gain_t, mut gain) = (vec![0.0; nn], vec![0.0; nn], vec![0.0; nn]);
    let (mut dx, mut dp, mut jdp) = (vec![0.0; n], vec![0.0; nn], vec![0.0; nn]);
    for t in (0..last).rev() {
        let (now, next) = (t * nn..(t + 1) * nn, (t + 1) * nn..(t + 2) * nn);
        // J' = P(t+1|t)⁻¹ C(t)' by the L D L' factor of P(t+1|t), never its inverse
        ldl::<Dyn>(&mut factor, &p_pred[next.clone()], n).map_err(|j| Error::NotPositiveDefinite {
            what: "P(t|t-1)",
            step: t + 1,
            problem: format!(
                "pivot {j} of its L D L' factor is not above rounding, so the smoother gain \
                 J = C P(t|t-1)^-1 is undefined (a singular Q with a rank-deficient Jacobian?)"
            ),
        })?;
        transpose(&mut gain_t, &cross[now.clone()], n, n);
        ldl_solve::<Dyn>(&factor, &mut gain_t, n, n);
        transpose(&mut gain, &gain_t, n, n);
        for i in 0..n {
            dx[i] = xs[(t + 1) * n + i] - x_pred[(t + 1) * n + i];
        }
        let x_t = &mut xs[t * n..(t + 1) * n];
        x_t.copy_from_slice(&x_filt[t * n..(t + 1) * n]);
        for i in 0..n {
            x_t[i] += gain[i * n..(i + 1) * n].iter().zip(&dx).map(|(g, d)| g * d).sum::<f64>();
        }
        for (d, (s, p)) in dp.iter_mut().zip(ps[next.clone()].iter().zip(&p_pred[next.clone()])) {
            *d = s - p;
        }
        // J (P(t+1|T−1) − P(t+1|t)) J' as one mirrored triangle
        mul::<Dyn>(&mut jdp, &gain, &dp, n, n, n);
        let (head, rest) = ps.split_at_mut((t + 1) * nn);
        mul_bt_sym::<Dyn>(&mut head[now.clone()], &jdp, &gain, n, n);
        for (s, f) in head[now.clone()].iter_mut().zip(&p_filt[now.clone()]) {
            *s += f;
        }
        symmetrize(&mut head[now], n);
        // Cov(x(t+1), x(t) | all) = P(t+1|T−1) J'
        mul::<Dyn>(&mut lag1[next], &rest[..nn], &gain_t, n, n, n);
    }
    Ok(())
}
