//! Bridging row-major slices and faer matrices, for the solvers that use faer's
//! factorizations (Schur, LU, eigenvalues).

use faer::{Mat, MatMut, MatRef};

use crate::error::{Error, Result};

/// The square row-major `a` (n × n) as a faer matrix.
pub(crate) fn to_mat(a: &[f64], n: usize) -> Mat<f64> {
    MatRef::from_row_major_slice(a, n, n).to_owned()
}

/// A faer matrix as a row-major vector.
pub(crate) fn from_mat(m: &Mat<f64>) -> Vec<f64> {
    let (r, c) = (m.nrows(), m.ncols());
    let mut v = vec![0.0; r * c];
    MatMut::from_row_major_slice_mut(&mut v, r, c).copy_from(m);
    v
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
    Ok(MatRef::from_row_major_slice(v, rows, cols).to_owned())
}
