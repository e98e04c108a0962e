//! Streaming objects: `kfast.KalmanFilter` and `kfast.FixedLagSmoother`. Per call they check
//! only the shapes (and finiteness) of y and u.

use std::sync::Arc;

use numpy::ndarray::IxDyn;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple, PyType};

use super::model::PyLinearGaussian;
use super::{as_float64, data, form_arg, index_arg, prior, slice, to_array, vector, KfastError};
use crate::core::gaussian::LoglikSum;
use crate::linear::filter::{self, KalmanFilter, UpdateForm};
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

/// What pickling needs besides the Rust state: the constructor's model object (and its
/// compiled model) and prior.
struct Origin {
    model: Py<PyAny>,
    core: Arc<LinearGaussian>,
    x0: Vec<f64>,
    p0: Vec<f64>,
}

impl Origin {
    /// The constructor's first arguments: (model, x0, P0).
    fn args<'py>(&self, py: Python<'py>) -> PyResult<[Bound<'py, PyAny>; 3]> {
        let n = self.x0.len();
        Ok([
            self.model.bind(py).clone(),
            to_array(py, &self.x0, &[n])?.into_any(),
            to_array(py, &self.p0, &[n, n])?.into_any(),
        ])
    }
}

fn form_name(form: UpdateForm) -> &'static str {
    super::FORMS.iter().find(|(_, f)| *f == form).map_or("joseph", |(name, _)| name)
}

/// An optional vector kept in a buffer reused from step to step.
#[derive(Default)]
struct Kept {
    values: Vec<f64>,
    given: bool,
}

impl Kept {
    fn set(&mut self, values: Option<&[f64]>) {
        self.values.clear();
        self.values.extend_from_slice(values.unwrap_or_default());
        self.given = values.is_some();
    }

    fn get(&self) -> Option<&[f64]> {
        self.given.then_some(self.values.as_slice())
    }
}

/// The data of the update made at the current step (y, u and the step's own H and R), so
/// that unpickling can replay it: recomputing the update's by-products that the time update
/// reads gives the same bits and needs no export of the filter's internals.
#[derive(Default)]
struct StepData {
    y: Kept,
    u: Kept,
    h: Kept,
    r: Kept,
    loglik_before: LoglikSum,
}

/// `kf.update_with(y, u, h, r)`, recording the data for pickling.
fn update_recorded(
    kf: &mut KalmanFilter,
    last: &mut StepData,
    y: &[f64],
    u: Option<&[f64]>,
    h: Option<&[f64]>,
    r: Option<&[f64]>,
) -> crate::Result<()> {
    let before = kf.loglik_sum();
    kf.update_with(y, u, h, r)?;
    last.y.set(Some(y));
    last.u.set(u);
    last.h.set(h);
    last.r.set(r);
    last.loglik_before = before;
    Ok(())
}

/// `H` (m × n) or `R` (m × m) given for one update at step t: a float64 array of that shape
/// (a scalar for a 1 × 1 matrix).
fn step_matrix<'py>(
    py: Python<'py>,
    arg: &str,
    value: Option<&Bound<'py, PyAny>>,
    shape: [usize; 2],
    t: usize,
) -> PyResult<Option<PyReadonlyArrayDyn<'py, f64>>> {
    let Some(value) = value else { return Ok(None) };
    let arr = as_float64(py, arg, value)?;
    if arr.shape() != shape && !(arr.ndim() == 0 && shape == [1, 1]) {
        let got: Vec<String> = arr.shape().iter().map(|d| d.to_string()).collect();
        return Err(KfastError::new_err(format!(
            "{arg} at step {t}: expected shape ({}, {}), got ({})",
            shape[0],
            shape[1],
            got.join(", ")
        )));
    }
    Ok(Some(arr.readonly()))
}

/// The data of a [`step_matrix`].
fn matrix_data<'a>(arg: &str, arr: &'a Option<PyReadonlyArrayDyn<'_, f64>>) -> PyResult<Option<&'a [f64]>> {
    arr.as_ref().map(|a| a.as_slice().map_err(|_| KfastError::new_err(format!("{arg}: not contiguous")))).transpose()
}

/// The filter's state for pickling: the step t, the prediction x(t|t-1), P(t|t-1), the
/// log-likelihood before the update at t and, if it was made, that update's data.
fn filter_state<'py>(py: Python<'py>, kf: &KalmanFilter, last: &StepData) -> PyResult<Bound<'py, PyDict>> {
    let n = kf.model().n_states();
    let (x_pred, p_pred) = kf.prediction();
    let state = PyDict::new(py);
    state.set_item("t", kf.t())?;
    state.set_item("x_pred", to_array(py, x_pred, &[n])?)?;
    state.set_item("P_pred", to_array(py, p_pred, &[n, n])?)?;
    let loglik_before = if kf.is_updated() { last.loglik_before } else { kf.loglik_sum() };
    // The total, and the running sum it is taken from (which continues bit for bit).
    state.set_item("loglik", loglik_before.total())?;
    state.set_item("loglik_sum", loglik_before.parts().to_vec())?;
    if kf.is_updated() {
        let m = kf.model().n_obs();
        let update = PyDict::new(py);
        update.set_item("y", to_array(py, &last.y.values, &[m])?)?;
        let shapes =
            [("u", &last.u, vec![last.u.values.len()]), ("H", &last.h, vec![m, n]), ("R", &last.r, vec![m, m])];
        for (key, kept, shape) in shapes {
            update.set_item(key, kept.get().map(|v| to_array(py, v, &shape)).transpose()?)?;
        }
        state.set_item("update", update)?;
    } else {
        state.set_item("update", py.None())?;
    }
    Ok(state)
}

fn item<'py>(state: &Bound<'py, PyDict>, key: &str) -> PyResult<Bound<'py, PyAny>> {
    state
        .get_item(key)?
        .ok_or_else(|| KfastError::new_err(format!("state: has no {key:?} entry (not a pickled kfast filter?)")))
}

/// A float64 array of any shape, read as one contiguous slice.
fn flat<'py>(py: Python<'py>, name: &str, value: &Bound<'py, PyAny>) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    Ok(as_float64(py, name, value)?.readonly())
}

/// The filter of [`filter_state`]'s `state` with the `model` and `form` it was made with, and
/// the data of its update at the current step, which it replays.
fn resume_filter(
    py: Python<'_>,
    model: &Arc<LinearGaussian>,
    form: UpdateForm,
    state: &Bound<'_, PyDict>,
) -> PyResult<(KalmanFilter, StepData)> {
    let t: usize = item(state, "t")?.extract()?;
    let loglik = match state.get_item("loglik_sum")? {
        Some(parts) => LoglikSum::from_parts(parts.extract()?)
            .ok_or_else(|| KfastError::new_err("state: \"loglik_sum\" is not a log-likelihood sum"))?,
        // A state without it (pickled by kfast before 2026-12-02): continue from the total.
        None => LoglikSum::carrying(item(state, "loglik")?.extract()?),
    };
    let x_pred = vector(py, "x_pred", &item(state, "x_pred")?)?;
    let p_pred = flat(py, "P_pred", &item(state, "P_pred")?)?;
    let p_pred = data("P_pred", &p_pred, 2)?;
    let mut kf = KalmanFilter::resume(model.clone(), slice("x_pred", &x_pred)?, p_pred, form, t, loglik)?;
    let mut last = StepData::default();
    let update = item(state, "update")?;
    if !update.is_none() {
        let update = update.cast_into::<PyDict>()?;
        let given = |key: &str| -> PyResult<Option<Bound<'_, PyAny>>> {
            let value = item(&update, key)?;
            Ok((!value.is_none()).then_some(value))
        };
        let (m, n) = (kf.model().n_obs(), kf.model().n_states());
        let h = step_matrix(py, "H", given("H")?.as_ref(), [m, n], t)?;
        let r = step_matrix(py, "R", given("R")?.as_ref(), [m, m], t)?;
        let (h, r) = (matrix_data("H", &h)?, matrix_data("R", &r)?);
        with_step_data(py, Some(&item(&update, "y")?), given("u")?.as_ref(), |y, u| {
            update_recorded(&mut kf, &mut last, y.unwrap_or_default(), u, h, r)
        })?;
    }
    Ok((kf, last))
}

/// Streaming Kalman filter: ``update(y)``, ``predict(u)``, ``step(y, u)``; ``x``, ``P``.
///
/// Starts from the prior (x0, P0) = x(0|-1), P(0|-1). After ``update`` at step t, ``x`` and
/// ``P`` are x(t|t), P(t|t); after ``predict`` they are x(t+1|t), P(t+1|t). A ``predict``
/// without an ``update`` treats the step as missing. The results equal
/// ``LinearGaussian.filter`` on the same data. Pickles (and copies) with its model; the copy
/// continues the stream bit for bit (a robust form's pickle to rounding).
///
/// Threads: each call (``update``, ``predict``, ``step``, reading ``x``) runs whole, holding
/// the GIL, so concurrent calls never corrupt the filter. But a stream is one sequence of
/// calls: threads that share a filter interleave their updates and predictions (an error says
/// so when two updates meet). Give each thread its own filter, use ``step`` (one call per
/// observation), or hold a lock around each update/predict pair.
///
/// Parameters
/// ----------
/// model : LinearGaussian
///     The model; per-step matrices are used in turn.
/// x0 : array_like, shape (n,)
///     Prior mean x(0|-1) (a scalar when n = 1).
/// P0 : array_like, shape (n, n)
///     Prior covariance P(0|-1), symmetric positive semidefinite.
/// form : {"joseph", "standard", "sqrt", "ud", "information", "sequential"}
///     The update form, as in ``LinearGaussian.filter`` (a robust form pickles with its
///     prediction refactored: the copy continues equal to rounding).
///
/// Raises
/// ------
/// KfastError
///     For a model that is not a ``kfast.LinearGaussian``, or an invalid prior.
///
/// Notes
/// -----
/// Söderström Lemma 6.1, (6.22)-(6.27), one step at a time: ``update`` computes
/// e = y - H x - D u, S = H P H' + R, K = P H' S^-1, x(t|t) = x(t|t-1) + K e and P(t|t);
/// ``predict`` computes x(t+1|t) = F x(t|t) + B u + N S^-1 e and P(t+1|t).
///
/// Examples
/// --------
/// >>> model = kfast.LinearGaussian(F=0.8, H=1.0, Q=0.68, R=1.0)
/// >>> kf = kfast.KalmanFilter(model, x0=0.0, P0=1.0)
/// >>> for y in [0.3, -0.1, 0.7]:
/// ...     kf.update(y)  # x, P are now x(t|t), P(t|t)
/// ...     kf.predict()  # and now x(t+1|t), P(t+1|t)
/// >>> print(kf.x.round(4), kf.t)
/// [0.2832] 3
/// >>> bool(kf.loglik == model.loglik([0.3, -0.1, 0.7], 0.0, 1.0))
/// True
#[pyclass(module = "kfast._kfast", name = "KalmanFilter")]
pub(super) struct PyKalmanFilter {
    pub(super) inner: filter::KalmanFilter,
    origin: Origin,
    last: StepData,
}

#[pymethods]
impl PyKalmanFilter {
    #[new]
    #[pyo3(signature = (model, x0, P0, form=None), text_signature = "(model, x0, P0, form='joseph')")]
    #[allow(non_snake_case)]
    fn new(
        py: Python<'_>,
        model: &Bound<'_, PyAny>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        form: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let form: UpdateForm = form_arg(py, form)?;
        let (core, x0, p0) = model_and_prior(py, model, x0, P0)?;
        let inner = filter::KalmanFilter::new(core.clone(), &x0, &p0, form)?;
        let origin = Origin { model: model.clone().unbind(), core, x0, p0 };
        Ok(PyKalmanFilter { inner, origin, last: StepData::default() })
    }

    /// Measurement update with the observation y at the current step t.
    ///
    /// Parameters
    /// ----------
    /// y : array_like, shape (m,)
    ///     The observation (a scalar when m = 1); NaN marks a missing component.
    /// u : array_like, shape (k,), optional
    ///     The input u(t); required when the model has D.
    /// H : array_like, shape (m, n), optional
    ///     The observation matrix for this update only, in place of the model's (keyword only;
    ///     as filterpy's ``update(z, R=..., H=...)``).
    /// R : array_like, shape (m, m), optional
    ///     The measurement noise covariance for this update only (keyword only): symmetric
    ///     positive semidefinite, and with the model's N so must [[Q, N], [N', R]] be.
    ///
    /// Raises
    /// ------
    /// KfastError
    ///     For a wrong shape, inf, a missing input, an invalid H or R (the message names it and
    ///     the step), a second update without a predict in between, or a step past the end of
    ///     per-step matrices. The filter is then unchanged.
    /// InnovationCovarianceError
    ///     When S = H P H' + R of the observed components is not positive definite.
    ///
    /// Examples
    /// --------
    /// A reading whose noise variance is known when it arrives:
    ///
    /// >>> model = kfast.LinearGaussian(F=1.0, H=1.0, Q=0.1, R=1.0)
    /// >>> kf = kfast.KalmanFilter(model, x0=0.0, P0=1.0)
    /// >>> kf.update(2.0, R=0.25)  # K = 1 / (1 + 0.25) = 0.8
    /// >>> print(kf.x.round(6), kf.P.round(6))
    /// [1.6] [[0.2]]
    #[pyo3(signature = (y, u=None, *, H=None, R=None))]
    #[allow(non_snake_case)]
    fn update(
        &mut self,
        py: Python<'_>,
        y: &Bound<'_, PyAny>,
        u: Option<&Bound<'_, PyAny>>,
        H: Option<&Bound<'_, PyAny>>,
        R: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let (m, n, t) = (self.inner.model().n_obs(), self.inner.model().n_states(), self.inner.t());
        let (h, r) = (step_matrix(py, "H", H, [m, n], t)?, step_matrix(py, "R", R, [m, m], t)?);
        let (h, r) = (matrix_data("H", &h)?, matrix_data("R", &r)?);
        with_step_data(py, Some(y), u, |y, u| {
            update_recorded(&mut self.inner, &mut self.last, y.unwrap_or_default(), u, h, r)
        })
    }

    /// Time update to the next step (a step without ``update`` counts as missing).
    ///
    /// Parameters
    /// ----------
    /// u : array_like, shape (k,), optional
    ///     The input u(t); required when the model has B.
    ///
    /// Raises
    /// ------
    /// KfastError
    ///     For a wrong input or a step past the end of per-step matrices.
    #[pyo3(signature = (u=None))]
    fn predict(&mut self, py: Python<'_>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, None, u, |_, u| self.inner.predict(u))
    }

    /// ``update(y, u, H=H, R=R)`` then ``predict(u)``: one whole step.
    #[pyo3(signature = (y, u=None, *, H=None, R=None))]
    #[allow(non_snake_case)]
    fn step(
        &mut self,
        py: Python<'_>,
        y: &Bound<'_, PyAny>,
        u: Option<&Bound<'_, PyAny>>,
        H: Option<&Bound<'_, PyAny>>,
        R: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.update(py, y, u, H, R)?;
        self.predict(py, u)
    }

    /// Pickling: the constructor's arguments and the state (see `__setstate__`).
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyType>, Bound<'py, PyTuple>, Bound<'py, PyDict>)> {
        let py = slf.py();
        let this = slf.borrow();
        let [model, x0, p0] = this.origin.args(py)?;
        let args = PyTuple::new(py, [model, x0, p0, form_name(this.inner.form()).into_pyobject(py)?.into_any()])?;
        Ok((slf.get_type(), args, filter_state(py, &this.inner, &this.last)?))
    }

    /// Unpickling: continue from the state `__reduce__` gave.
    fn __setstate__(&mut self, py: Python<'_>, state: &Bound<'_, PyDict>) -> PyResult<()> {
        (self.inner, self.last) = resume_filter(py, &self.origin.core, self.inner.form(), state)?;
        Ok(())
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

/// Online fixed-lag smoother: ``update(y)``, ``predict(u)``, ``step(y, u)``.
///
/// Starts from the prior (x0, P0) = x(0|-1), P(0|-1). After ``update`` at step t,
/// ``x_lagged``, ``P_lagged`` are x(t-lag|t), P(t-lag|t) (None while t < lag), and
/// ``x_window``, ``P_window`` hold x(t-i|t) for i = 0..min(t, lag). Pickles (and copies) with
/// its model; the copy continues the stream bit for bit. Threads: as for ``KalmanFilter``.
///
/// Parameters
/// ----------
/// model, x0, P0
///     As for ``KalmanFilter``.
/// form : {"joseph", "standard"}
///     The covariance update, as in ``LinearGaussian.filter``.
/// lag : int
///     The lag L >= 0.
///
/// Raises
/// ------
/// KfastError
///     For a model that is not a ``kfast.LinearGaussian``, an invalid prior or a negative lag.
///
/// Notes
/// -----
/// Söderström (6.58)-(6.79), with the structured recursion (6.70)-(6.75): O(lag n^3) per step.
/// ``x_lagged`` after the update at s + lag is row s of ``LinearGaussian.smooth_fixed_lag``.
///
/// Examples
/// --------
/// The random walk of Söderström ch. 8 with beta = 1: the variance with lag 2 is 0.6875.
///
/// >>> walk = kfast.LinearGaussian(F=1.0, H=1.0, Q=1.0, R=2.0)
/// >>> fl = kfast.FixedLagSmoother(walk, x0=0.0, P0=2.0, lag=2)
/// >>> for y in np.zeros(10):
/// ...     fl.step(y)
/// >>> fl.update(0.0)
/// >>> print(fl.P_lagged.round(6), fl.x_window.shape)
/// [[0.6875]] (3, 1)
#[pyclass(module = "kfast._kfast", name = "FixedLagSmoother")]
pub(super) struct PyFixedLagSmoother {
    inner: FixedLagSmoother,
    origin: Origin,
    last: StepData,
}

#[pymethods]
impl PyFixedLagSmoother {
    #[new]
    #[pyo3(signature = (model, x0, P0, lag, form=None), text_signature = "(model, x0, P0, lag, form='joseph')")]
    #[allow(non_snake_case)]
    fn new(
        py: Python<'_>,
        model: &Bound<'_, PyAny>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        lag: &Bound<'_, PyAny>,
        form: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let lag = index_arg(py, "lag", lag)?;
        let form = form_arg(py, form)?;
        let (core, x0, p0) = model_and_prior(py, model, x0, P0)?;
        let inner = FixedLagSmoother::new(core.clone(), &x0, &p0, lag, form)?;
        let origin = Origin { model: model.clone().unbind(), core, x0, p0 };
        Ok(PyFixedLagSmoother { inner, origin, last: StepData::default() })
    }

    /// Measurement update with the observation y at the current step t.
    ///
    /// Parameters
    /// ----------
    /// y : array_like, shape (m,)
    ///     The observation (a scalar when m = 1); NaN marks a missing component.
    /// u : array_like, shape (k,), optional
    ///     The input u(t); required when the model has D.
    ///
    /// Raises
    /// ------
    /// KfastError
    ///     For a wrong shape, inf, a missing input, a second update without a predict in between,
    ///     or a step past the end of per-step matrices.
    /// InnovationCovarianceError
    ///     When S = H P H' + R of the observed components is not positive definite.
    #[pyo3(signature = (y, u=None))]
    fn update(&mut self, py: Python<'_>, y: &Bound<'_, PyAny>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, Some(y), u, |y, u| self.update_recorded(y.unwrap_or_default(), u))
    }

    /// Time update to the next step (a step without ``update`` counts as missing).
    ///
    /// Parameters
    /// ----------
    /// u : array_like, shape (k,), optional
    ///     The input u(t); required when the model has B.
    ///
    /// Raises
    /// ------
    /// KfastError
    ///     For a wrong input or a step past the end of per-step matrices.
    #[pyo3(signature = (u=None))]
    fn predict(&mut self, py: Python<'_>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, None, u, |_, u| self.inner.predict(u))
    }

    /// ``update(y, u)`` then ``predict(u)``: one whole step.
    #[pyo3(signature = (y, u=None))]
    fn step(&mut self, py: Python<'_>, y: &Bound<'_, PyAny>, u: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        with_step_data(py, Some(y), u, |y, u| {
            self.update_recorded(y.unwrap_or_default(), u)?;
            self.inner.predict(u)
        })
    }

    /// Pickling: the constructor's arguments and the state (see `__setstate__`).
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyType>, Bound<'py, PyTuple>, Bound<'py, PyDict>)> {
        let py = slf.py();
        let this = slf.borrow();
        let [model, x0, p0] = this.origin.args(py)?;
        let lag = this.inner.lag().into_pyobject(py)?.into_any();
        let form = form_name(this.inner.filter().form()).into_pyobject(py)?.into_any();
        let args = PyTuple::new(py, [model, x0, p0, lag, form])?;
        let state = filter_state(py, this.inner.filter(), &this.last)?;
        let n = this.inner.filter().model().n_states();
        let window = this
            .inner
            .window_state()
            .map(|(x, p, c)| {
                PyTuple::new(py, [to_array(py, x, &[n])?, to_array(py, p, &[n, n])?, to_array(py, c, &[n, n])?])
            })
            .collect::<PyResult<Vec<_>>>()?;
        state.set_item("window", window)?;
        Ok((slf.get_type(), args, state))
    }

    /// Unpickling: continue from the state `__reduce__` gave (the filter's, and the window's
    /// past states x(s|.), P(s|.) and cross covariances with the current state).
    fn __setstate__(&mut self, py: Python<'_>, state: &Bound<'_, PyDict>) -> PyResult<()> {
        let (filter, last) = resume_filter(py, &self.origin.core, self.inner.filter().form(), state)?;
        let mut arrays = Vec::new();
        for entry in item(state, "window")?.try_iter()? {
            let (x, p, c): (Bound<'_, PyAny>, Bound<'_, PyAny>, Bound<'_, PyAny>) = entry?.extract()?;
            arrays.push([flat(py, "window", &x)?, flat(py, "window", &p)?, flat(py, "window", &c)?]);
        }
        let window = arrays
            .iter()
            .map(|[x, p, c]| Ok((data("window", x, 1)?, data("window", p, 2)?, data("window", c, 2)?)))
            .collect::<PyResult<Vec<_>>>()?;
        self.inner = FixedLagSmoother::resume(filter, self.inner.lag(), &window)?;
        self.last = last;
        Ok(())
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

impl PyFixedLagSmoother {
    /// `inner.update(y, u)`, recording the data for pickling.
    fn update_recorded(&mut self, y: &[f64], u: Option<&[f64]>) -> crate::Result<()> {
        let before = self.inner.filter().loglik_sum();
        self.inner.update(y, u)?;
        self.last.y.set(Some(y));
        self.last.u.set(u);
        self.last.loglik_before = before;
        Ok(())
    }
}
