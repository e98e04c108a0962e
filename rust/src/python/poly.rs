//! The polynomial toolbox's numerics (`kfast.poly`): zeros, spectral factor, Diophantine
//! equation, predictor identity, Levinson's Toeplitz solve.

use numpy::PyReadonlyArrayDyn;
use pyo3::prelude::*;

use super::data;

type Array<'py> = PyReadonlyArrayDyn<'py, f64>;

/// The zeros of a polynomial (complex).
#[pyfunction]
pub(super) fn poly_roots<'py>(
    py: Python<'py>,
    p: Array<'py>,
) -> PyResult<Bound<'py, numpy::PyArray1<numpy::Complex64>>> {
    let pv = data("p", &p, 1)?;
    let z = py.detach(|| crate::poly::roots(pv))?;
    Ok(numpy::PyArray1::from_vec(py, z.into_iter().map(|(re, im)| numpy::Complex64::new(re, im)).collect()))
}

/// (B, λ², on_circle) of a symmetric Laurent polynomial by its zeros.
#[pyfunction]
pub(super) fn spectral_factor_roots(py: Python<'_>, r: Array<'_>) -> PyResult<(Vec<f64>, f64, bool)> {
    let rv = data("r", &r, 1)?;
    let f = py.detach(|| crate::poly::spectral_factor(rv))?;
    Ok((f.b, f.lam2, f.on_circle))
}

/// (X, Y, condition) of A X + B Y = C.
#[pyfunction]
#[allow(non_snake_case)]
pub(super) fn diophantine(
    py: Python<'_>,
    A: Array<'_>,
    B: Array<'_>,
    C: Array<'_>,
) -> PyResult<(Vec<f64>, Vec<f64>, f64)> {
    let (a, b, c) = (data("A", &A, 1)?, data("B", &B, 1)?, data("C", &C, 1)?);
    let d = py.detach(|| crate::poly::diophantine(a, b, c))?;
    Ok((d.x, d.y, d.condition))
}

/// (F, L) of z^(k−1) C = A F + L.
#[pyfunction]
#[allow(non_snake_case)]
pub(super) fn predictor_identity(
    py: Python<'_>,
    A: Array<'_>,
    C: Array<'_>,
    k: usize,
) -> PyResult<(Vec<f64>, Vec<f64>)> {
    let (a, c) = (data("A", &A, 1)?, data("C", &C, 1)?);
    Ok(py.detach(|| crate::poly::predictor_identity(a, c, k))?)
}

/// (x, quadratic) of the symmetric Toeplitz system T(r) x = b by Levinson's recursion.
#[pyfunction]
pub(super) fn levinson(py: Python<'_>, r: Array<'_>, b: Array<'_>) -> PyResult<(Vec<f64>, Vec<f64>)> {
    let (rv, bv) = (data("r", &r, 1)?, data("b", &b, 1)?);
    let sol = py.detach(|| crate::poly::levinson(rv, bv))?;
    Ok((sol.x, sol.quadratic))
}
