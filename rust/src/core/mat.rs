//! Bridging row-major slices and faer matrices, for the solvers that use faer's
//! factorizations (Schur, LU, eigenvalues).

use faer::Mat;

use crate::error::{Error, Result};

/// The square row-major `a` (n × n) as a faer matrix.
pub(crate) fn to_mat(a: &[f64], n: usize) -> Mat<f64> {
    Mat::from_fn(n, n, |i, j| a[i * n + j])
}

/// A faer matrix as a row-major vector.
pub(crate) fn from_mat(m: &Mat<f64>) -> Vec<f64> {
    let (r, c) = (m.nrows(), m.ncols());
    (0..r * c).map(|k| m[(k / c, k % c)]).collect()
}

/// The row-major `v` as a `rows × cols` faer matrix, after checking its size and that every
/// entry is finite (`arg` names it in errors).
pub(crate) fn checked_mat(arg: &'static str, v: &[f64], rows: usize, cols: usize) -> Result<Mat<f64>> {
    if rows.checked_mul(cols) != Some(v.len()) {
        return Err(Error::arg(arg, format!("expected shape ({rows}, {cols}), got {} entries", v.len())));
    }
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        return Err(Error::arg(arg, format!("contains a non-finite value ({x})")));
    }
    Ok(Mat::from_fn(rows, cols, |i, j| v[i * cols + j]))
}
