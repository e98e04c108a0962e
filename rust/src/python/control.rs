//! The LQ regulators (`kfast.control.lqr`, `lq_finite`) and a general eigenvalue solve.

use numpy::PyReadonlyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::model::step_matrix;
use super::solvers::{matrix, parse_method, square};
use super::{data, to_array, KfastError};
use crate::control::{LqProblem, LqSteps};

type Array<'py> = PyReadonlyArrayDyn<'py, f64>;

fn complex(values: &[(f64, f64)]) -> Vec<numpy::Complex64> {
    values.iter().map(|&(re, im)| numpy::Complex64::new(re, im)).collect()
}

/// The stationary regulator as a dict: L, S, closed_loop (F − G L), residual, and the
/// closed-loop eigenvalues with `eigenvalues`.
#[pyfunction]
#[pyo3(signature = (F, G, Q1, Q2, Q12=None, method="doubling", eigenvalues=false))]
#[allow(non_snake_case, clippy::too_many_arguments)]
pub(super) fn lqr<'py>(
    py: Python<'py>,
    F: Array<'py>,
    G: Array<'py>,
    Q1: Array<'py>,
    Q2: Array<'py>,
    Q12: Option<Array<'py>>,
    method: &str,
    eigenvalues: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let method = parse_method(method)?;
    let (f, n) = square("F", &F)?;
    let (g, gn, k) = matrix("G", &G)?;
    if gn != n {
        return Err(KfastError::new_err(format!("G: expected {n} rows like F, got shape ({gn}, {k})")));
    }
    let (q1, q2) = (data("Q1", &Q1, 2)?, data("Q2", &Q2, 2)?);
    let q12 = Q12.as_ref().map(|a| data("Q12", a, 2)).transpose()?;
    let mut problem = LqProblem::new(f, g, q1, q2, n, k);
    if let Some(q12) = q12 {
        problem = problem.with_cross(q12);
    }
    let (sol, eig) = py.detach(|| {
        let sol = crate::control::lqr(problem, method)?;
        let eig = if eigenvalues { Some(complex(sol.closed_loop_eigenvalues()?)) } else { None };
        crate::Result::Ok((sol, eig))
    })?;
    let dict = PyDict::new(py);
    dict.set_item("L", to_array(py, sol.gain(), &[k, n])?)?;
    dict.set_item("S", to_array(py, sol.s(), &[n, n])?)?;
    dict.set_item("closed_loop", to_array(py, sol.closed_loop(), &[n, n])?)?;
    dict.set_item("residual", sol.residual())?;
    if let Some(eig) = eig {
        dict.set_item("closed_loop_eigenvalues", numpy::PyArray1::from_vec(py, eig))?;
    }
    Ok(dict)
}

/// The finite-horizon regulator as a dict: L (N, k, n) and S (N + 1, n, n).
#[pyfunction]
#[pyo3(signature = (F, G, Q0, Q1, Q2, N, Q12=None))]
#[allow(non_snake_case, clippy::too_many_arguments)]
pub(super) fn lq_finite<'py>(
    py: Python<'py>,
    F: Array<'py>,
    G: Array<'py>,
    Q0: Array<'py>,
    Q1: Array<'py>,
    Q2: Array<'py>,
    N: usize,
    Q12: Option<Array<'py>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut steps =
        LqSteps::new(step_matrix("F", &F)?, step_matrix("G", &G)?, step_matrix("Q1", &Q1)?, step_matrix("Q2", &Q2)?);
    if let Some(q12) = &Q12 {
        steps = steps.with_cross(step_matrix("Q12", q12)?);
    }
    let q0 = data("Q0", &Q0, 2)?;
    let (n, k) = (steps.f.rows(), steps.g.cols());
    let res = py.detach(|| crate::control::lq_finite(&steps, q0, N))?;
    let dict = PyDict::new(py);
    dict.set_item("L", to_array(py, &res.gains, &[N, k, n])?)?;
    dict.set_item("S", to_array(py, &res.s, &[N + 1, n, n])?)?;
    Ok(dict)
}

/// Eigenvalues of a square matrix (complex), by the solver the Riccati post-checks use.
#[pyfunction]
pub(super) fn eigenvalues<'py>(
    py: Python<'py>,
    a: Array<'py>,
) -> PyResult<Bound<'py, numpy::PyArray1<numpy::Complex64>>> {
    let (av, n) = square("a", &a)?;
    let ev = py.detach(|| crate::riccati::are::eigenvalues_of(av, n))?;
    Ok(numpy::PyArray1::from_vec(py, complex(&ev)))
}
