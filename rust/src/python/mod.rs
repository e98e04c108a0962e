//! The pyo3 module `kfast._kfast`: conversion between NumPy arrays and the Rust API, and
//! nothing else (no numerics here). The Python package `kfast` wraps it; arrays arrive here
//! already converted to C-contiguous float64 by `kfast._arrays.as_float64`.

mod control;
mod diagnostics;
mod model;
mod multiple;
mod nonlinear;
mod poly;
mod solvers;

/// The extension's own Rust allocations (faer's matrices in the solvers, workspaces) use
/// mimalloc: small-matrix solvers spent about half their time in the system malloc/free.
/// Only the Python extension sets it; Rust users of the crate keep their allocator.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;
mod streaming;

use numpy::ndarray::IxDyn;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple};

use crate::core::alloc::check_f64_arrays;
use crate::error::Error;
use crate::linear::filter::{FilterOutputs, Series, UpdateForm, FILTER_FIELDS};
use crate::linear::smoother::SmoothOutputs;

create_exception!(kfast, KfastError, PyValueError, "Invalid input to kfast (a ValueError).");
create_exception!(
    kfast,
    NoStabilizingSolutionError,
    KfastError,
    "A Riccati equation has no stabilizing solution (a ValueError)."
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
            Error::NoStabilizingSolution { .. } => NoStabilizingSolutionError::new_err(err.to_string()),
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
        return Err(KfastError::new_err(format!("{arg}: expected a {ndim}-D array, got shape {:?}", arr.shape())));
    }
    contiguous(arg, arr)
}

/// The data of a float64 array of any shape, which must be contiguous (`arg` names it).
fn contiguous<'a>(arg: &str, arr: &'a PyReadonlyArrayDyn<'_, f64>) -> PyResult<&'a [f64]> {
    arr.as_slice().map_err(|_| KfastError::new_err(format!("{arg}: array is not contiguous")))
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

/// A count or index argument that must not be negative.
fn non_negative(arg: &str, value: i64) -> PyResult<usize> {
    usize::try_from(value).map_err(|_| KfastError::new_err(format!("{arg}: must be ≥ 0, got {value}")))
}

/// Calls `kfast._args.<check>(*args)`: the one place the scalar arguments (counts, choices,
/// flags) are checked, for the classes that Python reaches without a wrapper.
fn checked_arg<'py>(
    py: Python<'py>,
    check: &str,
    args: impl pyo3::call::PyCallArgs<'py>,
) -> PyResult<Bound<'py, PyAny>> {
    py.import("kfast._args")?.getattr(check)?.call1(args)
}

/// A count argument (a non-negative integer below 2⁶³), checked by `kfast._args.index`.
fn index_arg(py: Python<'_>, name: &str, value: &Bound<'_, PyAny>) -> PyResult<usize> {
    checked_arg(py, "index", (name, value))?.extract()
}

/// The update forms by their Python names.
const FORMS: [(&str, UpdateForm); 6] = [
    ("joseph", UpdateForm::Joseph),
    ("standard", UpdateForm::Standard),
    ("sqrt", UpdateForm::SquareRoot),
    ("ud", UpdateForm::UD),
    ("information", UpdateForm::Information),
    ("sequential", UpdateForm::Sequential),
];

/// The `form=` argument (default Joseph), checked by `kfast._args.choice`; the estimators
/// that offer only the covariance forms refuse the others themselves.
fn form_arg(py: Python<'_>, value: Option<&Bound<'_, PyAny>>) -> PyResult<UpdateForm> {
    match value {
        None => Ok(UpdateForm::Joseph),
        Some(value) => {
            let names = PyTuple::new(py, FORMS.iter().map(|(name, _)| *name))?;
            parse_form(&checked_arg(py, "choice", ("form", value, names))?.extract::<String>()?)
        }
    }
}

fn parse_form(form: &str) -> PyResult<UpdateForm> {
    FORMS.iter().find(|(name, _)| *name == form).map(|(_, f)| *f).ok_or_else(|| {
        let names: Vec<&str> = FORMS.iter().map(|(name, _)| *name).collect();
        KfastError::new_err(format!("form: expected one of {names:?}, got {form:?}"))
    })
}

/// A 2-D float64 array as a [`Series`] (`arg` names it in errors).
fn series_of<'a>(arg: &'static str, a: &'a PyReadonlyArrayDyn<'_, f64>) -> PyResult<Series<'a>> {
    Ok(Series::new(arg, data(arg, a, 2)?, a.shape()[0], a.shape()[1])?)
}

/// `y` (T, m) and `u` (T, k) as [`Series`].
fn series<'a>(
    y: &'a PyReadonlyArrayDyn<'_, f64>,
    u: Option<&'a PyReadonlyArrayDyn<'_, f64>>,
) -> PyResult<(Series<'a>, Option<Series<'a>>)> {
    Ok((series_of("y", y)?, u.map(|u| series_of("u", u)).transpose()?))
}

/// A vector argument as a float64 array: float64 contiguous 1-D arrays are read in place,
/// anything else goes through `kfast._arrays.as_float64` (lists, ints, float32, scalars,
/// masked arrays — an ndarray subclass whose mask must not be skipped ...).
fn vector<'py>(py: Python<'py>, name: &str, value: &Bound<'py, PyAny>) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    if let Ok(arr) = value.cast_exact::<PyArrayDyn<f64>>() {
        if arr.is_c_contiguous() && arr.ndim() == 1 {
            return Ok(arr.readonly());
        }
    }
    let arr = as_float64(py, name, value)?;
    let arr = if arr.ndim() == 0 { arr.reshape(IxDyn(&[1]))?.cast_into::<PyArrayDyn<f64>>()? } else { arr };
    if arr.ndim() != 1 {
        return Err(KfastError::new_err(format!("{name}: expected a 1-D array, got shape {:?}", arr.shape())));
    }
    Ok(arr.readonly())
}

/// The data of an array `vector` returned.
fn slice<'a>(name: &str, arr: &'a PyReadonlyArrayDyn<'_, f64>) -> PyResult<&'a [f64]> {
    data(name, arr, 1)
}

/// A vector as a new NumPy array of the given shape.
fn to_array<'py>(py: Python<'py>, values: &[f64], shape: &[usize]) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    numpy::PyArray1::from_slice(py, values).reshape(IxDyn(shape))
}

/// Named output arrays, allocated once with the GIL held and then filled without it.
struct OutArrays<'py> {
    names: Vec<&'static str>,
    arrays: Vec<Bound<'py, PyArrayDyn<f64>>>,
}

impl<'py> OutArrays<'py> {
    /// Zeroed arrays of the given names and shapes; `arg` is the argument their sizes come
    /// from (refused when they would not fit in memory).
    fn new(py: Python<'py>, arg: &'static str, specs: &[(&'static str, &[usize])]) -> PyResult<Self> {
        check_sizes(arg, specs)?;
        Ok(OutArrays {
            names: specs.iter().map(|s| s.0).collect(),
            arrays: specs.iter().map(|s| PyArrayDyn::<f64>::zeros(py, IxDyn(s.1), false)).collect(),
        })
    }

    /// Like [`new`](Self::new) but not zeroed, for outputs the core writes in full before
    /// they reach Python (the filter's and the smoother's: every row of every output is
    /// stored). Zeroing is a pass over memory that costs as much as a third of a
    /// frozen-gain filter step at n = 20, where P(t|t) is most of what is written.
    fn written_in_full(py: Python<'py>, arg: &'static str, specs: &[(&'static str, &[usize])]) -> PyResult<Self> {
        check_sizes(arg, specs)?;
        Ok(OutArrays {
            names: specs.iter().map(|s| s.0).collect(),
            // SAFETY: f64 has no invalid bit patterns and no destructor; every entry is written
            // by the filter/smoother before the array is handed to Python, and an array of a
            // call that fails is dropped unseen.
            arrays: specs.iter().map(|s| unsafe { PyArrayDyn::<f64>::new(py, IxDyn(s.1), false) }).collect(),
        })
    }

    /// The filter's outputs named in `wanted` (all of [`FILTER_FIELDS`] when `None`), written
    /// in full by the filter.
    fn for_filter(py: Python<'py>, steps: usize, n: usize, m: usize, wanted: Option<&[String]>) -> PyResult<Self> {
        let is_field = |name: &str| FILTER_FIELDS.iter().any(|f| f.name == name);
        if let Some(bad) = wanted.and_then(|w| w.iter().find(|name| !is_field(name))) {
            let names: Vec<&str> = FILTER_FIELDS.iter().map(|f| f.name).collect();
            return Err(KfastError::new_err(format!("outputs: unknown field {bad:?}; choose from {names:?}")));
        }
        let chosen: Vec<_> =
            FILTER_FIELDS.iter().filter(|f| wanted.is_none_or(|w| w.iter().any(|x| x == f.name))).collect();
        let shapes: Vec<Vec<usize>> = chosen.iter().map(|f| f.shape_for(steps, n, m)).collect();
        let specs: Vec<(&'static str, &[usize])> =
            chosen.iter().zip(&shapes).map(|(f, s)| (f.name, s.as_slice())).collect();
        Self::written_in_full(py, "y", &specs)
    }

    /// Appends more arrays that the core writes in full (see [`written_in_full`](Self::written_in_full)).
    fn with_written_in_full(mut self, py: Python<'py>, specs: &[(&'static str, &[usize])]) -> PyResult<Self> {
        let more = Self::written_in_full(py, "y", specs)?;
        self.names.extend(more.names);
        self.arrays.extend(more.arrays);
        Ok(self)
    }

    /// Mutable views of every array, in order.
    fn slices(&mut self) -> PyResult<Vec<&mut [f64]>> {
        // SAFETY: the arrays were created by `new` and are not shared with Python until
        // `into_dict`; each is borrowed once here.
        self.arrays
            .iter()
            .map(|a| unsafe { a.as_slice_mut() })
            .collect::<Result<_, _>>()
            .map_err(|e| KfastError::new_err(e.to_string()))
    }

    fn into_dict(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for (name, arr) in self.names.into_iter().zip(self.arrays) {
            dict.set_item(name, arr)?;
        }
        Ok(dict)
    }
}

/// Refuses output arrays that would not fit in memory (NumPy's failure to allocate would
/// otherwise surface as a panic).
fn check_sizes(arg: &'static str, specs: &[(&'static str, &[usize])]) -> PyResult<()> {
    let shapes: Vec<&[usize]> = specs.iter().map(|s| s.1).collect();
    Ok(check_f64_arrays(arg, &shapes)?)
}

/// `check_alloc(arg, shapes)`: raises `KfastError` naming `arg` when float64 arrays of these
/// shapes would not fit in memory (for allocations the Python layer makes, e.g. simulation
/// noise).
#[pyfunction]
fn check_alloc(arg: &str, shapes: Vec<Vec<usize>>) -> PyResult<()> {
    let shapes: Vec<&[usize]> = shapes.iter().map(Vec::as_slice).collect();
    check_f64_arrays("size", &shapes).map_err(|e| match e {
        Error::InvalidArgument { problem, .. } => KfastError::new_err(format!("{arg}: {problem}")),
        other => other.into(),
    })
}

/// `kernel_info()`: how the compiled loops run on this machine, for benchmarks and bug
/// reports: `{"instruction_set": "avx2+fma" | "avx2" | "baseline", "deterministic": bool,
/// "cpu_features": "avx2 fma ...", "fixed_sizes": "..."}`.
#[pyfunction]
fn kernel_info(py: Python<'_>) -> PyResult<Bound<'_, pyo3::types::PyDict>> {
    let info = pyo3::types::PyDict::new(py);
    info.set_item("instruction_set", crate::instruction_set())?;
    info.set_item("deterministic", crate::deterministic())?;
    info.set_item("cpu_features", crate::core::isa::cpu_features())?;
    info.set_item("fixed_sizes", crate::core::dims::FIXED_SIZES)?;
    info.set_item("build", if cfg!(debug_assertions) { "debug" } else { "release" })?;
    info.set_item("target", format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS))?;
    info.set_item("threads", std::thread::available_parallelism().map_or(1, |c| c.get()))?;
    Ok(info)
}

/// `set_deterministic(on)`: see `kfast.set_deterministic`; returns the previous setting.
#[pyfunction]
fn set_deterministic(on: bool) -> bool {
    crate::set_deterministic(on)
}

/// `deterministic()`: whether deterministic mode is on.
#[pyfunction]
fn deterministic() -> bool {
    crate::deterministic()
}

/// `_force_kernel(name)`: every later call runs the loops `name` ("baseline", "avx2",
/// "avx2+fma", "baseline+fma"; `None` undoes it), for tests and benchmark rows. Raises `ValueError` if the
/// name is unknown or this CPU cannot run it.
#[pyfunction]
#[pyo3(signature = (name))]
fn _force_kernel(name: Option<&str>) -> PyResult<()> {
    use crate::core::isa::{force_kernel, Kernel};
    let kernel = match name {
        None => None,
        Some(name) => Some(
            [Kernel::Baseline, Kernel::Avx2, Kernel::Avx2Fma, Kernel::BaselineFma]
                .into_iter()
                .find(|k| k.name() == name)
                .ok_or_else(|| PyValueError::new_err(format!("name: unknown kernel {name:?}")))?,
        ),
    };
    if !force_kernel(kernel) {
        return Err(PyValueError::new_err(format!("name: this CPU cannot run the {name:?} loops")));
    }
    Ok(())
}

/// The fields a smoother adds to the filter's.
const SMOOTH_FIELDS: [&str; 3] = ["x_smooth", "P_smooth", "P_lag1"];

/// The filter's arrays among `names`/`slices` as [`FilterOutputs`] (absent ones are `None`).
fn filter_outputs<'a>(names: &[&'static str], slices: &'a mut [&mut [f64]]) -> FilterOutputs<'a> {
    outputs(names, slices).0
}

/// The filter's and the smoother's arrays among `names`/`slices`.
fn outputs<'a>(names: &[&'static str], slices: &'a mut [&mut [f64]]) -> (FilterOutputs<'a>, SmoothOutputs<'a>) {
    let (mut out, mut sm) = (FilterOutputs::default(), SmoothOutputs::default());
    for (name, slice) in names.iter().zip(slices.iter_mut()) {
        let field = match *name {
            "x_smooth" => &mut sm.x_smooth,
            "P_smooth" => &mut sm.p_smooth,
            "P_lag1" => &mut sm.p_lag1,
            _ => match out.slots().find(|(f, _)| f.name == *name) {
                Some((_, slot)) => slot,
                None => continue,
            },
        };
        *field = Some(&mut **slice);
    }
    (out, sm)
}

/// The letter of a dimension in the shapes exported to Python.
fn dim_name(d: crate::linear::filter::Dim) -> &'static str {
    use crate::linear::filter::Dim;
    match d {
        Dim::Steps => "T",
        Dim::States => "n",
        Dim::Outputs => "m",
    }
}

#[pymodule]
fn _kfast(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // The one version: Cargo.toml's (pyproject.toml takes it too, as a dynamic field).
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // The filter's output names and shapes, from the one table of the crate (the Python
    // FilterResult's fields are checked against it by the tests).
    let fields: Vec<(&str, Vec<&str>)> =
        FILTER_FIELDS.iter().map(|f| (f.name, f.shape.iter().map(|d| dim_name(*d)).collect())).collect();
    m.add("FILTER_FIELDS", fields)?;
    m.add("KfastError", py.get_type::<KfastError>())?;
    m.add("InnovationCovarianceError", py.get_type::<InnovationCovarianceError>())?;
    m.add("NoStabilizingSolutionError", py.get_type::<NoStabilizingSolutionError>())?;
    m.add_class::<model::PyLinearGaussian>()?;
    m.add_class::<nonlinear::PyNonlinearModel>()?;
    m.add_class::<nonlinear::PyNonlinearKalmanFilter>()?;
    m.add_class::<nonlinear::PyParticleFilter>()?;
    m.add_class::<multiple::PyMultipleModelFilter>()?;
    m.add_function(wrap_pyfunction!(nonlinear::median_filter, m)?)?;
    m.add_function(wrap_pyfunction!(nonlinear::mean_filter, m)?)?;
    m.add_function(wrap_pyfunction!(nonlinear::quantize, m)?)?;
    m.add_function(wrap_pyfunction!(nonlinear::quantized_loglik, m)?)?;
    m.add_function(wrap_pyfunction!(nonlinear::quantized_moments, m)?)?;
    m.add_class::<streaming::PyKalmanFilter>()?;
    m.add_class::<streaming::PyFixedLagSmoother>()?;
    m.add_function(wrap_pyfunction!(solvers::solve_discrete_lyapunov, m)?)?;
    m.add_function(wrap_pyfunction!(solvers::solve_continuous_lyapunov, m)?)?;
    m.add_function(wrap_pyfunction!(solvers::stationary_covariance, m)?)?;
    m.add_function(wrap_pyfunction!(model::filter_batch, m)?)?;
    m.add_function(wrap_pyfunction!(diagnostics::innovation_diagnostics, m)?)?;
    m.add_function(wrap_pyfunction!(diagnostics::state_diagnostics, m)?)?;
    m.add_function(wrap_pyfunction!(diagnostics::chi_square, m)?)?;
    m.add_function(wrap_pyfunction!(check_alloc, m)?)?;
    m.add_function(wrap_pyfunction!(kernel_info, m)?)?;
    m.add_function(wrap_pyfunction!(set_deterministic, m)?)?;
    m.add_function(wrap_pyfunction!(deterministic, m)?)?;
    m.add_function(wrap_pyfunction!(_force_kernel, m)?)?;
    m.add_function(wrap_pyfunction!(solvers::dare, m)?)?;
    m.add_function(wrap_pyfunction!(control::lqr, m)?)?;
    m.add_function(wrap_pyfunction!(control::lq_finite, m)?)?;
    m.add_function(wrap_pyfunction!(control::eigenvalues, m)?)?;
    m.add_function(wrap_pyfunction!(poly::poly_roots, m)?)?;
    m.add_function(wrap_pyfunction!(poly::spectral_factor_roots, m)?)?;
    m.add_function(wrap_pyfunction!(poly::diophantine, m)?)?;
    m.add_function(wrap_pyfunction!(poly::predictor_identity, m)?)?;
    m.add_function(wrap_pyfunction!(poly::levinson, m)?)?;
    m.add_function(wrap_pyfunction!(solvers::care, m)?)?;
    m.add_function(wrap_pyfunction!(solvers::expm, m)?)?;
    m.add_function(wrap_pyfunction!(solvers::discretize, m)?)?;
    Ok(())
}
