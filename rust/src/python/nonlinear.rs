//! `kfast._kfast.NonlinearModel`: f and h given as Python callables (vectorized over a batch of
//! points) or as built-in Rust models, and the EKF and UKF over a series.

use std::sync::Arc;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use super::model::{batch_part, run_batch, step_matrix};
use super::{contiguous, filter_outputs, outputs, parse_form, prior, series, KfastError, OutArrays, FILTER_FIELDS};
use crate::error::{Error, Result};
use crate::nonlinear::models::{Bearing, CoordinatedTurn, RangeBearing, RangeBearingElevation, Ungm};
use crate::nonlinear::{
    self, ConstantMap, CustomPoints, EkfOptions, Iteration, LinearMap, PointFunction, SigmaPoints, SmoothMethod,
    UkfForm, UkfOptions,
};

type Array<'py> = PyReadonlyArrayDyn<'py, f64>;

/// A user's function of a batch of points: a Python callable `fn(X, t, u)` (X of shape (k, n),
/// called with the GIL taken for the call; the filters run without it), or a compiled function
/// of the signature [`CFn`] (a numba `@cfunc`, a `scipy.LowLevelCallable` or a ctypes pointer,
/// its signature checked in Python before its address gets here), called directly.
enum Callee {
    Python(Py<PyAny>),
    /// The address of a compiled function, of the signature [`CFn`] (f, h, g and their
    /// derivatives) or [`ParticleCFn`] (a particle filter's likelihood or move).
    C(usize),
}

/// The C signature of a compiled function: `void f(const double *X, intptr_t k, intptr_t n,
/// int64_t t, const double *u, double *out)` — the k points X (k × n, row-major), the step t,
/// the input row u (NULL without inputs) and the k results (k × the numbers per point).
type CFn = unsafe extern "C" fn(*const f64, isize, isize, i64, *const f64, *mut f64);

/// The C signature of a compiled likelihood or move of the particle filter: `void f(const
/// double *X, intptr_t k, intptr_t n, const double *y, intptr_t m, int64_t t, const double *u,
/// double *out)` — [`CFn`] with y(t) (m numbers, NaN where missing) after the points.
type ParticleCFn = unsafe extern "C" fn(*const f64, isize, isize, *const f64, isize, i64, *const f64, *mut f64);

impl Callee {
    /// `callable` from Python: a function, or `("cfunc", address)` for a compiled one.
    fn of(name: &str, callable: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(tuple) = callable.cast::<PyTuple>() {
            let (kind, address): (String, usize) = tuple.extract()?;
            if kind != "cfunc" || address == 0 {
                return Err(KfastError::new_err(format!("{name}: expected a callable or a compiled function")));
            }
            // a non-null address of a function whose signature was checked in Python
            // (kfast.nonlinear.model._compiled_address)
            return Ok(Callee::C(address));
        }
        if !callable.is_callable() {
            return Err(KfastError::new_err(format!("{name}: expected a callable {name}(X, t, u)")));
        }
        Ok(Callee::Python(callable.clone().unbind()))
    }
}

/// f, h or g given by the user, with its Jacobian and Hessians if given (each a [`Callee`]).
struct UserFunction {
    name: &'static str,
    fun: Callee,
    jac: Option<Callee>,
    hess: Option<Callee>,
    dim_in: usize,
    dim_out: usize,
    /// The shape of one point's result (`[dim_out]`, or `[n, r]` for a noise gain).
    shape: Vec<usize>,
}

impl UserFunction {
    /// Calls `callee` at the k `points` and copies its result, which must have the shape
    /// `shape_tail` per point, into `out`.
    #[allow(clippy::too_many_arguments)]
    fn call(
        &self,
        callee: &Callee,
        what: &str,
        points: &[f64],
        k: usize,
        t: usize,
        u: Option<&[f64]>,
        shape_tail: &[usize],
        out: &mut [f64],
    ) -> Result<()> {
        let fail = |problem: String| Error::arg_at(self.name, t, problem);
        let points = &points[..k * self.dim_in];
        let callable = match callee {
            Callee::C(address) => {
                let (k_c, n_c, t_c) =
                    c_sizes(k, self.dim_in, t).ok_or_else(|| fail("too many points for a C call".into()))?;
                let out = &mut out[..k * shape_tail.iter().product::<usize>()];
                let u = u.map_or(std::ptr::null(), |u| u.as_ptr());
                // SAFETY: the caller of `kfast.NonlinearModel` vouched for the address, a
                // function of the signature CFn (checked in Python); the buffers have the sizes
                // it promises.
                unsafe {
                    let fun = std::mem::transmute::<usize, CFn>(*address);
                    fun(points.as_ptr(), k_c, n_c, t_c, u, out.as_mut_ptr())
                };
                return Ok(());
            }
            Callee::Python(callable) => callable,
        };
        Python::attach(|py| {
            let x = points_array(py, points, k, self.dim_in).map_err(fail)?;
            let u = u.map(|u| numpy::PyArray1::from_slice(py, u));
            let result = callable.bind(py).call1((x, t, u));
            copy_result(py, result, what, (k, self.dim_in), shape_tail, out).map_err(fail)
        })
    }
}

/// k, n and t as a C call takes them (None if they do not fit).
fn c_sizes(k: usize, n: usize, t: usize) -> Option<(isize, isize, i64)> {
    Some((isize::try_from(k).ok()?, isize::try_from(n).ok()?, i64::try_from(t).ok()?))
}

/// The k points (k × n) as a NumPy array.
fn points_array<'py>(
    py: Python<'py>,
    points: &[f64],
    k: usize,
    n: usize,
) -> std::result::Result<Bound<'py, PyAny>, String> {
    Ok(Array2::from_shape_vec((k, n), points.to_vec()).map_err(|e| e.to_string())?.into_pyarray(py).into_any())
}

/// The `result` of a Python callable (`what`) at points of shape `points` (k, n), which must
/// have the shape (k, *`shape_tail`), into `out`; else what is wrong with it.
fn copy_result(
    py: Python<'_>,
    result: PyResult<Bound<'_, PyAny>>,
    what: &str,
    (k, n): (usize, usize),
    shape_tail: &[usize],
    out: &mut [f64],
) -> std::result::Result<(), String> {
    let result = result.map_err(|e| format!("{what} raised {}", describe(py, &e)))?;
    // a float64 array as it is (the usual case: no call into NumPy), anything else through
    // numpy.asarray
    let arr = match result.cast_into::<PyArrayDyn<f64>>() {
        Ok(arr) => arr,
        Err(other) => py
            .import("numpy")
            .and_then(|np| np.getattr("asarray")?.call1((other.into_inner(), "float64")))
            .and_then(|a| Ok(a.cast_into::<PyArrayDyn<f64>>()?))
            .map_err(|e| format!("{what} did not return an array of numbers ({})", describe(py, &e)))?,
    };
    let mut want = vec![k];
    want.extend_from_slice(shape_tail);
    if arr.shape() != want.as_slice() {
        return Err(format!(
            "{what} returned shape {} for points X of shape ({k}, {n}), expected {}",
            tuple(arr.shape()),
            tuple(&want)
        ));
    }
    let arr = arr.readonly();
    match arr.as_slice() {
        Ok(values) => out[..values.len()].copy_from_slice(values),
        Err(_) => {
            for (o, v) in out.iter_mut().zip(arr.as_array().iter()) {
                *o = *v;
            }
        }
    }
    Ok(())
}

/// The particle filter's likelihood (`shape` []: log p(y(t) | x) per particle) or move
/// (`shape` [n]: the moved particle) given by the user: `fn(X, y, t, u)` or a compiled
/// function of the signature [`ParticleCFn`].
struct UserParticleFunction {
    name: &'static str,
    fun: Callee,
    n: usize,
    /// The shape of one particle's result.
    shape: Vec<usize>,
}

impl nonlinear::ParticleFunction for UserParticleFunction {
    fn eval(&self, particles: &[f64], k: usize, y: &[f64], t: usize, u: Option<&[f64]>, out: &mut [f64]) -> Result<()> {
        let fail = |problem: String| Error::arg_at(self.name, t, problem);
        let points = &particles[..k * self.n];
        let out = &mut out[..k * self.shape.iter().product::<usize>()];
        let callable = match &self.fun {
            Callee::C(address) => {
                let (k_c, n_c, t_c) =
                    c_sizes(k, self.n, t).ok_or_else(|| fail("too many particles for a C call".into()))?;
                let m_c = isize::try_from(y.len()).map_err(|_| fail("too many outputs for a C call".into()))?;
                let u = u.map_or(std::ptr::null(), |u| u.as_ptr());
                // SAFETY: the address is a function of the signature ParticleCFn (checked in
                // Python); the buffers have the sizes it promises.
                unsafe {
                    let fun = std::mem::transmute::<usize, ParticleCFn>(*address);
                    fun(points.as_ptr(), k_c, n_c, y.as_ptr(), m_c, t_c, u, out.as_mut_ptr())
                };
                return Ok(());
            }
            Callee::Python(callable) => callable,
        };
        Python::attach(|py| {
            let x = points_array(py, points, k, self.n).map_err(fail)?;
            let (y, u) = (numpy::PyArray1::from_slice(py, y), u.map(|u| numpy::PyArray1::from_slice(py, u)));
            let result = callable.bind(py).call1((x, y, t, u));
            copy_result(py, result, "it", (k, self.n), &self.shape, out).map_err(fail)
        })
    }

    fn parallel(&self) -> bool {
        matches!(self.fun, Callee::C(_))
    }
}

/// A shape as Python prints it: `(3, 2)`, `(3,)`.
fn tuple(shape: &[usize]) -> String {
    match shape {
        [one] => format!("({one},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    }
}

/// `TypeError: message` of a Python exception.
fn describe(py: Python<'_>, err: &PyErr) -> String {
    let kind = err.get_type(py).name().map(|n| n.to_string()).unwrap_or_else(|_| "an exception".into());
    format!("{kind}: {}", err.value(py))
}

impl PointFunction for UserFunction {
    fn dim_in(&self) -> usize {
        self.dim_in
    }

    /// Compiled functions run on any thread; a Python one holds the GIL for its call.
    fn parallel(&self) -> bool {
        [Some(&self.fun), self.jac.as_ref(), self.hess.as_ref()]
            .into_iter()
            .flatten()
            .all(|c| matches!(c, Callee::C(_)))
    }

    fn dim_out(&self) -> usize {
        self.dim_out
    }

    fn eval(&self, points: &[f64], k: usize, t: usize, u: Option<&[f64]>, out: &mut [f64]) -> Result<()> {
        self.call(&self.fun, "it", points, k, t, u, &self.shape, out)
    }

    fn jacobian(&self, points: &[f64], k: usize, t: usize, u: Option<&[f64]>, out: &mut [f64]) -> Option<Result<()>> {
        let jac = self.jac.as_ref()?;
        Some(self.call(jac, "its Jacobian", points, k, t, u, &[self.dim_out, self.dim_in], out))
    }

    fn hessian(&self, points: &[f64], k: usize, t: usize, u: Option<&[f64]>, out: &mut [f64]) -> Option<Result<()>> {
        let hess = self.hess.as_ref()?;
        Some(self.call(hess, "its Hessian", points, k, t, u, &[self.dim_out, self.dim_in, self.dim_in], out))
    }
}

/// f, h or g from Python: a callable or `("cfunc", address)` (with the Jacobian and Hessians
/// given, either kind), or a built-in given as `(kind, params)`: `("coordinated_turn", (dt,))`,
/// `("range_bearing", (sx, sy))`, `("linear", A)`.
fn point_function(
    name: &'static str,
    spec: &Bound<'_, PyAny>,
    (jac, hess): (Option<&Bound<'_, PyAny>>, Option<&Bound<'_, PyAny>>),
    n: usize,
    shape: &[usize],
) -> PyResult<Arc<dyn PointFunction>> {
    let dim_out = shape.iter().product();
    let built_in = spec.cast::<PyTuple>().ok().map(|t| Ok::<_, PyErr>((t.get_item(0)?.extract::<String>()?, t)));
    if let Some((kind, tuple)) = built_in.transpose()?.filter(|(kind, _)| kind != "cfunc") {
        let params = tuple.get_item(1)?;
        let built: Arc<dyn PointFunction> = match kind.as_str() {
            "coordinated_turn" => Arc::new(CoordinatedTurn::new(params.extract::<(f64,)>()?.0)?),
            "range_bearing" => {
                let (sx, sy): (f64, f64) = params.extract()?;
                Arc::new(RangeBearing::new([sx, sy], n)?)
            }
            "bearing" => {
                let (sx, sy): (f64, f64) = params.extract()?;
                Arc::new(Bearing::new([sx, sy], n)?)
            }
            "range_bearing_elevation" => {
                let (sx, sy, sz): (f64, f64, f64) = params.extract()?;
                Arc::new(RangeBearingElevation::new([sx, sy, sz], n)?)
            }
            "ungm" => Arc::new(Ungm::transition()),
            "ungm_measurement" => Arc::new(Ungm::measurement()),
            "constant" => {
                let a: PyReadonlyArrayDyn<'_, f64> = params.extract()?;
                Arc::new(ConstantMap::new(contiguous(name, &a)?.to_vec(), n))
            }
            "linear" => {
                let a: PyReadonlyArrayDyn<'_, f64> = params.extract()?;
                let shape = a.shape().to_vec();
                Arc::new(LinearMap::new(contiguous(name, &a)?.to_vec(), shape[0], shape[1])?)
            }
            other => return Err(KfastError::new_err(format!("{name}: unknown built-in model {other:?}"))),
        };
        if built.dim_in() != n || built.dim_out() != dim_out {
            return Err(KfastError::new_err(format!(
                "{name}: the built-in model maps {} states to {} numbers, expected {n} to {dim_out}",
                built.dim_in(),
                built.dim_out()
            )));
        }
        return Ok(built);
    }
    let derivative = |what: &str, d: Option<&Bound<'_, PyAny>>| d.map(|d| Callee::of(what, d)).transpose();
    Ok(Arc::new(UserFunction {
        name,
        fun: Callee::of(name, spec)?,
        jac: derivative(&format!("jac_{name}"), jac)?,
        hess: derivative(&format!("hess_{name}"), hess)?,
        dim_in: n,
        dim_out,
        shape: shape.to_vec(),
    }))
}

fn ekf_options(form: &str, iterations: usize, iteration: &str, order: usize) -> PyResult<EkfOptions> {
    if !matches!(order, 1 | 2) {
        return Err(KfastError::new_err(format!("order: expected 1 or 2, got {order}")));
    }
    Ok(EkfOptions {
        form: parse_form(form)?,
        iterations,
        iteration: parse_iteration(iteration)?,
        second_order: order == 2,
    })
}

/// The filter `method` ("ekf" with its options, or "ukf" with its points).
fn parse_method(
    method: &str,
    points: PointsSpec<'_>,
    (form, iterations, iteration, order): (&str, usize, &str, usize),
) -> PyResult<SmoothMethod> {
    match method {
        "ekf" => Ok(SmoothMethod::Ekf(ekf_options(form, iterations, iteration, order)?)),
        "ukf" => Ok(SmoothMethod::Ukf(ukf_options(points, form)?)),
        other => Err(KfastError::new_err(format!("method: expected \"ekf\" or \"ukf\", got {other:?}"))),
    }
}

/// The UKF's sigma points and form ("standard" or "sqrt").
fn ukf_options(points: PointsSpec<'_>, form: &str) -> PyResult<UkfOptions> {
    let form = match form {
        "standard" => UkfForm::Standard,
        "sqrt" => UkfForm::SquareRoot,
        other => {
            return Err(KfastError::new_err(format!("form: the UKF's form is \"standard\" or \"sqrt\", got {other:?}")))
        }
    };
    Ok(UkfOptions { points: sigma_points(points)?, form })
}

fn parse_iteration(iteration: &str) -> PyResult<Iteration> {
    match iteration {
        "book" => Ok(Iteration::Book),
        "gauss-newton" => Ok(Iteration::GaussNewton),
        other => Err(KfastError::new_err(format!("iteration: expected \"book\" or \"gauss-newton\", got {other:?}"))),
    }
}

/// `kfast.sigma.SigmaPoints._spec()`: `(kind, alpha, beta, kappa, unit, Wm, Wc)`, the three
/// arrays given for a custom set only (unit points (k, n), weights (k,)).
type PointsSpec<'py> = (String, f64, f64, f64, Option<Array<'py>>, Option<Array<'py>>, Option<Array<'py>>);

/// The sigma points of a [`PointsSpec`].
fn sigma_points((kind, alpha, beta, kappa, unit, wm, wc): PointsSpec<'_>) -> PyResult<SigmaPoints> {
    let values = |arg: &str, a: &Option<Array<'_>>| -> PyResult<Vec<f64>> {
        let a = a.as_ref().ok_or_else(|| KfastError::new_err(format!("points: a custom set needs {arg}")))?;
        Ok(a.as_slice().map_err(|_| KfastError::new_err(format!("points: {arg} is not contiguous")))?.to_vec())
    };
    match kind.as_str() {
        "merwe" => Ok(SigmaPoints::Merwe { alpha, beta, kappa }),
        "julier" => Ok(SigmaPoints::Julier { kappa }),
        "cubature" => Ok(SigmaPoints::Cubature),
        "custom" => {
            let n = unit.as_ref().filter(|u| u.ndim() == 2).map_or(0, |u| u.shape()[1]);
            let set = CustomPoints::new(values("points", &unit)?, n, values("Wm", &wm)?, values("Wc", &wc)?)?;
            Ok(SigmaPoints::Custom(Arc::new(set)))
        }
        other => Err(KfastError::new_err(format!("points: unknown sigma-point set {other:?}"))),
    }
}

/// The compiled nonlinear model; `kfast.NonlinearModel` wraps it.
#[pyclass(module = "kfast._kfast", name = "NonlinearModel", frozen)]
pub(super) struct PyNonlinearModel {
    inner: nonlinear::NonlinearModel,
    /// The same model, shared with the streaming filters made from it.
    shared: Arc<nonlinear::NonlinearModel>,
}

#[pymethods]
impl PyNonlinearModel {
    #[new]
    #[pyo3(signature = (f, h, Q, R, n, m, angles, jac_f=None, jac_h=None, hess_f=None, hess_h=None, g=None, noise_input=false))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn new(
        f: &Bound<'_, PyAny>,
        h: &Bound<'_, PyAny>,
        Q: Array<'_>,
        R: Array<'_>,
        n: usize,
        m: usize,
        angles: Vec<usize>,
        jac_f: Option<&Bound<'_, PyAny>>,
        jac_h: Option<&Bound<'_, PyAny>>,
        hess_f: Option<&Bound<'_, PyAny>>,
        hess_h: Option<&Bound<'_, PyAny>>,
        g: Option<&Bound<'_, PyAny>>,
        noise_input: bool,
    ) -> PyResult<Self> {
        let (q, r) = (step_matrix("Q", &Q)?, step_matrix("R", &R)?);
        // with the noise an input of f, f takes the n + r numbers (x, w)
        let f_inputs = if noise_input { n + q.rows() } else { n };
        let f = point_function("f", f, (jac_f, hess_f), f_inputs, &[n])?;
        let h = point_function("h", h, (jac_h, hess_h), n, &[m])?;
        let inner = match g {
            None if noise_input => nonlinear::NonlinearModel::with_noise_input(f, h, q, r, angles)?,
            None => nonlinear::NonlinearModel::new(f, h, q, r, angles)?,
            Some(_) if noise_input => {
                return Err(KfastError::new_err("g: a noise gain and the noise as an input of f exclude each other"))
            }
            Some(g) => {
                let g = point_function("g", g, (None, None), n, &[n, q.rows()])?;
                nonlinear::NonlinearModel::with_noise_gain(f, g, h, q, r, angles)?
            }
        };
        Ok(PyNonlinearModel { shared: Arc::new(inner.clone()), inner })
    }

    /// The extended Kalman filter; a dict of the FilterResult fields named in `outputs`.
    #[pyo3(signature = (y, x0, P0, outputs, u=None, form="joseph", iterations=0, iteration="book", order=1))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn ekf<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        outputs: Vec<String>,
        u: Option<Array<'py>>,
        form: &str,
        iterations: usize,
        iteration: &str,
        order: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let options = ekf_options(form, iterations, iteration, order)?;
        self.run(py, y, x0, P0, u, &outputs, |model, y, u, x0, p0, out| {
            nonlinear::ekf_into(model, y, u, x0, p0, options, out)
        })
    }

    /// The extended (`method="ekf"`) or unscented (`"ukf"`, with `points`) RTS smoother: a
    /// dict of the filter's fields (all but K_pred) and x_smooth, P_smooth, P_lag1.
    #[pyo3(signature = (y, x0, P0, method, points, u=None, form="joseph", iterations=0, iteration="book", order=1))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn smooth<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        method: &str,
        points: PointsSpec<'py>,
        u: Option<Array<'py>>,
        form: &str,
        iterations: usize,
        iteration: &str,
        order: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let method = parse_method(method, points, (form, iterations, iteration, order))?;
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let (n, m, steps) = (self.inner.n_states(), self.inner.n_obs(), y.steps());
        let fields: Vec<String> =
            FILTER_FIELDS.iter().map(|f| f.name.to_string()).filter(|name| name != "K_pred").collect();
        let mut out = OutArrays::for_filter(py, steps, n, m, Some(&fields))?.with_written_in_full(
            py,
            &[("x_smooth", &[steps, n]), ("P_smooth", &[steps, n, n]), ("P_lag1", &[steps, n, n])],
        )?;
        let names = out.names.clone();
        let mut slices = out.slices()?;
        let model = &self.inner;
        let loglik = py.detach(|| {
            let (filt, smoothed) = outputs(&names, &mut slices);
            nonlinear::smooth_nonlinear_into(model, y, u, x0, p0, method, filt, smoothed)
        })?;
        drop(slices);
        let dict = out.into_dict(py)?;
        dict.set_item("loglik", loglik)?;
        Ok(dict)
    }

    /// The unscented Kalman filter with the sigma points `(kind, alpha, beta, kappa)`.
    #[pyo3(signature = (y, x0, P0, outputs, points, u=None, form="standard"))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn ukf<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        outputs: Vec<String>,
        points: PointsSpec<'py>,
        u: Option<Array<'py>>,
        form: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let options = ukf_options(points, form)?;
        self.run(py, y, x0, P0, u, &outputs, |model, y, u, x0, p0, out| {
            nonlinear::ukf_into(model, y, u, x0, p0, options.clone(), out)
        })
    }

    /// The particle filter: a dict with x_filt (T, n), P_filt (T, n, n), ess (T,), resampled
    /// (T,) bool, loglik_t (T,), loglik and, with `keep` "last" or "all", particles and log_weights.
    #[pyo3(signature = (y, x0, P0, n_particles, resample="multinomial", ess_threshold=None, seed=0, keep=None, u=None, threads=None, likelihood=None, regularize=None, copies=1, rejuvenate=None))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn particle_filter<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        n_particles: usize,
        resample: &'py str,
        ess_threshold: Option<f64>,
        seed: u64,
        keep: Option<&str>,
        u: Option<Array<'py>>,
        threads: Option<usize>,
        likelihood: Option<LikelihoodSpec<'py>>,
        regularize: Option<f64>,
        copies: usize,
        rejuvenate: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let args = ParticleArgs {
            particles: n_particles,
            copies,
            resample,
            ess_threshold,
            seed,
            threads,
            likelihood,
            regularize,
            rejuvenate,
        };
        let options = particle_options(args, self.inner.n_states())?;
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let (n, steps) = (self.inner.n_states(), y.steps());
        let kept_steps = match keep {
            None => 0,
            Some("last") => 1,
            Some("all") => steps,
            Some(other) => {
                return Err(KfastError::new_err(format!("keep: expected None, \"last\" or \"all\", got {other:?}")))
            }
        };
        crate::core::alloc::check_f64_arrays(
            "n_particles",
            &[&[kept_steps, n_particles, n + 1], &[steps, n + 1, n + 1]],
        )?;
        let mut x_filt = vec![0.0; steps * n];
        let mut p_filt = vec![0.0; steps * n * n];
        let (mut ess, mut resampled, mut loglik_t) = (vec![0.0; steps], vec![false; steps], vec![0.0; steps]);
        let mut particles = vec![0.0; kept_steps * n_particles * n];
        let mut log_weights = vec![0.0; kept_steps * n_particles];
        let model = &self.inner;
        let loglik = py.detach(|| {
            let out = nonlinear::ParticleOutputs {
                x_filt: &mut x_filt,
                p_filt: &mut p_filt,
                ess: &mut ess,
                resampled: &mut resampled,
                loglik_t: &mut loglik_t,
                particles: (kept_steps > 0).then_some(&mut particles[..]),
                log_weights: (kept_steps > 0).then_some(&mut log_weights[..]),
            };
            nonlinear::particle_filter_into(model, y, u, x0, p0, options, out)
        })?;
        let dict = PyDict::new(py);
        let shaped = |v: Vec<f64>, shape: &[usize]| -> PyResult<Bound<'py, PyAny>> {
            Ok(v.into_pyarray(py).reshape(shape.to_vec())?.into_any())
        };
        dict.set_item("x_filt", shaped(x_filt, &[steps, n])?)?;
        dict.set_item("P_filt", shaped(p_filt, &[steps, n, n])?)?;
        dict.set_item("ess", ess.into_pyarray(py))?;
        dict.set_item("resampled", resampled.into_pyarray(py))?;
        dict.set_item("loglik_t", loglik_t.into_pyarray(py))?;
        dict.set_item("loglik", loglik)?;
        if let Some(keep) = keep {
            let (p_shape, w_shape) = if keep == "last" {
                (vec![n_particles, n], vec![n_particles])
            } else {
                (vec![steps, n_particles, n], vec![steps, n_particles])
            };
            dict.set_item("particles", shaped(particles, &p_shape)?)?;
            dict.set_item("log_weights", shaped(log_weights, &w_shape)?)?;
        }
        Ok(dict)
    }

    /// The EKF (`method="ekf"`) or UKF (`"ukf"`, with `points`) of many series at once: a dict
    /// with x_filt (B, T, n), P_filt (B, T, n, n; absent without covariances) and loglik (B,).
    #[pyo3(signature = (Y, x0, P0, method, points, u=None, return_covs=true, threads=None, form="joseph", iterations=0, iteration="book", order=1))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn batch<'py>(
        &self,
        py: Python<'py>,
        Y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        method: &str,
        points: PointsSpec<'py>,
        u: Option<Array<'py>>,
        return_covs: bool,
        threads: Option<usize>,
        form: &str,
        iterations: usize,
        iteration: &str,
        order: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let method = parse_method(method, points, (form, iterations, iteration, order))?;
        let (n, m) = (self.inner.n_states(), self.inner.n_obs());
        let y = super::data("Y", &Y, 3)?;
        let (bs, steps) = (Y.shape()[0], Y.shape()[1]);
        if Y.shape()[2] != m {
            return Err(KfastError::new_err(format!(
                "Y: expected shape (B, T, {m}) for m = {m} outputs, got {:?}",
                Y.shape()
            )));
        }
        let x0 = batch_part("x0", &x0, &[n], bs)?;
        let p0 = batch_part("P0", &P0, &[n, n], bs)?;
        let (u, u_shared) = match &u {
            None => (None, false),
            Some(u) => {
                let shape = u.shape();
                let per_series = shape.len() == 3 && shape[0] == bs && shape[1] == steps;
                if !(per_series || (shape.len() == 2 && shape[0] == steps)) {
                    return Err(KfastError::new_err(format!(
                        "u: expected shape ({steps}, k) (shared) or ({bs}, {steps}, k) (one per series), got {shape:?}"
                    )));
                }
                (Some(contiguous("u", u)?), !per_series)
            }
        };
        let batch = crate::Batch { y, series: bs, steps, u, u_shared, x0, p0 };
        let model = &self.inner;
        let covs = return_covs.then(|| vec![bs, steps, n, n]);
        let (dict, ()) = run_batch(py, [bs, steps, n], covs, |out| match method {
            SmoothMethod::Ekf(options) => nonlinear::ekf_batch(model, batch, options, out, threads),
            SmoothMethod::Ukf(points) => nonlinear::ukf_batch(model, batch, points, out, threads),
        })?;
        Ok(dict)
    }
}

impl PyNonlinearModel {
    /// Allocates the outputs, runs `filter` without the GIL, returns the dict of outputs.
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn run<'py>(
        &self,
        py: Python<'py>,
        y: Array<'py>,
        x0: Array<'py>,
        P0: Array<'py>,
        u: Option<Array<'py>>,
        outputs: &[String],
        filter: impl Fn(
                &nonlinear::NonlinearModel,
                crate::Series<'_>,
                Option<crate::Series<'_>>,
                &[f64],
                &[f64],
                crate::FilterOutputs<'_>,
            ) -> Result<f64>
            + Send
            + Sync,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (y, u) = series(&y, u.as_ref())?;
        let (x0, p0) = prior(&x0, &P0, self.inner.n_states())?;
        let (n, m) = (self.inner.n_states(), self.inner.n_obs());
        let mut out = OutArrays::for_filter(py, y.steps(), n, m, Some(outputs))?;
        let names = out.names.clone();
        let mut slices = out.slices()?;
        let model = &self.inner;
        let loglik = py.detach(|| filter(model, y, u, x0, p0, filter_outputs(&names, &mut slices)))?;
        drop(slices);
        let dict = out.into_dict(py)?;
        dict.set_item("loglik", loglik)?;
        Ok(dict)
    }
}

/// The streaming EKF or UKF; `kfast.ExtendedKalmanFilter` and `kfast.UnscentedKalmanFilter`
/// wrap it.
#[pyclass(module = "kfast._kfast", name = "NonlinearKalmanFilter")]
pub(super) struct PyNonlinearKalmanFilter {
    pub(super) inner: nonlinear::NonlinearKalmanFilter,
}

#[pymethods]
impl PyNonlinearKalmanFilter {
    /// `method` "ekf" (with form, iterations, iteration, order) or "ukf" (with points).
    #[new]
    #[pyo3(signature = (model, x0, P0, method, points, form="joseph", iterations=0, iteration="book", order=1))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn new(
        model: &PyNonlinearModel,
        x0: Array<'_>,
        P0: Array<'_>,
        method: &str,
        points: PointsSpec<'_>,
        form: &str,
        iterations: usize,
        iteration: &str,
        order: usize,
    ) -> PyResult<Self> {
        let (x0, p0) = prior(&x0, &P0, model.inner.n_states())?;
        let shared = Arc::clone(&model.shared);
        let inner = match method {
            "ekf" => {
                nonlinear::NonlinearKalmanFilter::ekf(shared, x0, p0, ekf_options(form, iterations, iteration, order)?)?
            }
            "ukf" => nonlinear::NonlinearKalmanFilter::ukf(shared, x0, p0, ukf_options(points, form)?)?,
            other => return Err(KfastError::new_err(format!("method: expected \"ekf\" or \"ukf\", got {other:?}"))),
        };
        Ok(PyNonlinearKalmanFilter { inner })
    }

    /// The update with y(t); with `h` (a callable or a built-in spec) and `R`, by that sensor.
    #[pyo3(signature = (y, u=None, h=None, R=None, angles=None))]
    #[allow(non_snake_case)]
    fn update(
        &mut self,
        py: Python<'_>,
        y: Array<'_>,
        u: Option<Array<'_>>,
        h: Option<&Bound<'_, PyAny>>,
        R: Option<Array<'_>>,
        angles: Option<Vec<usize>>,
    ) -> PyResult<()> {
        let y = super::data("y", &y, 1)?;
        let u = u.as_ref().map(|u| super::data("u", u, 1)).transpose()?;
        let inner = &mut self.inner;
        match (h, R) {
            (None, None) => Ok(py.detach(|| inner.update(y, u))?),
            (Some(h), Some(r)) => {
                let m = r.shape().first().copied().unwrap_or(0);
                let r = super::data("R", &r, 2)?;
                let h = point_function("h", h, (None, None), inner.n_states(), &[m])?;
                let angles = angles.unwrap_or_default();
                let sensor = nonlinear::Sensor { h: &*h, r, angles: &angles };
                Ok(py.detach(|| inner.update_with(sensor, y, u))?)
            }
            _ => Err(KfastError::new_err("h, R: a second sensor needs both its h and its R")),
        }
    }

    /// The time update to t + 1.
    #[pyo3(signature = (u=None))]
    fn predict(&mut self, py: Python<'_>, u: Option<Array<'_>>) -> PyResult<()> {
        let u = u.as_ref().map(|u| super::data("u", u, 1)).transpose()?;
        let inner = &mut self.inner;
        Ok(py.detach(|| inner.predict(u))?)
    }

    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        super::to_array(py, self.inner.x(), &[self.inner.x().len()])
    }

    #[getter(P)]
    fn p<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.inner.x().len();
        super::to_array(py, self.inner.p(), &[n, n])
    }

    #[getter]
    fn t(&self) -> usize {
        self.inner.t()
    }

    #[getter]
    fn loglik(&self) -> f64 {
        self.inner.loglik()
    }
}

/// The streaming particle filter; `kfast.ParticleFilter` wraps it.
#[pyclass(module = "kfast._kfast", name = "ParticleFilter")]
pub(super) struct PyParticleFilter {
    inner: nonlinear::ParticleFilter,
}

#[pymethods]
impl PyParticleFilter {
    #[new]
    #[pyo3(signature = (model, x0, P0, n_particles, resample="multinomial", ess_threshold=None, seed=0, threads=None, likelihood=None, regularize=None, copies=1, rejuvenate=None))]
    #[allow(non_snake_case)]
    #[allow(clippy::too_many_arguments)]
    fn new<'py>(
        py: Python<'py>,
        model: &PyNonlinearModel,
        x0: Array<'py>,
        P0: Array<'py>,
        n_particles: usize,
        resample: &'py str,
        ess_threshold: Option<f64>,
        seed: u64,
        threads: Option<usize>,
        likelihood: Option<LikelihoodSpec<'py>>,
        regularize: Option<f64>,
        copies: usize,
        rejuvenate: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Self> {
        let (x0, p0) = prior(&x0, &P0, model.inner.n_states())?;
        let args = ParticleArgs {
            particles: n_particles,
            copies,
            resample,
            ess_threshold,
            seed,
            threads,
            likelihood,
            regularize,
            rejuvenate,
        };
        let options = particle_options(args, model.inner.n_states())?;
        let shared = Arc::clone(&model.shared);
        let inner = py.detach(|| nonlinear::ParticleFilter::new(shared, x0, p0, options))?;
        Ok(PyParticleFilter { inner })
    }

    /// The update with y(t); returns its estimate of log p(y(t) | y(0..t-1)).
    #[pyo3(signature = (y, u=None))]
    fn update(&mut self, py: Python<'_>, y: Array<'_>, u: Option<Array<'_>>) -> PyResult<f64> {
        let y = super::data("y", &y, 1)?;
        let u = u.as_ref().map(|u| super::data("u", u, 1)).transpose()?;
        let inner = &mut self.inner;
        Ok(py.detach(|| inner.update(y, u))?)
    }

    /// Resampling if due and the time update; whether it resampled.
    #[pyo3(signature = (u=None))]
    fn predict(&mut self, py: Python<'_>, u: Option<Array<'_>>) -> PyResult<bool> {
        let u = u.as_ref().map(|u| super::data("u", u, 1)).transpose()?;
        let inner = &mut self.inner;
        Ok(py.detach(|| inner.predict(u))?)
    }

    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        super::to_array(py, self.inner.x(), &[self.inner.x().len()])
    }

    #[getter(P)]
    fn p<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.inner.x().len();
        super::to_array(py, self.inner.p(), &[n, n])
    }

    #[getter]
    fn particles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.inner.x().len();
        let particles = self.inner.particles();
        super::to_array(py, particles, &[particles.len() / n, n])
    }

    #[getter]
    fn log_weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let mut out = vec![0.0; self.inner.particles().len() / self.inner.x().len()];
        self.inner.log_weights(&mut out);
        super::to_array(py, &out, &[out.len()])
    }

    #[getter]
    fn ess(&self) -> f64 {
        self.inner.ess()
    }

    #[getter]
    fn t(&self) -> usize {
        self.inner.t()
    }

    #[getter]
    fn loglik(&self) -> f64 {
        self.inner.loglik()
    }
}

/// A quantizing sensor from Python: (delta, low, high), the bounds optional.
type Quantizer<'py> = (Array<'py>, Option<Array<'py>>, Option<Array<'py>>);
/// The particle filter's likelihood from Python: ("student_t", ν, None), ("uniform", 0, None),
/// ("quantized", 0, quantizer) or ("user", 0, callable or ("cfunc", address)); None is the
/// Gaussian.
type LikelihoodSpec<'py> = (String, f64, Option<Bound<'py, PyAny>>);

/// The particle filter's settings from Python, as its methods take them.
struct ParticleArgs<'py> {
    particles: usize,
    copies: usize,
    resample: &'py str,
    ess_threshold: Option<f64>,
    seed: u64,
    threads: Option<usize>,
    likelihood: Option<LikelihoodSpec<'py>>,
    regularize: Option<f64>,
    rejuvenate: Option<Bound<'py, PyAny>>,
}

/// The particle filter's options from Python's arguments, for a model of n states.
fn particle_options(args: ParticleArgs<'_>, n: usize) -> PyResult<nonlinear::ParticleOptions> {
    use nonlinear::MeasurementLikelihood as Kind;
    let resampling = nonlinear::Resampling::from_name(args.resample)?;
    let user = |name: &'static str, spec: &Bound<'_, PyAny>, shape: Vec<usize>| -> PyResult<_> {
        Ok(Arc::new(UserParticleFunction { name, fun: Callee::of(name, spec)?, n, shape }))
    };
    let likelihood = match args.likelihood {
        None => Kind::Gaussian,
        Some((kind, nu, extra)) => match (kind.as_str(), extra) {
            ("student_t", _) => Kind::StudentT { nu },
            ("uniform", _) => Kind::Uniform,
            ("quantized", Some(quantizer)) => {
                let (delta, low, high): Quantizer<'_> = quantizer.extract()?;
                Kind::Quantized(quantized_sensor(contiguous("delta", &delta)?, low.as_ref(), high.as_ref())?)
            }
            ("user", Some(fun)) => Kind::User(user("likelihood", &fun, vec![])?),
            (other, _) => return Err(KfastError::new_err(format!("likelihood: unknown kind {other:?}"))),
        },
    };
    let rejuvenate: Option<Arc<dyn nonlinear::ParticleFunction>> = match &args.rejuvenate {
        None => None,
        Some(spec) => Some(user("move", spec, vec![n])?),
    };
    Ok(nonlinear::ParticleOptions {
        particles: args.particles,
        copies: args.copies,
        resampling,
        ess_threshold: args.ess_threshold,
        seed: args.seed,
        threads: args.threads,
        likelihood,
        regularize: args.regularize,
        rejuvenate,
    })
}

/// The causal running median of window `n` of each column of `u` (T, k); `mode` "valid" or
/// "grow".
#[pyfunction]
pub(super) fn median_filter<'py>(py: Python<'py>, u: Array<'py>, n: usize, mode: &str) -> PyResult<Bound<'py, PyAny>> {
    order_filter(py, u, n, mode, nonlinear::median_filter)
}

/// The causal running mean of window `n` of each column of `u` (T, k).
#[pyfunction]
pub(super) fn mean_filter<'py>(py: Python<'py>, u: Array<'py>, n: usize, mode: &str) -> PyResult<Bound<'py, PyAny>> {
    order_filter(py, u, n, mode, nonlinear::mean_filter)
}

type WindowFilter = fn(&[f64], usize, usize, usize, nonlinear::StartUp) -> Result<Vec<f64>>;

fn order_filter<'py>(
    py: Python<'py>,
    u: Array<'py>,
    n: usize,
    mode: &str,
    filter: WindowFilter,
) -> PyResult<Bound<'py, PyAny>> {
    let start = nonlinear::StartUp::from_name(mode)?;
    let shape = u.shape().to_vec();
    if shape.len() != 2 {
        return Err(KfastError::new_err(format!("u: expected shape (T, k), got {shape:?}")));
    }
    let values = contiguous("u", &u)?;
    let out = py.detach(|| filter(values, shape[0], shape[1], n, start))?;
    Ok(out.into_pyarray(py).reshape(shape)?.into_any())
}

/// Q_Δ(x) of each row of `x` (.., m), component i with step `delta[i]` (Söderström (9.101),
/// half up).
#[pyfunction]
pub(super) fn quantize<'py>(py: Python<'py>, x: Array<'py>, delta: Array<'py>) -> PyResult<Bound<'py, PyAny>> {
    let shape = x.shape().to_vec();
    let (values, steps) = (contiguous("x", &x)?, contiguous("delta", &delta)?);
    let mut out = vec![0.0; values.len()];
    py.detach(|| nonlinear::quantize_into(values, steps, &mut out))?;
    Ok(out.into_pyarray(py).reshape(shape)?.into_any())
}

/// The log-likelihood of the quantized measurement `y` (m,) for each row of `y_hat` (M, m);
/// see `nonlinear::quantized_loglik`.
#[pyfunction]
#[pyo3(signature = (y, y_hat, std, delta, low=None, high=None))]
pub(super) fn quantized_loglik<'py>(
    py: Python<'py>,
    y: Array<'py>,
    y_hat: Array<'py>,
    std: Array<'py>,
    delta: Array<'py>,
    low: Option<Array<'py>>,
    high: Option<Array<'py>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (y, y_hat) = (contiguous("y", &y)?, contiguous("y_hat", &y_hat)?);
    let (std, delta) = (contiguous("R", &std)?, contiguous("delta", &delta)?);
    let sensor = quantized_sensor(delta, low.as_ref(), high.as_ref())?;
    let rows = if y.is_empty() { 0 } else { y_hat.len() / y.len() };
    let mut out = vec![0.0; rows];
    py.detach(|| nonlinear::quantized_loglik(&sensor, y, y_hat, std, &mut out))?;
    Ok(out.into_pyarray(py).into_any())
}

/// The quantizing sensor of steps `delta` and optional (`low`, `high`) levels.
fn quantized_sensor(
    delta: &[f64],
    low: Option<&Array<'_>>,
    high: Option<&Array<'_>>,
) -> PyResult<nonlinear::QuantizedSensor> {
    let values = |a: &Array<'_>| -> PyResult<Vec<f64>> { Ok(contiguous("bounds", a)?.to_vec()) };
    let bounds = match (low, high) {
        (Some(low), Some(high)) => Some((values(low)?, values(high)?)),
        _ => None,
    };
    Ok(nonlinear::QuantizedSensor::new(delta.to_vec(), bounds)?)
}

/// (mean, second moment, variance) of Q_Δ(x), x "gaussian" or "uniform" with the given mean
/// and standard deviation; see `nonlinear::quantized_moments`.
#[pyfunction]
pub(super) fn quantized_moments(delta: f64, mean: f64, std: f64, distribution: &str) -> PyResult<(f64, f64, f64)> {
    let dist = match distribution {
        "gaussian" => nonlinear::Distribution::Gaussian,
        "uniform" => nonlinear::Distribution::Uniform,
        other => {
            return Err(KfastError::new_err(format!(
                "distribution: expected \"gaussian\" or \"uniform\", got {other:?}"
            )))
        }
    };
    let q = nonlinear::quantized_moments(delta, mean, std, dist)?;
    Ok((q.mean, q.second_moment, q.var))
}
