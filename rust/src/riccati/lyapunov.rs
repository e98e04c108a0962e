//! Lyapunov equations, with SciPy's conventions (docs/algorithms.md, "Lyapunov"):
//!
//! - [`solve_discrete_lyapunov`]`(a, q)`: X = a X a' + q  (Söderström (4.9), (4.22)–(4.24))
//! - [`solve_continuous_lyapunov`]`(a, q)`: a X + X a' = q  (Söderström (4.90)–(4.92); a
//!   covariance needs q = −Qc)
//! - [`stationary_covariance`]`(F, Q)`: the state covariance Π = F Π F' + Q of a stable model.
//!
//! Bartels–Stewart: with the real Schur form a = Z T Z', the equation for Y = Z' X Z is solved
//! block by block (1×1 and 2×2 diagonal blocks of T) by back substitution, O(n³). A block
//! system that is singular means the solution is not unique (λ_i λ_j = 1, resp.
//! λ_i + λ_j = 0) and is reported as an error, never returned as garbage. Matrices are
//! row-major `n × n` slices.

use faer::Mat;

use crate::core::mat::{checked_mat, from_mat};
use crate::core::schur::{real_schur, RealSchur};
use crate::error::{Error, Result};

/// Which equation: `X − a X a' = q` or `a X + X a' = q`.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Discrete,
    Continuous,
}

/// X solving X = a X a' + q (SciPy's `solve_discrete_lyapunov(a, q)`).
pub fn solve_discrete_lyapunov(a: &[f64], q: &[f64], n: usize) -> Result<Vec<f64>> {
    solve(a, q, n, Kind::Discrete)
}

/// X solving a X + X a' = q (SciPy's `solve_continuous_lyapunov(a, q)`).
pub fn solve_continuous_lyapunov(a: &[f64], q: &[f64], n: usize) -> Result<Vec<f64>> {
    solve(a, q, n, Kind::Continuous)
}

/// The stationary state covariance Π = F Π F' + Q; an error unless F is stable (ρ(F) < 1),
/// since otherwise no stationary covariance exists (Grewal & Andrews problems 4.27–4.28).
pub fn stationary_covariance(f: &[f64], q: &[f64], n: usize) -> Result<Vec<f64>> {
    let (fm, qm) = (checked_mat("F", f, n, n)?, checked_mat("Q", q, n, n)?);
    let schur = real_schur(&fm).map_err(|p| Error::arg("F", p))?;
    let rho = spectral_radius(&schur);
    if rho >= 1.0 - 1e-12 {
        return Err(Error::arg(
            "F",
            format!("is not stable (spectral radius {rho:.6e}): the state has no stationary covariance"),
        ));
    }
    solve_with_schur(&schur, &qm, q, Kind::Discrete)
}

pub(crate) fn spectral_radius(schur: &RealSchur) -> f64 {
    schur.eigenvalues().iter().map(|(re, im)| re.hypot(*im)).fold(0.0, f64::max)
}

fn solve(a: &[f64], q: &[f64], n: usize, kind: Kind) -> Result<Vec<f64>> {
    let (am, qm) = (checked_mat("a", a, n, n)?, checked_mat("q", q, n, n)?);
    let schur = real_schur(&am).map_err(|p| Error::arg("a", p))?;
    solve_with_schur(&schur, &qm, q, kind)
}

/// `q` is the right-hand side as a matrix (`qm`) and row-major (to test its symmetry).
fn solve_with_schur(schur: &RealSchur, qm: &Mat<f64>, q: &[f64], kind: Kind) -> Result<Vec<f64>> {
    let (t, z) = (&schur.t, &schur.z);
    let n = t.nrows();
    let c = z.transpose() * qm * z;
    let blocks = schur.blocks();
    let mut y = Mat::<f64>::zeros(n, n);
    for &(j0, qj) in blocks.iter().rev() {
        // U = Σ_{L > J} Y[:, L] T[J, L]'  (n × qj)
        let mut u = Mat::<f64>::zeros(n, qj);
        let tail = j0 + qj;
        for r in 0..n {
            for cc in 0..qj {
                u[(r, cc)] = (tail..n).map(|l| y[(r, l)] * t[(j0 + cc, l)]).sum();
            }
        }
        // Right-hand side of the column block: discrete V = T U + C[:, J]; continuous C[:, J] − U.
        let mut v = Mat::<f64>::zeros(n, qj);
        for r in 0..n {
            for cc in 0..qj {
                v[(r, cc)] = match kind {
                    Kind::Discrete => {
                        (r.saturating_sub(1)..n).map(|k| t[(r, k)] * u[(k, cc)]).sum::<f64>() + c[(r, j0 + cc)]
                    }
                    Kind::Continuous => c[(r, j0 + cc)] - u[(r, cc)],
                };
            }
        }
        for &(i0, pi) in blocks.iter().rev() {
            // R = Σ_{K > I} T[I, K] Y[K, J]  (pi × qj)
            let mut rhs = [[0.0; 2]; 2];
            for (a, row) in rhs.iter_mut().enumerate().take(pi) {
                for (b, val) in row.iter_mut().enumerate().take(qj) {
                    let r: f64 = (i0 + pi..n).map(|k| t[(i0 + a, k)] * y[(k, j0 + b)]).sum();
                    *val = r;
                }
            }
            let mut b = [[0.0; 2]; 2];
            for a in 0..pi {
                for cc in 0..qj {
                    b[a][cc] = match kind {
                        // V_I + R T_JJ'
                        Kind::Discrete => {
                            v[(i0 + a, cc)] + (0..qj).map(|l| rhs[a][l] * t[(j0 + cc, j0 + l)]).sum::<f64>()
                        }
                        Kind::Continuous => v[(i0 + a, cc)] - rhs[a][cc],
                    };
                }
            }
            let block = solve_block(t, i0, pi, j0, qj, &b, kind).ok_or_else(|| no_unique_solution(schur, kind))?;
            for a in 0..pi {
                for cc in 0..qj {
                    y[(i0 + a, j0 + cc)] = block[a][cc];
                }
            }
        }
    }
    let x = z * &y * z.transpose();
    let mut out = from_mat(&x);
    if out.iter().any(|v| !v.is_finite()) {
        // Entries near 1e155 and beyond: the products of the solve overflow.
        return Err(Error::arg(
            "a",
            "the solution is not finite: a or q is too large for double precision (rescale them)",
        ));
    }
    if crate::core::validate::check_symmetric(q, n).is_ok() {
        crate::core::dense::symmetrize(&mut out, n);
    }
    Ok(out)
}

fn no_unique_solution(schur: &RealSchur, kind: Kind) -> Error {
    let what = match kind {
        Kind::Discrete => "two eigenvalues of a have λ_i λ_j = 1",
        Kind::Continuous => "two eigenvalues of a have λ_i + λ_j = 0",
    };
    let rho = spectral_radius(schur);
    Error::arg("a", format!("the Lyapunov equation has no unique solution: {what} (spectral radius {rho:.6e})"))
}

/// Solves the ≤ 2×2 block equation for Y (p × q): discrete Y − A Y B' = rhs, continuous
/// A Y + Y B' = rhs, with A = T[i0.., i0..] (p × p) and B = T[j0.., j0..] (q × q), as a
/// Kronecker system of size p q ≤ 4 (partial pivoting). `None` when it is singular.
fn solve_block(
    t: &Mat<f64>,
    i0: usize,
    p: usize,
    j0: usize,
    q: usize,
    rhs: &[[f64; 2]; 2],
    kind: Kind,
) -> Option<[[f64; 2]; 2]> {
    let size = p * q;
    let mut m = [[0.0; 5]; 4];
    let idx = |r: usize, c: usize| c * p + r;
    let mut scale: f64 = 1.0;
    for r in 0..p {
        for c in 0..q {
            let row = idx(r, c);
            for a in 0..p {
                for b in 0..q {
                    let col = idx(a, b);
                    let (ara, bcb) = (t[(i0 + r, i0 + a)], t[(j0 + c, j0 + b)]);
                    m[row][col] = match kind {
                        Kind::Discrete => f64::from(u8::from(row == col)) - ara * bcb,
                        Kind::Continuous => ara * f64::from(u8::from(b == c)) + f64::from(u8::from(a == r)) * bcb,
                    };
                    // The size of the system's entries: 1 − a b for the discrete equation,
                    // a + b for the continuous one (whose scale must not include a b: with
                    // entries of 1e6 it would refuse a well-posed block, SciPy's CAREX 8).
                    scale = match kind {
                        Kind::Discrete => scale.max(ara.abs() * bcb.abs()),
                        Kind::Continuous => scale,
                    }
                    .max(ara.abs())
                    .max(bcb.abs());
                }
            }
            m[row][size] = rhs[r][c];
        }
    }
    for col in 0..size {
        let pivot = (col..size).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))?;
        if m[pivot][col].abs() <= 1e-13 * scale {
            return None;
        }
        m.swap(col, pivot);
        let pivot_row = m[col];
        for row in m.iter_mut().take(size).skip(col + 1) {
            let f = row[col] / pivot_row[col];
            for (v, p) in row.iter_mut().zip(pivot_row.iter()).skip(col) {
                *v -= f * p;
            }
        }
    }
    let mut sol = [0.0; 4];
    for row in (0..size).rev() {
        let s: f64 = (row + 1..size).map(|k| m[row][k] * sol[k]).sum();
        sol[row] = (m[row][size] - s) / m[row][row];
    }
    let mut out = [[0.0; 2]; 2];
    for r in 0..p {
        for c in 0..q {
            out[r][c] = sol[idx(r, c)];
        }
    }
    Some(out)
}
