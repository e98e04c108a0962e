//! Streaming objects: `kfast.KalmanFilter` and `kfast.FixedLagSmoother`. Per call they check
//! only the shapes (and finiteness) of y and u.

use std::sync::Arc;

use numpy::ndarray::IxDyn;
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

use super::model::PyLinearGaussian;
use super::{as_float64, non_negative, parse_form, prior, slice, to_array, vector, KfastError};
use crate::linear::filter::{self, UpdateForm};
use crate::linear::model::LinearGaussian;
use crate::linear::smoother::FixedLagSmoother;

/// The Rust model behind `model` (a `kfast.LinearGaussian` or its compiled core), and the
/// prior as float64 vectors (scalars accepted for n = 1).
fn model_and_prior<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyAny>,
    x0: &Bound<'py, PyAny>,
    p0: &Bound<'py, PyAny>,
) -> PyResult<(Arc<LinearGaussian>, Vec<f64>, Vec<f64>)> {
    let core = match model.cast::<PyLinearGaussian>() {
        Ok(core) => core.clone(),
        Err(_) => model
            .getattr("_core")
            .and_then(|c| Ok(c.cast_into::<PyLinearGaussian>()?))
            .map_err(|_| KfastError::new_err("model: expected a kfast.LinearGaussian"))?,
    };
    let model = core.get().inner.clone();
    let n = model.n_states();
    let reshape = |a: Bound<'py, PyArrayDyn<f64>>, shape: &[usize]| -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        if n == 1 && PyUntypedArrayMethods::len(&a) == 1 {
            Ok(a.reshape(IxDyn(shape))?.cast_into::<PyArrayDyn<f64>>()?)
        } else {
            Ok(a)
        }
    };
    let x0 = reshape(as_float64(py, "x0", x0)?, &[1])?.readonly();
    let p0 = reshape(as_float64(py, "P0", p0)?, &[1, 1])?.readonly();
    let (x0, p0) = prior(&x0, &p0, n)?;
    Ok((model, x0.to_vec(), p0.to_vec()))
}

/// Runs `f` on y and u as float64 slices.
fn with_step_data<T>(
    py: Python<'_>,
    y: Option<&Bound<'_, PyAny>>,
    u: Option<&Bound<'_, PyAny>>,
    f: impl FnOnce(Option<&[f64]>, Option<&[f64]>) -> crate::Result<T>,
) -> PyResult<T> {
    let y = y.map(|y| vector(py, "y", y)).transpose()?;
    let u = u.map(|u| vector(py, "u", u)).transpose()?;
    let ys = y.as_ref().map(|y| slice("y", y)).transpose()?;
    let us = u.as_ref().map(|u| slice("u", u)).transpose()?;
    Ok(f(ys, us)?)
}

/// Streaming Kalman filter: `update(y)`, `predict(u)`, `step(y, u)`; `x`, `P`.
///
/// Starts from the prior (x0, P0) = x(0|-1), P(0|-1). After `update` at step t, `x` and `P`
/// are x(t|t), P(t|t); after `predict` they are x(t+1|t), P(t+1|t). A `predict` without an
/// `update` treats the step as missing. Equals `LinearGaussian.filter` on the same data.
#[pyclass(module = "kfast._kfast", name = "KalmanFilter")]
pub(super) struct PyKalmanFilter {
    inner: filter::KalmanFilter,
}

#[pymethods]
impl PyKalmanFilter {
    #[new]
    #[pyo3(signature = (model, x0, P0, form="joseph"))]
    #[allow(non_snake_case)]
    fn new(
        py: Python<'_>,
        model: &Bound<'_, PyAny>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        form: &str,
    ) -> PyResult<Self> {
        let form: UpdateForm = parse_form(form)?;
        let (model, x0, p0) = model_and_prior(py, model, x0, P0)?;
        Ok(PyKalmanFilter { inner: filter::KalmanFilter::new(model, &x0, &p0, form)? })
    }

    /// Measurement update with one observation y (length m; NaN = missing).
    #[pyo3(signature = (y, u=None))]
    fn update(&mut self, py: Python<'_>, y: &Bound<'_, PyAny>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, Some(y), u, |y, u| self.inner.update(y.unwrap_or_default(), u))
    }

    /// Time update to the next step (u is needed when the model has B).
    #[pyo3(signature = (u=None))]
    fn predict(&mut self, py: Python<'_>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, None, u, |_, u| self.inner.predict(u))
    }

    /// `update(y, u)` then `predict(u)`.
    #[pyo3(signature = (y, u=None))]
    fn step(&mut self, py: Python<'_>, y: &Bound<'_, PyAny>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, Some(y), u, |y, u| self.inner.step(y.unwrap_or_default(), u))
    }

    /// Current state estimate (a copy).
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        to_array(py, self.inner.x(), &[self.inner.model().n_states()])
    }

    /// Covariance of `x` (a copy).
    #[getter]
    #[allow(non_snake_case)]
    fn P<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.inner.model().n_states();
        to_array(py, self.inner.p(), &[n, n])
    }

    /// Current step (number of predicts so far).
    #[getter]
    fn t(&self) -> usize {
        self.inner.t()
    }

    /// Sum of the log-likelihood terms of the updates so far.
    #[getter]
    fn loglik(&self) -> f64 {
        self.inner.loglik()
    }
}

/// Online fixed-lag smoother: `update(y)`, `predict(u)`, `step(y, u)`.
///
/// After `update` at step t, `x_lagged`, `P_lagged` are x(t-lag|t), P(t-lag|t) (None while
/// t < lag), and `x_window`, `P_window` hold x(t-i|t) for i = 0..min(t, lag). Söderström
/// (6.58)-(6.79), structured recursion: O(lag n^3) per step.
#[pyclass(module = "kfast._kfast", name = "FixedLagSmoother")]
pub(super) struct PyFixedLagSmoother {
    inner: FixedLagSmoother,
}

#[pymethods]
impl PyFixedLagSmoother {
    #[new]
    #[pyo3(signature = (model, x0, P0, lag, form="joseph"))]
    #[allow(non_snake_case)]
    fn new(
        py: Python<'_>,
        model: &Bound<'_, PyAny>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        lag: i64,
        form: &str,
    ) -> PyResult<Self> {
        let lag = non_negative("lag", lag)?;
        let form = parse_form(form)?;
        let (model, x0, p0) = model_and_prior(py, model, x0, P0)?;
        Ok(PyFixedLagSmoother { inner: FixedLagSmoother::new(model, &x0, &p0, lag, form)? })
    }

    /// Measurement update with one observation y (length m; NaN = missing).
    #[pyo3(signature = (y, u=None))]
    fn update(&mut self, py: Python<'_>, y: &Bound<'_, PyAny>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, Some(y), u, |y, u| self.inner.update(y.unwrap_or_default(), u))
    }

    /// Time update to the next step.
    #[pyo3(signature = (u=None))]
    fn predict(&mut self, py: Python<'_>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, None, u, |_, u| self.inner.predict(u))
    }

    /// `update(y, u)` then `predict(u)`.
    #[pyo3(signature = (y, u=None))]
    fn step(&mut self, py: Python<'_>, y: &Bound<'_, PyAny>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, Some(y), u, |y, u| self.inner.step(y.unwrap_or_default(), u))
    }

    /// The lag.
    #[getter]
    fn lag(&self) -> usize {
        self.inner.lag()
    }

    /// Current step of the underlying filter.
    #[getter]
    fn t(&self) -> usize {
        self.inner.filter().t()
    }

    /// x(t-lag | t) after an update at t >= lag, else None.
    #[getter]
    fn x_lagged<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArrayDyn<f64>>>> {
        let n = self.inner.filter().model().n_states();
        self.inner.lagged().map(|(x, _)| to_array(py, x, &[n])).transpose()
    }

    /// P(t-lag | t) after an update at t >= lag, else None.
    #[getter]
    #[allow(non_snake_case)]
    fn P_lagged<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArrayDyn<f64>>>> {
        let n = self.inner.filter().model().n_states();
        self.inner.lagged().map(|(_, p)| to_array(py, p, &[n, n])).transpose()
    }

    /// x(t-i | t) for i = 0..w after an update (w <= lag + 1), shape (w, n).
    #[getter]
    fn x_window<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.inner.filter().model().n_states();
        let values: Vec<f64> = self.inner.window().flat_map(|(x, _)| x.iter().copied()).collect();
        to_array(py, &values, &[values.len() / n, n])
    }

    /// P(t-i | t) for i = 0..w after an update, shape (w, n, n).
    #[getter]
    #[allow(non_snake_case)]
    fn P_window<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.inner.filter().model().n_states();
        let values: Vec<f64> = self.inner.window().flat_map(|(_, p)| p.iter().copied()).collect();
        to_array(py, &values, &[values.len() / (n * n), n, n])
    }
}
