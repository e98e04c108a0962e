//! Validation of data, inputs and options against a linear model: once per call, before the
//! time loop (the model's own matrices are validated by [`LinearGaussian::new`]).

use crate::core::validate::{check_input_row, check_observations, check_prior};
use crate::core::Series;
use crate::error::{Error, Result};
use crate::linear::model::LinearGaussian;

pub(crate) fn check_converge_tol(model: &LinearGaussian, tol: Option<f64>) -> Result<Option<f64>> {
    match tol {
        Some(t) if t.is_nan() || t < 0.0 => Err(Error::arg("converge_tol", format!("must be ≥ 0, got {t}"))),
        Some(_) if model.steps().is_some() => {
            Err(Error::arg("converge_tol", "needs constant model matrices (this model has per-step ones)"))
        }
        other => Ok(other),
    }
}

/// Validates data and prior against the model; returns T.
pub(crate) fn check_data(
    model: &LinearGaussian,
    y: Series<'_>,
    u: Option<Series<'_>>,
    x0: &[f64],
    p0: &[f64],
) -> Result<usize> {
    let steps = check_series(model, y, u)?;
    check_prior(model.n_states(), x0, p0).map(|_| steps)
}

/// Validates the data and inputs of one series against the model; returns T.
pub(crate) fn check_series(model: &LinearGaussian, y: Series<'_>, u: Option<Series<'_>>) -> Result<usize> {
    let steps = check_observations(y, model.n_obs(), model.steps())?;
    check_input_series(model, u, steps)?;
    Ok(steps)
}

pub(crate) fn check_input_series(model: &LinearGaussian, u: Option<Series<'_>>, steps: usize) -> Result<()> {
    match u {
        Some(u) => {
            check_input_width(model, u.width())?;
            if u.steps() != steps {
                return Err(Error::arg("u", format!("has {} steps but y has {steps}", u.steps())));
            }
            for t in 0..steps {
                check_input_row(u.row(t), Some(t))?;
            }
            Ok(())
        }
        None if model.has_input() => Err(Error::arg(
            "u",
            format!(
                "the model has B or D with k = {} inputs, so u of shape (T, {}) is required",
                model.n_inputs(),
                model.n_inputs()
            ),
        )),
        None => Ok(()),
    }
}

pub(crate) fn check_input_width(model: &LinearGaussian, width: usize) -> Result<()> {
    let k = model.n_inputs();
    if k == 0 {
        return Err(Error::arg("u", "given, but the model has neither B nor D"));
    }
    if width != k {
        return Err(Error::arg("u", format!("expected {k} inputs per step (B/D have k = {k} columns), got {width}")));
    }
    Ok(())
}
