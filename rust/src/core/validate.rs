//! Validators shared by every family: each returns an error naming the argument (and the
//! time step, where there is one) so that messages read like
//! `P0: not positive semidefinite (smallest eigenvalue -2.5e-1)`.

use crate::core::Series;
use crate::error::{Error, Result};

/// Tolerance, relative to the largest entry, for symmetry and semidefiniteness checks.
const COV_RTOL: f64 = 1e-10;

/// `Err(problem)` unless `a[n×n]` is symmetric to `COV_RTOL` relative to its largest entry.
pub(crate) fn check_symmetric(a: &[f64], n: usize) -> std::result::Result<(), String> {
    let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for i in 0..n {
        for j in 0..i {
            let diff = (a[i * n + j] - a[j * n + i]).abs();
            if diff > COV_RTOL * scale {
                return Err(format!(
                    "not symmetric: entry ({i}, {j}) is {} but ({j}, {i}) is {}",
                    a[i * n + j],
                    a[j * n + i]
                ));
            }
        }
    }
    Ok(())
}

/// `Err(problem)` unless the symmetric `a[n×n]` is positive semidefinite, i.e. its smallest
/// eigenvalue is ≥ −`COV_RTOL` · (largest absolute eigenvalue).
pub(crate) fn check_psd(a: &[f64], n: usize) -> std::result::Result<(), String> {
    if n == 0 {
        return Ok(());
    }
    if n == 1 {
        return if a[0] >= 0.0 { Ok(()) } else { Err(format!("not positive semidefinite (value {})", a[0])) };
    }
    if shifted_cholesky_exists(a, n) {
        return Ok(());
    }
    let mat = faer::Mat::<f64>::from_fn(n, n, |i, j| a[i * n + j]);
    let eig =
        mat.self_adjoint_eigenvalues(faer::Side::Lower).map_err(|_| "eigenvalues could not be computed".to_string())?;
    let (lo, hi) = (eig[0], eig[n - 1]);
    let scale = lo.abs().max(hi.abs());
    if lo < -COV_RTOL * scale {
        return Err(format!("not positive semidefinite (smallest eigenvalue {lo:.6e})"));
    }
    Ok(())
}

/// Whether a + τ I has a Cholesky factor, τ = `COV_RTOL` · max |a_ii|: then λ_min(a) ≥ −τ, and
/// since |a_ii| ≤ max |λ| that passes [`check_psd`]'s eigenvalue test (up to rounding of order
/// n ε ‖a‖, far below τ). An O(n³/6) fast path, a sixth of the cost of the eigenvalues, which are
/// computed only when it fails (for the verdict and the message).
fn shifted_cholesky_exists(a: &[f64], n: usize) -> bool {
    let tau = COV_RTOL * (0..n).fold(0.0f64, |s, i| s.max(a[i * n + i].abs()));
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let (li, lj) = (&l[i * n..i * n + j], &l[j * n..j * n + j]);
            let dot: f64 = li.iter().zip(lj).map(|(x, y)| x * y).sum();
            if i == j {
                let pivot = a[i * n + i] + tau - dot;
                if pivot.is_nan() || pivot <= 0.0 {
                    return false;
                }
                l[i * n + i] = pivot.sqrt();
            } else {
                l[i * n + j] = (a[i * n + j] - dot) / l[j * n + j];
            }
        }
    }
    true
}

/// `y[t]` may hold NaN (missing) but not ±inf.
pub(crate) fn check_observation(y: &[f64], step: Option<usize>) -> Result<()> {
    if let Some(i) = y.iter().position(|v| v.is_infinite()) {
        return Err(Error::arg("y", format!("component {i} is {} (missing values are NaN, inf is not allowed)", y[i]))
            .at_step(step));
    }
    Ok(())
}

pub(crate) fn check_input_row(u: &[f64], step: Option<usize>) -> Result<()> {
    if let Some(v) = u.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg("u", format!("contains a non-finite value ({v})")).at_step(step));
    }
    Ok(())
}

/// x0 has n finite entries; P0 is a finite symmetric PSD n × n matrix.
pub(crate) fn check_prior(n: usize, x0: &[f64], p0: &[f64]) -> Result<()> {
    if x0.len() != n {
        return Err(Error::arg("x0", format!("expected {n} entries (the state size n), got {}", x0.len())));
    }
    if let Some(v) = x0.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg("x0", format!("contains a non-finite value ({v})")));
    }
    if p0.len() != n * n {
        return Err(Error::arg("P0", format!("expected an ({n}, {n}) matrix, got {} entries", p0.len())));
    }
    if let Some(v) = p0.iter().find(|v| !v.is_finite()) {
        return Err(Error::arg("P0", format!("contains a non-finite value ({v})")));
    }
    check_symmetric(p0, n).map_err(|p| Error::arg("P0", p))?;
    check_psd(p0, n).map_err(|p| Error::arg("P0", p))
}

/// `Err(problem)` unless the joint covariance `[[Q, N], [N', R]]` of (w, v) is positive
/// semidefinite (Q n × n, N n × m, R m × m).
pub(crate) fn check_joint_psd(q: &[f64], nn: &[f64], r: &[f64], n: usize, m: usize) -> std::result::Result<(), String> {
    let size = n + m;
    let mut joint = vec![0.0; size * size];
    for i in 0..n {
        joint[i * size..i * size + n].copy_from_slice(&q[i * n..(i + 1) * n]);
        for j in 0..m {
            joint[i * size + n + j] = nn[i * m + j];
            joint[(n + j) * size + i] = nn[i * m + j];
        }
    }
    for i in 0..m {
        joint[(n + i) * size + n..(n + i + 1) * size].copy_from_slice(&r[i * m..(i + 1) * m]);
    }
    check_psd(&joint, size).map_err(|p| format!("[[Q, N], [N', R]] is {p}"))
}

/// The observations of one series: m per row, at least one row, as many rows as the model's
/// per-step matrices (`model_steps`, when it has them), no ±inf (NaN marks a missing value);
/// returns T.
pub(crate) fn check_observations(y: Series<'_>, m: usize, model_steps: Option<usize>) -> Result<usize> {
    let steps = y.steps();
    if y.width() != m {
        return Err(Error::arg("y", format!("expected shape (T, {m}) for m = {m} outputs, got (T, {})", y.width())));
    }
    if steps == 0 {
        return Err(Error::arg("y", "has no time steps (T = 0)"));
    }
    if let Some(tm) = model_steps {
        if tm != steps {
            return Err(Error::arg("y", format!("has {steps} steps but the model's per-step matrices have {tm}")));
        }
    }
    for t in 0..steps {
        check_observation(y.row(t), Some(t))?;
    }
    Ok(steps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cholesky_fast_path_agrees_with_the_eigenvalue_test() {
        // Singular PSD (rank one), a zero matrix, a negative eigenvalue within the tolerance,
        // one just beyond it, and clearly indefinite / NaN matrices.
        let rank_one = [1.0, 1.0, 1.0, 1.0];
        assert!(shifted_cholesky_exists(&rank_one, 2) && check_psd(&rank_one, 2).is_ok());
        assert!(check_psd(&[0.0; 9], 3).is_ok());
        let within = [1.0, 0.0, 0.0, -0.5e-10];
        assert!(check_psd(&within, 2).is_ok());
        let beyond = [1.0, 0.0, 0.0, -2e-10];
        assert!(!shifted_cholesky_exists(&beyond, 2));
        assert!(check_psd(&beyond, 2).unwrap_err().contains("smallest eigenvalue -2.0"));
        assert!(check_psd(&[1.0, 2.0, 2.0, 1.0], 2).is_err());
        assert!(!shifted_cholesky_exists(&[f64::NAN, 0.0, 0.0, 1.0], 2));
    }
}
