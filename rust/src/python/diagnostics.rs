//! Bindings of `linear::diagnostics`: the tests of a filter run, returned as dicts of arrays
//! for `kfast.linear.diagnostics.Diagnostics`.

use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::{data, KfastError};
use crate::linear::diagnostics::{self, DiagnosticOptions};

type Array<'py> = PyReadonlyArrayDyn<'py, f64>;

/// `innovation_diagnostics(innov (T, m), S (T, m, m), lags, burn, alpha)` -> dict of the
/// fields of `InnovationDiagnostics`.
#[pyfunction]
pub(super) fn innovation_diagnostics<'py>(
    py: Python<'py>,
    innov: Array<'py>,
    s: Array<'py>,
    lags: usize,
    burn: usize,
    alpha: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let values = data("innov", &innov, 2)?;
    let (steps, m) = (innov.shape()[0], innov.shape()[1]);
    if s.shape() != [steps, m, m] {
        return Err(KfastError::new_err(format!("S: expected shape ({steps}, {m}, {m}), got {:?}", s.shape())));
    }
    let covs = data("S", &s, 3)?;
    let options = DiagnosticOptions { lags, burn, alpha };
    let out = py.detach(|| diagnostics::innovation_diagnostics(values, covs, steps, m, options))?;
    let dict = PyDict::new(py);
    dict.set_item("standardized_innov", out.standardized.into_pyarray(py).reshape([steps, m])?)?;
    dict.set_item("nis", out.nis.into_pyarray(py))?;
    dict.set_item("nis_dof", out.observed.into_pyarray(py))?;
    dict.set_item("nis_bounds", out.nis_bounds.into_pyarray(py).reshape([steps, 2])?)?;
    dict.set_item("nis_mean", out.nis_mean)?;
    dict.set_item("nis_mean_bounds", out.nis_mean_bounds.to_vec().into_pyarray(py))?;
    dict.set_item("acf", out.acf.into_pyarray(py).reshape([lags + 1, m])?)?;
    dict.set_item("acf_bound", out.acf_bound.into_pyarray(py))?;
    dict.set_item("ljung_box", out.ljung_box.into_pyarray(py).reshape([lags, m])?)?;
    dict.set_item("ljung_box_pvalue", out.ljung_box_pvalue.into_pyarray(py).reshape([lags, m])?)?;
    dict.set_item("jarque_bera", out.jarque_bera.into_pyarray(py))?;
    dict.set_item("jarque_bera_pvalue", out.jarque_bera_pvalue.into_pyarray(py))?;
    dict.set_item("skew", out.skew.into_pyarray(py))?;
    dict.set_item("kurtosis", out.kurtosis.into_pyarray(py))?;
    Ok(dict)
}

/// `state_diagnostics(x_true (T, n), x_filt (T, n), P_filt (T, n, n), burn, alpha)` -> dict of
/// the fields of `StateDiagnostics`.
#[pyfunction]
pub(super) fn state_diagnostics<'py>(
    py: Python<'py>,
    x_true: Array<'py>,
    x_filt: Array<'py>,
    p_filt: Array<'py>,
    burn: usize,
    alpha: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let estimates = data("x_filt", &x_filt, 2)?;
    let (steps, n) = (x_filt.shape()[0], x_filt.shape()[1]);
    if x_true.shape() != [steps, n] {
        return Err(KfastError::new_err(format!(
            "x_true: expected shape ({steps}, {n}) like x_filt, got {:?}",
            x_true.shape()
        )));
    }
    if p_filt.shape() != [steps, n, n] {
        return Err(KfastError::new_err(format!(
            "P_filt: expected shape ({steps}, {n}, {n}), got {:?}",
            p_filt.shape()
        )));
    }
    let (truth, covs) = (data("x_true", &x_true, 2)?, data("P_filt", &p_filt, 3)?);
    let options = DiagnosticOptions { lags: 1, burn, alpha };
    let out = py.detach(|| diagnostics::state_diagnostics(truth, estimates, covs, steps, n, options))?;
    let dict = PyDict::new(py);
    dict.set_item("nees", out.nees.into_pyarray(py))?;
    dict.set_item("nees_bounds", out.nees_bounds.to_vec().into_pyarray(py))?;
    dict.set_item("nees_mean", out.nees_mean)?;
    dict.set_item("nees_mean_bounds", out.nees_mean_bounds.to_vec().into_pyarray(py))?;
    Ok(dict)
}

/// `chi_square(x_or_p, k, quantile)`: the upper tail `P(χ²(k) > x)`, or with `quantile=True`
/// the p-quantile.
#[pyfunction]
pub(super) fn chi_square(value: f64, k: f64, quantile: bool) -> PyResult<f64> {
    if !(k > 0.0 && k.is_finite()) {
        return Err(KfastError::new_err(format!("k: degrees of freedom must be positive and finite, got {k}")));
    }
    if quantile {
        Ok(diagnostics::chi_square_quantile(value, k)?)
    } else {
        Ok(diagnostics::chi_square_sf(value, k))
    }
}
