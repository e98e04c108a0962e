//! Gaussian mixtures: the moments of a weighted sum of Gaussians, and the maps that carry a
//! state of one mode into the space of another.

use crate::core::validate::{check_psd, check_symmetric};
use crate::error::{Error, Result};

/// The mean and covariance of the mixture Σ_i w_i N(x_i, P_i) (weights summing to 1),
/// Söderström (9.47)–(9.48): x = Σ w_i x_i, then P = Σ w_i [P_i + (x_i − x)(x_i − x)'] —
/// the sum of positive semidefinite terms, never Σ w_i (P_i + x_i x_i') − x x', which
/// cancels. `state(i)` is component i; zero weights are skipped (their state may be stale);
/// `diff` (n values) is scratch.
pub(crate) fn moment_match<'s>(
    weights: &[f64],
    state: impl Fn(usize) -> (&'s [f64], &'s [f64]),
    x: &mut [f64],
    p: &mut [f64],
    diff: &mut [f64],
) {
    let n = x.len();
    let diff = &mut diff[..n];
    x.fill(0.0);
    for (i, &w) in weights.iter().enumerate().filter(|(_, &w)| w > 0.0) {
        for (xk, xi) in x.iter_mut().zip(state(i).0) {
            *xk += w * xi;
        }
    }
    p.fill(0.0);
    for (i, &w) in weights.iter().enumerate().filter(|(_, &w)| w > 0.0) {
        let (xi, pi) = state(i);
        for ((d, a), b) in diff.iter_mut().zip(xi).zip(x.iter()) {
            *d = a - b;
        }
        // Whole rows (they vectorize); P_i symmetric and dr dc = dc dr keep P symmetric.
        for ((p_row, pi_row), &dr) in p.chunks_exact_mut(n).zip(pi.chunks_exact(n)).zip(diff.iter()) {
            for ((pv, &piv), &dc) in p_row.iter_mut().zip(pi_row).zip(diff.iter()) {
                *pv += w * (piv + dr * dc);
            }
        }
    }
}

/// How the state of one mode reads in the space of another (MATLAB's `switchimm`):
/// `x_to = A x_from + b`, with covariance `A P A' + Σ`, Σ the uncertainty of the states that
/// the first mode does not carry (e.g. the turn rate of a coordinated-turn mode mixed from a
/// constant-velocity one).
#[derive(Debug, Clone, PartialEq)]
pub struct StateMap {
    n_from: usize,
    n_to: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    cov: Vec<f64>,
}

impl StateMap {
    /// The map from `n_from` to `n_to` states: `a` (n_to × n_from, row-major), `b` (n_to;
    /// zero when `None`), `cov` (n_to × n_to symmetric positive semidefinite; zero when `None`).
    pub fn new(n_from: usize, n_to: usize, a: Vec<f64>, b: Option<Vec<f64>>, cov: Option<Vec<f64>>) -> Result<Self> {
        let b = b.unwrap_or_else(|| vec![0.0; n_to]);
        let cov = cov.unwrap_or_else(|| vec![0.0; n_to * n_to]);
        for (what, values, len, shape) in [
            ("A", &a, n_to * n_from, format!("({n_to}, {n_from})")),
            ("b", &b, n_to, format!("({n_to},)")),
            ("Sigma", &cov, n_to * n_to, format!("({n_to}, {n_to})")),
        ] {
            if values.len() != len {
                return Err(Error::arg(
                    "state_maps",
                    format!("{what}: expected shape {shape}, got {} values", values.len()),
                ));
            }
            if let Some(v) = values.iter().find(|v| !v.is_finite()) {
                return Err(Error::arg("state_maps", format!("{what}: contains a non-finite value ({v})")));
            }
        }
        check_symmetric(&cov, n_to).map_err(|p| Error::arg("state_maps", format!("Sigma: {p}")))?;
        check_psd(&cov, n_to).map_err(|p| Error::arg("state_maps", format!("Sigma: {p}")))?;
        Ok(StateMap { n_from, n_to, a, b, cov })
    }

    /// The identity of n states (for pairs of modes of one size).
    pub fn identity(n: usize) -> Self {
        let mut a = vec![0.0; n * n];
        a.iter_mut().step_by(n + 1).for_each(|v| *v = 1.0);
        StateMap { n_from: n, n_to: n, a, b: vec![0.0; n], cov: vec![0.0; n * n] }
    }

    /// The sizes (from, to).
    pub fn sizes(&self) -> (usize, usize) {
        (self.n_from, self.n_to)
    }

    /// `(A x + b, A P A' + Σ)` into `(x_out, p_out)`; `scratch` holds A P (n_to × n_from).
    pub(crate) fn apply(&self, (x, p): (&[f64], &[f64]), x_out: &mut [f64], p_out: &mut [f64], scratch: &mut [f64]) {
        let (ni, nj, a) = (self.n_from, self.n_to, &self.a);
        for r in 0..nj {
            x_out[r] = self.b[r] + (0..ni).map(|k| a[r * ni + k] * x[k]).sum::<f64>();
        }
        for r in 0..nj {
            for c in 0..ni {
                scratch[r * ni + c] = (0..ni).map(|k| a[r * ni + k] * p[k * ni + c]).sum();
            }
        }
        for r in 0..nj {
            for c in 0..=r {
                let v = self.cov[r * nj + c] + (0..ni).map(|k| scratch[r * ni + k] * a[c * ni + k]).sum::<f64>();
                p_out[r * nj + c] = v;
                p_out[c * nj + r] = v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moments_of_two_points_are_their_spread() {
        let (x1, x2, zero) = ([1.0], [3.0], [0.0]);
        let states = [(&x1[..], &zero[..]), (&x2[..], &zero[..])];
        let (mut x, mut p, mut d) = ([0.0], [0.0], [0.0]);
        moment_match(&[0.5, 0.5], |i| states[i], &mut x, &mut p, &mut d);
        assert_eq!((x[0], p[0]), (2.0, 1.0));
    }

    #[test]
    fn a_map_adds_its_covariance() {
        let map = StateMap::new(1, 2, vec![1.0, 0.0], Some(vec![0.0, 0.5]), Some(vec![0.0, 0.0, 0.0, 0.25])).unwrap();
        let (mut x, mut p, mut s) = ([0.0; 2], [0.0; 4], [0.0; 2]);
        map.apply((&[2.0], &[4.0]), &mut x, &mut p, &mut s);
        assert_eq!((x, p), ([2.0, 0.5], [4.0, 0.0, 0.0, 0.25]));
        assert!(StateMap::new(1, 2, vec![1.0], None, None).is_err());
        assert!(StateMap::new(1, 1, vec![1.0], None, Some(vec![-1.0])).is_err());
    }
}
