//! [`PointFunction`]: the state transition f or the measurement h of a nonlinear model,
//! evaluated at a batch of points in one call, and Jacobians by central differences.

use crate::error::{Error, Result};

/// A vector function `φ(x, t, u)` of the state (n numbers) with `dim_out` outputs, evaluated at
/// `k` points at once: one call per step serves all sigma points (or all difference points),
/// so a function written in Python costs one call per step, not one per point.
///
/// Implementations: the built-in models ([`super::models`]), a linear map ([`LinearMap`]) and,
/// in the Python extension, a Python callable or a compiled C function.
pub trait PointFunction: Send + Sync {
    /// The number of inputs n (the state size).
    fn dim_in(&self) -> usize;

    /// The number of outputs.
    fn dim_out(&self) -> usize;

    /// `out[i] = φ(points[i], t, u)` for the `k` rows of `points` (row-major `k × n` in,
    /// `k × dim_out` out). `u` is the input row of step `t`, if the model has inputs.
    fn eval(&self, points: &[f64], k: usize, t: usize, u: Option<&[f64]>, out: &mut [f64]) -> Result<()>;

    /// Whether calls from several threads run at the same time (`ekf_batch` and `ukf_batch`
    /// run their series in parallel only then): true but for a Python callable, which holds
    /// the GIL while it runs.
    fn parallel(&self) -> bool {
        true
    }

    /// The Jacobians `∂φ/∂x` at the `k` points (`k × dim_out × n`), when known in closed
    /// form; `None` (the default) means "use central differences" (the filters difference φ
    /// then, all 2n points in one call; docs/algorithms.md, "Extended Kalman filter").
    fn jacobian(&self, points: &[f64], k: usize, t: usize, u: Option<&[f64]>, out: &mut [f64]) -> Option<Result<()>> {
        let _ = (points, k, t, u, out);
        None
    }

    /// `φ(x)` (`dim_out`) and `∂φ/∂x` (`dim_out × n`) at one point together, for functions
    /// whose value and Jacobian share work (the coordinated turn's sine and cosine); `None`
    /// (the default) means "call [`eval`](Self::eval) and [`jacobian`](Self::jacobian)".
    fn eval_with_jacobian(
        &self,
        x: &[f64],
        t: usize,
        u: Option<&[f64]>,
        value: &mut [f64],
        jac: &mut [f64],
    ) -> Option<Result<()>> {
        let _ = (x, t, u, value, jac);
        None
    }

    /// The Hessians `∂²φ_i/∂x²` at the `k` points (`k × dim_out × n × n`), when known in closed
    /// form; `None` (the default) means "use second differences".
    fn hessian(&self, points: &[f64], k: usize, t: usize, u: Option<&[f64]>, out: &mut [f64]) -> Option<Result<()>> {
        let _ = (points, k, t, u, out);
        None
    }
}

/// `x ↦ A x` for a constant `A` (`dim_out × n`, row-major): a linear model as a nonlinear one.
#[derive(Debug, Clone)]
pub struct LinearMap {
    a: Vec<f64>,
    rows: usize,
    cols: usize,
}

impl LinearMap {
    /// The map of `a` (`rows × cols`, row-major).
    pub fn new(a: Vec<f64>, rows: usize, cols: usize) -> Result<Self> {
        if rows.checked_mul(cols) != Some(a.len()) {
            return Err(Error::arg("A", format!("has {} entries, not {rows} × {cols}", a.len())));
        }
        Ok(LinearMap { a, rows, cols })
    }
}

impl PointFunction for LinearMap {
    fn dim_in(&self) -> usize {
        self.cols
    }

    fn dim_out(&self) -> usize {
        self.rows
    }

    fn eval(&self, points: &[f64], k: usize, _t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Result<()> {
        // sizes up to 6 × 6 get the loop compiled for them (unrolled: a step's few points
        // are loop-control bound at run-time sizes), others the same loop at run time
        macro_rules! sized {
            ($(($r:literal, $c:literal))*) => {
                match (self.rows, self.cols) {
                    $(($r, $c) => map_points(&self.a, points, k, out, $r, $c),)*
                    (r, c) => map_points(&self.a, points, k, out, r, c),
                }
            };
        }
        sized!((1, 1)(1, 2)(1, 3)(1, 4)(1, 5)(1, 6)(2, 1)(2, 2)(2, 3)(2, 4)(2, 5)(2, 6)(3, 1)(3, 2)(3, 3)(3, 4)(3, 5)(
            3, 6
        )(4, 1)(4, 2)(4, 3)(4, 4)(4, 5)(4, 6)(5, 1)(5, 2)(5, 3)(5, 4)(5, 5)(5, 6)(6, 1)(6, 2)(6, 3)(
            6, 4
        )(6, 5)(6, 6));
        Ok(())
    }

    fn jacobian(
        &self,
        _points: &[f64],
        k: usize,
        _t: usize,
        _u: Option<&[f64]>,
        out: &mut [f64],
    ) -> Option<Result<()>> {
        for block in out.chunks_exact_mut(self.a.len()).take(k) {
            block.copy_from_slice(&self.a);
        }
        Some(Ok(()))
    }
}

/// `out_i = A x_i` for the k points `x_i` (rows of `points`), A r × c: each entry summed left
/// to right.
#[inline(always)]
fn map_points(a: &[f64], points: &[f64], k: usize, out: &mut [f64], r: usize, c: usize) {
    let a = &a[..r * c];
    for i in 0..k {
        let (x, o) = (&points[i * c..][..c], &mut out[i * r..][..r]);
        for j in 0..r {
            let row = &a[j * c..][..c];
            let mut acc = 0.0;
            for l in 0..c {
                acc += row[l] * x[l];
            }
            o[j] = acc;
        }
    }
}

/// `x ↦ c` for a constant `c` of `dim_out` numbers (e.g. a constant noise gain G, n × r).
#[derive(Debug, Clone)]
pub struct ConstantMap {
    values: Vec<f64>,
    dim_in: usize,
}

impl ConstantMap {
    /// The map from `dim_in` states to `values`.
    pub fn new(values: Vec<f64>, dim_in: usize) -> Self {
        ConstantMap { values, dim_in }
    }
}

impl PointFunction for ConstantMap {
    fn dim_in(&self) -> usize {
        self.dim_in
    }

    fn dim_out(&self) -> usize {
        self.values.len()
    }

    fn eval(&self, _points: &[f64], k: usize, _t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Result<()> {
        for block in out.chunks_exact_mut(self.values.len().max(1)).take(k) {
            block.copy_from_slice(&self.values);
        }
        Ok(())
    }
}

/// Scratch for [`jacobian_by_differences`]: the 2n difference points and their images.
#[derive(Debug, Clone, Default)]
pub(crate) struct Differences {
    points: Vec<f64>,
    images: Vec<f64>,
    steps: Vec<f64>,
}

/// `∂φ/∂x` at `x` (`dim_out × n` into `out`) by central differences, all 2n points in one
/// call of `φ`: column j is `(φ(x + δ_j e_j) − φ(x − δ_j e_j)) / 2δ_j` with
/// `δ_j = ε^{1/3} max(|x_j|, 1)` (ε the machine epsilon; the step that balances truncation
/// and rounding error for a central difference). Output components listed in `angles` are
/// angles: their differences are wrapped to [−π, π) first, so a function that wraps its
/// output (atan2) is differenced across ±π correctly.
pub(crate) fn jacobian_by_differences(
    phi: &dyn PointFunction,
    x: &[f64],
    t: usize,
    u: Option<&[f64]>,
    angles: &[usize],
    scratch: &mut Differences,
    out: &mut [f64],
) -> Result<()> {
    let (n, r) = (x.len(), phi.dim_out());
    let Differences { points, images, steps } = scratch;
    points.resize(2 * n * n, 0.0);
    images.resize(2 * n * r, 0.0);
    steps.resize(n, 0.0);
    let cbrt_eps = f64::EPSILON.cbrt();
    for j in 0..n {
        steps[j] = cbrt_eps * x[j].abs().max(1.0);
        for (side, sign) in [(0, 1.0), (1, -1.0)] {
            let row = &mut points[(side * n + j) * n..(side * n + j + 1) * n];
            row.copy_from_slice(x);
            row[j] += sign * steps[j];
        }
    }
    phi.eval(points, 2 * n, t, u, images)?;
    for j in 0..n {
        // The step actually taken (x ± δ rounds), so that the quotient is exact for a linear φ.
        let h = points[j * n + j] - points[(n + j) * n + j];
        for i in 0..r {
            let mut diff = images[j * r + i] - images[(n + j) * r + i];
            if angles.contains(&i) {
                diff = wrap_angle(diff);
            }
            out[i * n + j] = diff / h;
        }
    }
    Ok(())
}

/// `a − 2π ⌊(a + π) / 2π⌋`, in [−π, π).
#[inline]
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if a.abs() < 3.0 {
        // the formula's value here (the floor is 0), without the call of floor
        return a;
    }
    a - TAU * ((a + PI) / TAU).floor()
}

/// The Hessians of every output of `φ` at `x` (`dim_out × n × n` into `out`) by second central
/// differences with the step `δ_j = ε^{1/4} max(|x_j|, 1)`, all 1 + 2n² points in one call:
/// `H_jj = (φ(x + δ_j e_j) − 2φ(x) + φ(x − δ_j e_j)) / δ_j²` and, for j < l,
/// `H_jl = H_lj = (φ(++) − φ(+−) − φ(−+) + φ(−−)) / 4δ_jδ_l`.
pub(crate) fn hessian_by_differences(
    phi: &dyn PointFunction,
    x: &[f64],
    t: usize,
    u: Option<&[f64]>,
    scratch: &mut Differences,
    out: &mut [f64],
) -> Result<()> {
    let (n, r) = (x.len(), phi.dim_out());
    let count = 1 + 2 * n * n;
    let Differences { points, images, steps } = scratch;
    points.resize(count * n, 0.0);
    images.resize(count * r, 0.0);
    steps.resize(n, 0.0);
    let quarter_eps = f64::EPSILON.powf(0.25);
    for j in 0..n {
        steps[j] = quarter_eps * x[j].abs().max(1.0);
    }
    {
        let mut rows = points.chunks_exact_mut(n);
        let mut next = |moves: &[(usize, f64)]| {
            let row = rows.next().unwrap_or_default();
            row.copy_from_slice(x);
            for &(j, sign) in moves {
                row[j] += sign * steps[j];
            }
        };
        next(&[]);
        for j in 0..n {
            next(&[(j, 1.0)]);
            next(&[(j, -1.0)]);
        }
        for j in 0..n {
            for l in j + 1..n {
                for (a, b) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                    next(&[(j, a), (l, b)]);
                }
            }
        }
    }
    phi.eval(points, count, t, u, images)?;
    let z = |p: usize, i: usize| images[p * r + i];
    for i in 0..r {
        let h = &mut out[i * n * n..(i + 1) * n * n];
        for j in 0..n {
            h[j * n + j] = (z(1 + 2 * j, i) - 2.0 * z(0, i) + z(2 + 2 * j, i)) / (steps[j] * steps[j]);
        }
        let mut p = 1 + 2 * n;
        for j in 0..n {
            for l in j + 1..n {
                let v = (z(p, i) - z(p + 1, i) - z(p + 2, i) + z(p + 3, i)) / (4.0 * steps[j] * steps[l]);
                h[j * n + l] = v;
                h[l * n + j] = v;
                p += 4;
            }
        }
    }
    Ok(())
}
