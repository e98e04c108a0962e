//! The pyo3 module `kfast._kfast`: conversion between NumPy arrays and the Rust API, and
//! nothing else (no numerics here). The Python package `kfast` wraps it; arrays arrive here
//! already converted to C-contiguous float64 by `kfast._arrays.as_float64`.

use std::sync::Arc;

use numpy::ndarray::IxDyn;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyDict;

use crate::error::Error;
use crate::filter::{self, FilterOutputs, Series, UpdateForm};
use crate::model::{self, Matrices, StepMatrix};

create_exception!(
    kfast,
    KfastError,
    PyValueError,
    "Invalid input to kfast (a ValueError)."
);
create_exception!(
    kfast,
    InnovationCovarianceError,
    KfastError,
    "The innovation covariance S = H P H' + R at some step cannot be factorized."
);

impl From<Error> for PyErr {
    fn from(err: Error) -> PyErr {
        match err {
            Error::InnovationCovariance { .. } => InnovationCovarianceError::new_err(err.to_string()),
            _ => KfastError::new_err(err.to_string()),
        }
    }
}

/// Calls `kfast._arrays.as_float64(name, value)`: the one place array-likes become float64.
fn as_float64<'py>(py: Python<'py>, name: &str, value: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    static CONVERT: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    let convert = CONVERT.get_or_try_init(py, || -> PyResult<Py<PyAny>> {
        Ok(py.import("kfast._arrays")?.getattr("as_float64")?.unbind())
    })?;
    Ok(convert.bind(py).call1((name, value))?.cast_into::<PyArrayDyn<f64>>()?)
}

/// The contiguous data of a float64 array of the given ndim (`arg` names it in errors).
fn data<'a>(arg: &str, arr: &'a PyReadonlyArrayDyn<'_, f64>, ndim: usize) -> PyResult<&'a [f64]> {
    if arr.ndim() != ndim {
        return Err(KfastError::new_err(format!(
            "{arg}: expected a {ndim}-D array, got shape {:?}",
            arr.shape()
        )));
    }
    arr.as_slice()
        .map_err(|_| KfastError::new_err(format!("{arg}: array is not contiguous")))
}

/// The prior `x0` (1-D) and `P0` (2-D, n × n) as float64 slices.
fn prior<'a>(
    x0: &'a PyReadonlyArrayDyn<'_, f64>,
    p0: &'a PyReadonlyArrayDyn<'_, f64>,
    n: usize,
) -> PyResult<(&'a [f64], &'a [f64])> {
    let x0 = data("x0", x0, 1)?;
    let p0s = data("P0", p0, 2)?;
    if p0.shape() != [n, n] {
        return Err(KfastError::new_err(format!(
            "P0: expected a square ({n}, {n}) matrix (n = {n} states), got shape {:?}",
            p0.shape()
        )));
    }
    Ok((x0, p0s))
}

fn parse_form(form: &str) -> PyResult<UpdateForm> {
    match form {
        "joseph" => Ok(UpdateForm::Joseph),
        "standard" => Ok(UpdateForm::Standard),
        other => Err(KfastError::new_err(format!(
            "form: expected \"joseph\" or \"standard\", got {other:?}"
        ))),
    }
}

fn step_matrix(arg: &'static str, arr: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<StepMatrix> {
    let values = arr
        .as_slice()
        .map_err(|_| KfastError::new_err(format!("{arg}: array is not contiguous")))?;
    Ok(StepMatrix::from_shape(arg, arr.shape(), values.to_vec())?)
}

/// The compiled model; `kfast.LinearGaussian` wraps it.
#[pyclass(module = "kfast._kfast", name = "LinearGaussian", frozen)]
struct PyLinearGaussian {
    inner: Arc<model::LinearGaussian>,
}

#[pymethods]
impl PyLinearGaussian {
    #[new]
    #[pyo3(signature = (F, H, Q, R, B=None, D=None, N=None))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn new(
        F: PyReadonlyArrayDyn<'_, f64>,
        H: PyReadonlyArrayDyn<'_, f64>,
        Q: PyReadonlyArrayDyn<'_, f64>,
        R: PyReadonlyArrayDyn<'_, f64>,
        B: Option<PyReadonlyArrayDyn<'_, f64>>,
        D: Option<PyReadonlyArrayDyn<'_, f64>>,
        N: Option<PyReadonlyArrayDyn<'_, f64>>,
    ) -> PyResult<Self> {
        let opt = |arg: &'static str, a: &Option<PyReadonlyArrayDyn<'_, f64>>| {
            a.as_ref().map(|a| step_matrix(arg, a)).transpose()
        };
        let mats = Matrices {
            b: opt("B", &B)?,
            d: opt("D", &D)?,
            n: opt("N", &N)?,
            ..Matrices::new(
                step_matrix("F", &F)?,
                step_matrix("H", &H)?,
                step_matrix("Q", &Q)?,
                step_matrix("R", &R)?,
            )
        };
        Ok(PyLinearGaussian {
            inner: Arc::new(model::LinearGaussian::new(mats)?),
        })
    }

    #[getter]
    fn n_states(&self) -> usize {
        self.inner.n_states()
    }

    #[getter]
    fn n_obs(&self) -> usize {
        self.inner.n_obs()
    }

    #[getter]
    fn n_inputs(&self) -> usize {
        self.inner.n_inputs()
    }

    #[getter]
    fn steps(&self) -> Option<usize> {
        self.inner.steps()
    }

    /// Runs the filter; returns a dict of the FilterResult fields.
    #[pyo3(signature = (y, x0, P0, u=None, form="joseph"))]
    #[allow(non_snake_case)]
    fn filter<'py>(
        &self,
        py: Python<'py>,
        y: PyReadonlyArrayDyn<'py, f64>,
        x0: PyReadonlyArrayDyn<'py, f64>,
        P0: PyReadonlyArrayDyn<'py, f64>,
        u: Option<PyReadonlyArrayDyn<'py, f64>>,
        form: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let form = parse_form(form)?;
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let (n, m, steps) = (self.inner.n_states(), self.inner.n_obs(), y.steps());
        let zeros = |dims: &[usize]| PyArrayDyn::<f64>::zeros(py, IxDyn(dims), false);
        let names = [
            "x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K", "K_pred", "loglik_t", "x_next", "P_next",
        ];
        let arrays = [
            zeros(&[steps, n]),
            zeros(&[steps, n, n]),
            zeros(&[steps, n]),
            zeros(&[steps, n, n]),
            zeros(&[steps, m]),
            zeros(&[steps, m, m]),
            zeros(&[steps, n, m]),
            zeros(&[steps, n, m]),
            zeros(&[steps]),
            zeros(&[n]),
            zeros(&[n, n]),
        ];
        // SAFETY: the arrays were just created here and are not shared with Python yet.
        let mut slices: Vec<&mut [f64]> = arrays
            .iter()
            .map(|a| unsafe { a.as_slice_mut() })
            .collect::<Result<_, _>>()
            .map_err(|e| KfastError::new_err(e.to_string()))?;
        let [x_pred, p_pred, x_filt, p_filt, innov, innovation_cov, gain, gain_pred, loglik_t, x_next, p_next] =
            &mut slices[..]
        else {
            unreachable!("eleven output arrays")
        };
        let out = FilterOutputs {
            x_pred,
            p_pred,
            x_filt,
            p_filt,
            innov,
            innovation_cov,
            gain,
            gain_pred,
            loglik_t,
            x_next,
            p_next,
        };
        let model = &*self.inner;
        let loglik = py.detach(|| filter::filter_into(model, y, u, x0, p0, form, out))?;
        let dict = PyDict::new(py);
        for (name, arr) in names.iter().zip(arrays) {
            dict.set_item(name, arr)?;
        }
        dict.set_item("loglik", loglik)?;
        Ok(dict)
    }

    /// The log-likelihood alone.
    #[pyo3(signature = (y, x0, P0, u=None, form="joseph"))]
    #[allow(non_snake_case)]
    fn loglik(
        &self,
        py: Python<'_>,
        y: PyReadonlyArrayDyn<'_, f64>,
        x0: PyReadonlyArrayDyn<'_, f64>,
        P0: PyReadonlyArrayDyn<'_, f64>,
        u: Option<PyReadonlyArrayDyn<'_, f64>>,
        form: &str,
    ) -> PyResult<f64> {
        let form = parse_form(form)?;
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let model = &*self.inner;
        Ok(py.detach(|| filter::loglik(model, y, u, x0, p0, form))?)
    }
}

/// `y` (T, m) and `u` (T, k) as [`Series`].
fn series<'a>(
    y: &'a PyReadonlyArrayDyn<'_, f64>,
    u: Option<&'a PyReadonlyArrayDyn<'_, f64>>,
) -> PyResult<(Series<'a>, Option<Series<'a>>)> {
    let ys = Series::new("y", data("y", y, 2)?, y.shape()[0], y.shape()[1])?;
    let us = match u {
        Some(u) => Some(Series::new("u", data("u", u, 2)?, u.shape()[0], u.shape()[1])?),
        None => None,
    };
    Ok((ys, us))
}

/// Streaming Kalman filter: `update(y)`, `predict(u)`, `step(y, u)`; `x`, `P`.
///
/// Starts from the prior (x0, P0) = x(0|-1), P(0|-1). After `update` at step t, `x` and `P`
/// are x(t|t), P(t|t); after `predict` they are x(t+1|t), P(t+1|t). A `predict` without an
/// `update` treats the step as missing. Equals `LinearGaussian.filter` on the same data.
#[pyclass(module = "kfast._kfast", name = "KalmanFilter")]
struct PyKalmanFilter {
    inner: filter::KalmanFilter,
}

/// A vector argument as a float64 slice: float64 contiguous arrays are read in place, anything
/// else goes through `kfast._arrays.as_float64` (lists, ints, float32, scalars ...).
fn vector<'py>(py: Python<'py>, name: &str, value: &Bound<'py, PyAny>) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    if let Ok(arr) = value.cast::<PyArrayDyn<f64>>() {
        if arr.is_c_contiguous() && arr.ndim() == 1 {
            return Ok(arr.readonly());
        }
    }
    let arr = as_float64(py, name, value)?;
    let arr = if arr.ndim() == 0 {
        arr.reshape(IxDyn(&[1]))?.cast_into::<PyArrayDyn<f64>>()?
    } else {
        arr
    };
    if arr.ndim() != 1 {
        return Err(KfastError::new_err(format!(
            "{name}: expected a 1-D array, got shape {:?}",
            arr.shape()
        )));
    }
    Ok(arr.readonly())
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
        let core = match model.cast::<PyLinearGaussian>() {
            Ok(core) => core.clone(),
            Err(_) => model
                .getattr("_core")
                .and_then(|c| Ok(c.cast_into::<PyLinearGaussian>()?))
                .map_err(|_| KfastError::new_err("model: expected a kfast.LinearGaussian"))?,
        };
        let n = core.get().inner.n_states();
        let x0 = as_float64(py, "x0", x0)?;
        let p0 = as_float64(py, "P0", P0)?;
        let x0 = if n == 1 && x0.len() == 1 {
            x0.reshape(IxDyn(&[1]))?.cast_into::<PyArrayDyn<f64>>()?
        } else {
            x0
        };
        let p0 = if n == 1 && p0.len() == 1 {
            p0.reshape(IxDyn(&[1, 1]))?.cast_into::<PyArrayDyn<f64>>()?
        } else {
            p0
        };
        let (x0, p0) = (x0.readonly(), p0.readonly());
        let (x0, p0) = prior(&x0, &p0, n)?;
        let inner = filter::KalmanFilter::new(core.get().inner.clone(), x0, p0, parse_form(form)?)?;
        Ok(PyKalmanFilter { inner })
    }

    /// Measurement update with one observation y (length m; NaN = missing).
    #[pyo3(signature = (y, u=None))]
    fn update(&mut self, py: Python<'_>, y: &Bound<'_, PyAny>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let y = vector(py, "y", y)?;
        let u = u.map(|u| vector(py, "u", u)).transpose()?;
        let u = u
            .as_ref()
            .map(|u| u.as_slice())
            .transpose()
            .map_err(|e| KfastError::new_err(e.to_string()))?;
        Ok(self
            .inner
            .update(y.as_slice().map_err(|e| KfastError::new_err(e.to_string()))?, u)?)
    }

    /// Time update to the next step (u is needed when the model has B).
    #[pyo3(signature = (u=None))]
    fn predict(&mut self, py: Python<'_>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let u = u.map(|u| vector(py, "u", u)).transpose()?;
        let u = u
            .as_ref()
            .map(|u| u.as_slice())
            .transpose()
            .map_err(|e| KfastError::new_err(e.to_string()))?;
        Ok(self.inner.predict(u)?)
    }

    /// `update(y, u)` then `predict(u)`.
    #[pyo3(signature = (y, u=None))]
    fn step(&mut self, py: Python<'_>, y: &Bound<'_, PyAny>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        self.update(py, y, u)?;
        self.predict(py, u)
    }

    /// Current state estimate (a copy).
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        let n = self.inner.model().n_states();
        numpy::PyArray1::from_slice(py, self.inner.x())
            .reshape(IxDyn(&[n]))
            .expect("n entries")
    }

    /// Covariance of `x` (a copy).
    #[getter]
    #[allow(non_snake_case)]
    fn P<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.inner.model().n_states();
        numpy::PyArray1::from_slice(py, self.inner.p()).reshape(IxDyn(&[n, n]))
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

#[pymodule]
fn _kfast(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("KfastError", py.get_type::<KfastError>())?;
    m.add("InnovationCovarianceError", py.get_type::<InnovationCovarianceError>())?;
    m.add_class::<PyLinearGaussian>()?;
    m.add_class::<PyKalmanFilter>()?;
    Ok(())
}
