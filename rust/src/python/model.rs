//! `kfast._kfast.LinearGaussian`: the compiled model and its sequence methods.

use std::sync::Arc;

use numpy::{PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple, PyType};

use super::{
    contiguous, data, filter_outputs, non_negative, parse_form, prior, series, series_of, to_array, KfastError,
    OutArrays, FILTER_FIELDS, SMOOTH_FIELDS,
};
use crate::linear::filter::{self, FilterOptions};
use crate::linear::model::{self, Matrices, StepMatrix};
use crate::linear::smoother;

/// A matrix, constant (2-D) or per step (3-D), from Python.
pub(super) fn step_matrix(arg: &'static str, arr: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<StepMatrix> {
    Ok(StepMatrix::from_shape(arg, arr.shape(), contiguous(arg, arr)?.to_vec())?)
}

/// The compiled model; `kfast.LinearGaussian` wraps it.
#[pyclass(module = "kfast._kfast", name = "LinearGaussian", frozen)]
pub(super) struct PyLinearGaussian {
    pub(super) inner: Arc<model::LinearGaussian>,
}

type Array<'py> = PyReadonlyArrayDyn<'py, f64>;
type OutArray<'py> = Bound<'py, PyArrayDyn<f64>>;

#[pymethods]
impl PyLinearGaussian {
    #[new]
    #[pyo3(signature = (F, H, Q, R, B=None, D=None, N=None))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn new(
        F: Array<'_>,
        H: Array<'_>,
        Q: Array<'_>,
        R: Array<'_>,
        B: Option<Array<'_>>,
        D: Option<Array<'_>>,
        N: Option<Array<'_>>,
    ) -> PyResult<Self> {
        let opt = |arg: &'static str, a: &Option<Array<'_>>| a.as_ref().map(|a| step_matrix(arg, a)).transpose();
        let mats = Matrices {
            b: opt("B", &B)?,
            d: opt("D", &D)?,
            n: opt("N", &N)?,
            ..Matrices::new(step_matrix("F", &F)?, step_matrix("H", &H)?, step_matrix("Q", &Q)?, step_matrix("R", &R)?)
        };
        Ok(PyLinearGaussian { inner: Arc::new(model::LinearGaussian::new(mats)?) })
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

    /// Pickling: the constructor's arguments F, H, Q, R, B, D, N (validated again on
    /// unpickling).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyType>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let mats = slf.get().inner.matrices();
        let array = |mat: &StepMatrix| -> PyResult<Bound<'py, PyAny>> {
            let (shape, values) = match mat.steps() {
                None => (vec![mat.rows(), mat.cols()], mat.at(0).to_vec()),
                Some(t) => (vec![t, mat.rows(), mat.cols()], (0..t).flat_map(|s| mat.at(s).iter().copied()).collect()),
            };
            Ok(to_array(py, &values, &shape)?.into_any())
        };
        let optional = |mat: &Option<StepMatrix>| mat.as_ref().map(array).transpose();
        let args = [
            Some(array(&mats.f)?),
            Some(array(&mats.h)?),
            Some(array(&mats.q)?),
            Some(array(&mats.r)?),
            optional(&mats.b)?,
            optional(&mats.d)?,
            optional(&mats.n)?,
        ];
        Ok((slf.get_type(), PyTuple::new(py, args)?))
    }

    /// Runs the filter; returns a dict of the FilterResult fields named in `outputs` (all by
    /// default).
    #[pyo3(signature = (y, x0, P0, u=None, form="joseph", converge_tol=None, outputs=None))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn filter<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        u: Option<Array<'py>>,
        form: &str,
        converge_tol: Option<f64>,
        outputs: Option<Vec<String>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let form = FilterOptions { form: parse_form(form)?, converge_tol };
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let (n, m) = (self.inner.n_states(), self.inner.n_obs());
        let mut out = OutArrays::for_filter(py, y.steps(), n, m, outputs.as_deref())?;
        let names = out.names.clone();
        let mut slices = out.slices()?;
        let model = &*self.inner;
        let loglik =
            py.detach(|| filter::filter_into(model, y, u, x0, p0, form, filter_outputs(&names, &mut slices)))?;
        drop(slices);
        let dict = out.into_dict(py)?;
        dict.set_item("loglik", loglik)?;
        Ok(dict)
    }

    /// The filter with an exact diffuse start P(0|-1) = P0 + kappa P0_inf, kappa -> inf; the
    /// dict adds "n_diffuse" (d) and "P_pred_inf" (T, n, n).
    #[pyo3(signature = (y, x0, P0, P0_inf, u=None, form="joseph", converge_tol=None, outputs=None))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn filter_diffuse<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        P0_inf: Array<'py>,
        u: Option<Array<'py>>,
        form: &str,
        converge_tol: Option<f64>,
        outputs: Option<Vec<String>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let form = FilterOptions { form: parse_form(form)?, converge_tol };
        let (y, u) = series(&y, u.as_ref())?;
        let n = self.inner.n_states();
        let (x0, p0) = prior(&x0, &P0, n)?;
        let p0_inf = data("P0_inf", &P0_inf, 2)?;
        let m = self.inner.n_obs();
        let mut out = OutArrays::for_filter(py, y.steps(), n, m, outputs.as_deref())?
            .with_written_in_full(py, &[("P_pred_inf", &[y.steps(), n, n])])?;
        let names = out.names.clone();
        let mut slices = out.slices()?;
        let inf = slices.pop();
        let model = &*self.inner;
        let (loglik, diffuse) = py.detach(|| {
            filter::filter_diffuse_into(model, y, u, x0, p0, p0_inf, form, filter_outputs(&names, &mut slices), inf)
        })?;
        drop(slices);
        let dict = out.into_dict(py)?;
        dict.set_item("loglik", loglik)?;
        dict.set_item("n_diffuse", diffuse)?;
        Ok(dict)
    }

    /// The log-likelihood alone.
    #[pyo3(signature = (y, x0, P0, u=None, form="joseph", converge_tol=None))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn loglik(
        &self,
        py: Python<'_>,
        y: Array<'_>,
        x0: Array<'_>,
        P0: Array<'_>,
        u: Option<Array<'_>>,
        form: &str,
        converge_tol: Option<f64>,
    ) -> PyResult<f64> {
        let form = FilterOptions { form: parse_form(form)?, converge_tol };
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let model = &*self.inner;
        Ok(py.detach(|| filter::loglik(model, y, u, x0, p0, form))?)
    }

    /// Filter then RTS smoother; one dict with the filter's fields and x_smooth, P_smooth,
    /// P_lag1 (those named in `outputs`, all by default).
    #[pyo3(signature = (y, x0, P0, u=None, form="joseph", outputs=None))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn smooth<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        u: Option<Array<'py>>,
        form: &str,
        outputs: Option<Vec<String>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let form = parse_form(form)?;
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let (n, m, steps) = (self.inner.n_states(), self.inner.n_obs(), y.steps());
        let is_smooth = |name: &str| SMOOTH_FIELDS.contains(&name);
        if let Some(bad) = outputs
            .iter()
            .flatten()
            .find(|name| !is_smooth(name) && !FILTER_FIELDS.iter().any(|f| f.name == name.as_str()))
        {
            let all: Vec<&str> = FILTER_FIELDS.iter().map(|f| f.name).chain(SMOOTH_FIELDS).collect();
            return Err(KfastError::new_err(format!("outputs: unknown field {bad:?}; choose from {all:?}")));
        }
        let wanted_filter: Option<Vec<String>> =
            outputs.as_ref().map(|w| w.iter().filter(|name| !is_smooth(name)).cloned().collect());
        let shapes = [vec![steps, n], vec![steps, n, n], vec![steps, n, n]];
        let smooth_specs: Vec<(&'static str, &[usize])> = SMOOTH_FIELDS
            .iter()
            .zip(&shapes)
            .filter(|(name, _)| outputs.as_ref().is_none_or(|w| w.iter().any(|x| x == *name)))
            .map(|(name, shape)| (*name, shape.as_slice()))
            .collect();
        let mut out = OutArrays::for_filter(py, steps, n, m, wanted_filter.as_deref())?
            .with_written_in_full(py, &smooth_specs)?;
        let names = out.names.clone();
        let mut slices = out.slices()?;
        let model = &*self.inner;
        let loglik = py.detach(|| {
            let (filt, sm) = super::outputs(&names, &mut slices);
            smoother::smooth_into(model, y, u, x0, p0, form, filt, sm)
        })?;
        drop(slices);
        let dict = out.into_dict(py)?;
        dict.set_item("loglik", loglik)?;
        Ok(dict)
    }

    /// Fixed-lag smoother; dict with x_smooth (T, n), P_smooth (T, n, n).
    #[pyo3(signature = (y, x0, P0, lag, u=None, form="joseph"))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn smooth_fixed_lag<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        lag: i64,
        u: Option<Array<'py>>,
        form: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let form = parse_form(form)?;
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let lag = non_negative("lag", lag)?;
        let (n, steps) = (self.inner.n_states(), y.steps());
        let mut out = OutArrays::new(py, "y", &[("x_smooth", &[steps, n]), ("P_smooth", &[steps, n, n])])?;
        let mut slices = out.slices()?;
        let model = &*self.inner;
        py.detach(|| {
            let [x_out, p_out] = &mut slices[..] else { unreachable!("two output arrays") };
            smoother::smooth_fixed_lag_into(
                model,
                y,
                u,
                x0,
                p0,
                smoother::FixedLagOptions::new(lag).form(form),
                smoother::FixedLagOutputs::new(x_out, p_out),
            )
        })?;
        drop(slices);
        out.into_dict(py)
    }

    /// Fixed-point smoother; dict with x (T - t_point, n), P (T - t_point, n, n).
    #[pyo3(signature = (y, x0, P0, t_point, u=None, form="joseph"))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn smooth_fixed_point<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        t_point: i64,
        u: Option<Array<'py>>,
        form: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let form = parse_form(form)?;
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let t_point = non_negative("t_point", t_point)?;
        let model = &*self.inner;
        let res = py.detach(|| smoother::smooth_fixed_point(model, y, u, x0, p0, t_point, form))?;
        let (n, rows) = (self.inner.n_states(), y.steps() - t_point);
        let dict = PyDict::new(py);
        dict.set_item("x", super::to_array(py, &res.x, &[rows, n])?)?;
        dict.set_item("P", super::to_array(py, &res.p, &[rows, n, n])?)?;
        Ok(dict)
    }

    /// k-step forecasts from the one-step prediction (x, P); dict with x, P, y, y_cov.
    #[pyo3(signature = (x, P, steps, u=None))]
    #[allow(non_snake_case)]
    fn forecast<'py>(
        &self,
        py: Python<'py>,
        x: Array<'py>,
        P: Array<'py>,
        steps: i64,
        u: Option<Array<'py>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let steps = non_negative("steps", steps)?;
        let (n, m) = (self.inner.n_states(), self.inner.n_obs());
        let x = data("x", &x, 1)?;
        let p = data("P", &P, 2)?;
        let u = u.as_ref().map(|u| series_of("u", u)).transpose()?;
        let model = &*self.inner;
        let fc = py.detach(|| crate::forecast(model, x, p, steps, u))?;
        let dict = PyDict::new(py);
        dict.set_item("x", to_array(py, &fc.x, &[steps, n])?)?;
        dict.set_item("P", to_array(py, &fc.p, &[steps, n, n])?)?;
        dict.set_item("y", to_array(py, &fc.y, &[steps, m])?)?;
        dict.set_item("y_cov", to_array(py, &fc.y_cov, &[steps, m, m])?)?;
        Ok(dict)
    }

    /// Checks a prior (x0, P0) as the filter does: shapes, finite, P0 symmetric PSD.
    #[allow(non_snake_case)]
    fn check_prior(&self, x0: Array<'_>, P0: Array<'_>) -> PyResult<()> {
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        Ok(crate::core::validate::check_prior(self.inner.n_states(), x0, p0)?)
    }

    /// States and outputs driven by the given noise w (T, n), v (T, m) from x_init.
    #[pyo3(signature = (x_init, w, v, u=None))]
    fn propagate<'py>(
        &self,
        py: Python<'py>,
        x_init: Array<'py>,
        w: Array<'py>,
        v: Array<'py>,
        u: Option<Array<'py>>,
    ) -> PyResult<(OutArray<'py>, OutArray<'py>)> {
        let (n, m) = (self.inner.n_states(), self.inner.n_obs());
        let x_init = data("x_init", &x_init, 1)?;
        let (ws, vs) = (series_of("w", &w)?, series_of("v", &v)?);
        let us = u.as_ref().map(|u| series_of("u", u)).transpose()?;
        let model = &*self.inner;
        let (xs, ys) = py.detach(|| crate::propagate(model, x_init, ws, vs, us))?;
        let steps = ws.steps();
        Ok((to_array(py, &xs, &[steps, n])?, to_array(py, &ys, &[steps, m])?))
    }
}

/// Many series: dict with x_filt (B, T, n), P_filt ((T, n, n) when shared, else (B, T, n, n);
/// absent without covariances), loglik (B,), shared (bool).
#[pyfunction]
#[pyo3(signature = (model, Y, x0, P0, u=None, return_covs=true, threads=None, form="joseph"))]
#[allow(non_snake_case)]
#[allow(clippy::too_many_arguments)]
pub(super) fn filter_batch<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyLinearGaussian>,
    Y: Array<'py>,
    x0: Array<'py>,
    P0: Array<'py>,
    u: Option<Array<'py>>,
    return_covs: bool,
    threads: Option<usize>,
    form: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let form = parse_form(form)?;
    let model = model.get().inner.clone();
    let (n, m) = (model.n_states(), model.n_obs());
    let yv = super::data("Y", &Y, 3)?;
    let (bs, steps, width) = (Y.shape()[0], Y.shape()[1], Y.shape()[2]);
    if width != m {
        return Err(KfastError::new_err(format!(
            "Y: expected shape (B, T, {m}) for m = {m} outputs, got {:?}",
            Y.shape()
        )));
    }
    let k = model.n_inputs();
    // Exact shapes: the crate's flat slices cannot tell (n, B) from (B, n).
    let x0v = batch_part("x0", &x0, &[n], bs)?;
    let p0v = batch_part("P0", &P0, &[n, n], bs)?;
    let (uv, u_shared) = match &u {
        Some(u) if u.ndim() >= 2 && u.shape()[u.ndim() - 2] != steps => {
            return Err(KfastError::new_err(format!("u: has {} steps but Y has {steps}", u.shape()[u.ndim() - 2])));
        }
        Some(u) => (Some(batch_part("u", u, &[steps, k], bs)?), u.ndim() == 2),
        None => (None, false),
    };
    let batch = crate::Batch { y: yv, series: bs, steps, u: uv, u_shared, x0: x0v, p0: p0v };
    let shared = crate::linear::batch::shares_covariances(&model, &batch, form);
    let covs = return_covs.then(|| if shared { vec![steps, n, n] } else { vec![bs, steps, n, n] });
    let (dict, shared) =
        run_batch(py, [bs, steps, n], covs, |out| crate::filter_batch(&model, batch, form, out, threads))?;
    dict.set_item("shared", shared)?;
    Ok(dict)
}

/// Allocates a batch filter's outputs — x_filt (B, T, n), loglik (B,) and P_filt of shape
/// `covs` when given — runs `filter` on them without the GIL, and returns their dict with what
/// `filter` returned.
pub(super) fn run_batch<'py, R: Send>(
    py: Python<'py>,
    [bs, steps, n]: [usize; 3],
    covs: Option<Vec<usize>>,
    filter: impl FnOnce(crate::BatchOutputs<'_>) -> crate::Result<R> + Send,
) -> PyResult<(Bound<'py, PyDict>, R)> {
    let mut specs: Vec<(&'static str, Vec<usize>)> = vec![("x_filt", vec![bs, steps, n]), ("loglik", vec![bs])];
    specs.extend(covs.map(|shape| ("P_filt", shape)));
    let spec_refs: Vec<(&'static str, &[usize])> = specs.iter().map(|(k, v)| (*k, v.as_slice())).collect();
    let mut out = OutArrays::new(py, "Y", &spec_refs)?;
    let mut slices = out.slices()?;
    let result = py.detach(|| {
        let mut it = slices.iter_mut();
        let x_filt = it.next().expect("x_filt");
        let loglik = it.next().expect("loglik");
        let p_filt = it.next().map(|p| &mut **p);
        filter(crate::BatchOutputs { x_filt, p_filt, loglik })
    })?;
    drop(slices);
    Ok((out.into_dict(py)?, result))
}

/// The data of a batch argument of shape `shape` (shared by all series) or `(B, *shape)` (one
/// per series).
pub(super) fn batch_part<'a>(
    arg: &str,
    arr: &'a PyReadonlyArrayDyn<'_, f64>,
    shape: &[usize],
    series: usize,
) -> PyResult<&'a [f64]> {
    let per_series: Vec<usize> = std::iter::once(series).chain(shape.iter().copied()).collect();
    if arr.shape() != shape && arr.shape() != per_series.as_slice() {
        return Err(KfastError::new_err(format!(
            "{arg}: expected shape {} (shared) or {} (one per series: Y has {series} series), got {}",
            shape_str(shape),
            shape_str(&per_series),
            shape_str(arr.shape())
        )));
    }
    contiguous(arg, arr)
}

/// A shape as Python prints it: `(4,)`, `(3, 4)`.
fn shape_str(shape: &[usize]) -> String {
    match shape {
        [d] => format!("({d},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    }
}
