//! Module-level solver functions: Lyapunov, Riccati, matrix exponential, discretization.

use numpy::{PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use super::{data, to_array, KfastError};

type Array<'py> = PyReadonlyArrayDyn<'py, f64>;
type OutArray<'py> = Bound<'py, PyArrayDyn<f64>>;

/// The data and size of a square 2-D array.
pub(super) fn square<'a>(arg: &str, a: &'a Array<'_>) -> PyResult<(&'a [f64], usize)> {
    let values = data(arg, a, 2)?;
    let shape = a.shape();
    if shape[0] != shape[1] {
        return Err(KfastError::new_err(format!("{arg}: expected a square matrix, got shape {shape:?}")));
    }
    Ok((values, shape[0]))
}

fn same_size(arg: &str, n: usize, m: usize, other: &str) -> PyResult<()> {
    if n != m {
        return Err(KfastError::new_err(format!("{arg}: expected shape ({m}, {m}) like {other}, got ({n}, {n})")));
    }
    Ok(())
}

#[pyfunction]
pub(super) fn solve_discrete_lyapunov<'py>(py: Python<'py>, a: Array<'py>, q: Array<'py>) -> PyResult<OutArray<'py>> {
    let ((av, n), (qv, nq)) = (square("a", &a)?, square("q", &q)?);
    same_size("q", nq, n, "a")?;
    let x = py.detach(|| crate::solve_discrete_lyapunov(av, qv, n))?;
    to_array(py, &x, &[n, n])
}

#[pyfunction]
pub(super) fn solve_continuous_lyapunov<'py>(py: Python<'py>, a: Array<'py>, q: Array<'py>) -> PyResult<OutArray<'py>> {
    let ((av, n), (qv, nq)) = (square("a", &a)?, square("q", &q)?);
    same_size("q", nq, n, "a")?;
    let x = py.detach(|| crate::solve_continuous_lyapunov(av, qv, n))?;
    to_array(py, &x, &[n, n])
}

#[pyfunction]
#[pyo3(name = "stationary_covariance")]
#[allow(non_snake_case)]
pub(super) fn stationary_covariance<'py>(py: Python<'py>, F: Array<'py>, Q: Array<'py>) -> PyResult<OutArray<'py>> {
    let ((fv, n), (qv, nq)) = (square("F", &F)?, square("Q", &Q)?);
    same_size("Q", nq, n, "F")?;
    let x = py.detach(|| crate::stationary_covariance(fv, qv, n))?;
    to_array(py, &x, &[n, n])
}

/// A general (not necessarily square) 2-D array's data and shape.
pub(super) fn matrix<'a>(arg: &str, a: &'a Array<'_>) -> PyResult<(&'a [f64], usize, usize)> {
    let values = data(arg, a, 2)?;
    Ok((values, a.shape()[0], a.shape()[1]))
}

pub(super) fn parse_method(method: &str) -> PyResult<crate::DareMethod> {
    use crate::DareMethod::*;
    match method {
        "doubling" => Ok(Doubling),
        "newton" => Ok(Newton),
        "iteration" => Ok(Iteration),
        "eigen" => Ok(Eigen),
        other => Err(KfastError::new_err(format!(
            "method: expected \"doubling\", \"newton\", \"iteration\" or \"eigen\", got {other:?}"
        ))),
    }
}

/// The solution as a dict: x, gain, closed_loop_eigenvalues (complex; only with
/// `eigenvalues`), residual, iterations.
fn solution_dict<'py>(
    py: Python<'py>,
    sol: crate::RiccatiSolution,
    eigenvalues: Option<Vec<numpy::Complex64>>,
    n: usize,
    m: usize,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let dict = pyo3::types::PyDict::new(py);
    dict.set_item("x", to_array(py, &sol.x, &[n, n])?)?;
    dict.set_item("gain", to_array(py, &sol.gain, &[m, n])?)?;
    if let Some(eig) = eigenvalues {
        dict.set_item("closed_loop_eigenvalues", numpy::PyArray1::from_vec(py, eig))?;
    }
    dict.set_item("residual", sol.residual)?;
    dict.set_item("method", sol.method)?;
    dict.set_item("iterations", sol.iterations)?;
    Ok(dict)
}

/// Shapes of (a, b, q, r, e, s) against n = a's size and m = b's columns.
#[allow(clippy::type_complexity)]
fn riccati_args<'a>(
    a: &'a Array<'_>,
    b: &'a Array<'_>,
    q: &'a Array<'_>,
    r: &'a Array<'_>,
    e: Option<&'a Array<'_>>,
    s: Option<&'a Array<'_>>,
) -> PyResult<(&'a [f64], &'a [f64], &'a [f64], &'a [f64], Option<&'a [f64]>, Option<&'a [f64]>, usize, usize)> {
    let (av, n) = square("a", a)?;
    let (bv, bn, m) = matrix("b", b)?;
    if bn != n {
        return Err(KfastError::new_err(format!("b: expected {n} rows like a, got shape ({bn}, {m})")));
    }
    let (qv, nq) = square("q", q)?;
    same_size("q", nq, n, "a")?;
    let (rv, mr) = square("r", r)?;
    if mr != m {
        return Err(KfastError::new_err(format!("r: expected shape ({m}, {m}) (b has {m} columns), got ({mr}, {mr})")));
    }
    let ev = match e {
        Some(e) => {
            let (ev, ne) = square("e", e)?;
            same_size("e", ne, n, "a")?;
            Some(ev)
        }
        None => None,
    };
    let sv = match s {
        Some(s) => {
            let (sv, sn, sm) = matrix("s", s)?;
            if (sn, sm) != (n, m) {
                return Err(KfastError::new_err(format!("s: expected shape ({n}, {m}), got ({sn}, {sm})")));
            }
            Some(sv)
        }
        None => None,
    };
    Ok((av, bv, qv, rv, ev, sv, n, m))
}

#[pyfunction]
#[pyo3(signature = (a, b, q, r, e=None, s=None, method="doubling", eigenvalues=true))]
#[allow(clippy::too_many_arguments)]
pub(super) fn dare<'py>(
    py: Python<'py>,
    a: Array<'py>,
    b: Array<'py>,
    q: Array<'py>,
    r: Array<'py>,
    e: Option<Array<'py>>,
    s: Option<Array<'py>>,
    method: &str,
    eigenvalues: bool,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let method = parse_method(method)?;
    let (av, bv, qv, rv, ev, sv, n, m) = riccati_args(&a, &b, &q, &r, e.as_ref(), s.as_ref())?;
    let (sol, eig) = py.detach(|| {
        let sol = crate::solve_discrete_are(riccati_problem(av, bv, qv, rv, ev, sv, n, m), method)?;
        let eig = if eigenvalues { Some(complex_eigenvalues(&sol)?) } else { None };
        crate::Result::Ok((sol, eig))
    })?;
    solution_dict(py, sol, eig, n, m)
}

/// The closed loop's eigenvalues as NumPy complex numbers.
fn complex_eigenvalues(sol: &crate::RiccatiSolution) -> crate::Result<Vec<numpy::Complex64>> {
    Ok(sol.closed_loop_eigenvalues()?.iter().map(|&(re, im)| numpy::Complex64::new(re, im)).collect())
}

#[pyfunction]
#[pyo3(signature = (a, b, q, r, e=None, s=None))]
#[allow(clippy::too_many_arguments)]
pub(super) fn care<'py>(
    py: Python<'py>,
    a: Array<'py>,
    b: Array<'py>,
    q: Array<'py>,
    r: Array<'py>,
    e: Option<Array<'py>>,
    s: Option<Array<'py>>,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let (av, bv, qv, rv, ev, sv, n, m) = riccati_args(&a, &b, &q, &r, e.as_ref(), s.as_ref())?;
    let (sol, eig) = py.detach(|| {
        let sol = crate::solve_continuous_are(riccati_problem(av, bv, qv, rv, ev, sv, n, m))?;
        let eig = complex_eigenvalues(&sol)?;
        crate::Result::Ok((sol, eig))
    })?;
    solution_dict(py, sol, Some(eig), n, m)
}

#[pyfunction]
pub(super) fn expm<'py>(py: Python<'py>, a: Array<'py>) -> PyResult<OutArray<'py>> {
    let (av, n) = square("a", &a)?;
    let e = py.detach(|| crate::expm(av, n))?;
    to_array(py, &e, &[n, n])
}

/// Van Loan discretization for each dt: dict with F (T, n, n), Qd (T, n, n), Bd (T, n, k).
#[pyfunction]
#[pyo3(signature = (A, Qc, dt, B=None))]
#[allow(non_snake_case)]
pub(super) fn discretize<'py>(
    py: Python<'py>,
    A: Array<'py>,
    Qc: Array<'py>,
    dt: Array<'py>,
    B: Option<Array<'py>>,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let (av, n) = square("A", &A)?;
    let (qv, nq) = square("Qc", &Qc)?;
    same_size("Qc", nq, n, "A")?;
    let dts = data("dt", &dt, 1)?;
    let (bv, k) = match &B {
        Some(b) => {
            let (bv, bn, k) = matrix("B", b)?;
            if bn != n {
                return Err(KfastError::new_err(format!("B: expected {n} rows like A, got shape ({bn}, {k})")));
            }
            (Some(bv), k)
        }
        None => (None, 0),
    };
    let d = py.detach(|| crate::discretize_steps(av, qv, bv, n, k, dts))?;
    let steps = dts.len();
    let dict = pyo3::types::PyDict::new(py);
    dict.set_item("F", to_array(py, &d.f, &[steps, n, n])?)?;
    dict.set_item("Qd", to_array(py, &d.qd, &[steps, n, n])?)?;
    if bv.is_some() {
        dict.set_item("Bd", to_array(py, &d.bd, &[steps, n, k])?)?;
    }
    Ok(dict)
}

/// The Riccati problem of the given (validated-shape) arrays.
#[allow(clippy::too_many_arguments)]
fn riccati_problem<'a>(
    a: &'a [f64],
    b: &'a [f64],
    q: &'a [f64],
    r: &'a [f64],
    e: Option<&'a [f64]>,
    s: Option<&'a [f64]>,
    n: usize,
    m: usize,
) -> crate::RiccatiProblem<'a> {
    let mut p = crate::RiccatiProblem::new(a, b, q, r, n, m);
    (p.e, p.s) = (e, s);
    p
}
