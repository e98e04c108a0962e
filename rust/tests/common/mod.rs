//! Helpers shared by the integration tests: a seeded random generator (no dependencies) and
//! small dense linear algebra on row-major `Vec<f64>` matrices, written independently of the
//! crate so that the tests check kfast against code it does not share.

// Each test crate uses a different subset of these helpers.
#![allow(dead_code)]

use kfast::{Result, StepMatrix};

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny seeded generator, good enough for test data.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform on [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform on [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// An integer in lo..=hi.
    pub fn int(&mut self, lo: usize, hi: usize) -> usize {
        lo + (self.next_u64() % (hi - lo + 1) as u64) as usize
    }

    /// Standard normal (Box–Muller; one of the pair is discarded).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // in (0, 1]: ln is finite
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }

    /// A `rows × cols` matrix of standard normals.
    pub fn normals(&mut self, rows: usize, cols: usize) -> Vec<f64> {
        (0..rows * cols).map(|_| self.normal()).collect()
    }

    /// A random symmetric positive definite `n × n` matrix G G'/n + jitter I.
    pub fn spd(&mut self, n: usize, jitter: f64) -> Vec<f64> {
        let g = self.normals(n, n);
        let mut a = matmul(&g, &transpose(&g, n, n), n, n, n);
        for (i, v) in a.iter_mut().enumerate() {
            *v /= n as f64;
            if i % (n + 1) == 0 {
                *v += jitter;
            }
        }
        a
    }
}

/// A constant `rows × cols` model matrix from row-major data.
pub fn mat(rows: usize, cols: usize, data: &[f64]) -> Result<StepMatrix> {
    StepMatrix::constant(rows, cols, data.to_vec())
}

/// The `n × n` identity.
pub fn eye(n: usize) -> Vec<f64> {
    (0..n * n).map(|i| if i % (n + 1) == 0 { 1.0 } else { 0.0 }).collect()
}

/// `a[r×k] · b[k×c]`.
pub fn matmul(a: &[f64], b: &[f64], r: usize, k: usize, c: usize) -> Vec<f64> {
    assert_eq!((a.len(), b.len()), (r * k, k * c), "matmul shapes");
    let mut out = vec![0.0; r * c];
    for i in 0..r {
        for l in 0..k {
            let a_il = a[i * k + l];
            for j in 0..c {
                out[i * c + j] += a_il * b[l * c + j];
            }
        }
    }
    out
}

/// `a[r×c]'`.
pub fn transpose(a: &[f64], r: usize, c: usize) -> Vec<f64> {
    let mut out = vec![0.0; r * c];
    for i in 0..r {
        for j in 0..c {
            out[j * r + i] = a[i * c + j];
        }
    }
    out
}

/// `a + b`.
pub fn add(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + y).collect()
}

/// `a − b`.
pub fn sub(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x - y).collect()
}

/// `c · a`.
pub fn scale(a: &[f64], c: f64) -> Vec<f64> {
    a.iter().map(|x| c * x).collect()
}

/// Largest absolute entry.
pub fn max_abs(a: &[f64]) -> f64 {
    a.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// `a⁻¹ b` for an `n × n` `a` and `n × c` `b` by Gaussian elimination with partial pivoting.
pub fn solve(a: &[f64], b: &[f64], n: usize, c: usize) -> Vec<f64> {
    let (mut a, mut b) = (a.to_vec(), b.to_vec());
    for col in 0..n {
        let pivot = (col..n).max_by(|&i, &j| a[i * n + col].abs().total_cmp(&a[j * n + col].abs())).unwrap();
        assert!(a[pivot * n + col] != 0.0, "solve: singular matrix");
        for j in 0..n {
            a.swap(col * n + j, pivot * n + j);
        }
        for j in 0..c {
            b.swap(col * c + j, pivot * c + j);
        }
        for i in col + 1..n {
            let f = a[i * n + col] / a[col * n + col];
            for j in col..n {
                a[i * n + j] -= f * a[col * n + j];
            }
            for j in 0..c {
                b[i * c + j] -= f * b[col * c + j];
            }
        }
    }
    for col in (0..n).rev() {
        for j in 0..c {
            let tail: f64 = (col + 1..n).map(|l| a[col * n + l] * b[l * c + j]).sum();
            b[col * c + j] = (b[col * c + j] - tail) / a[col * n + col];
        }
    }
    b
}

/// The spectral radius of the `n × n` `a` by Gelfand's formula ρ = lim ‖a^k‖^(1/k), with
/// k = 2^40 reached by repeated squaring (renormalized each time so nothing over- or
/// underflows). Shares no code with the crate's eigenvalue solvers; accurate to a relative
/// ~1e-10 for matrices whose eigenvalues of largest modulus are semisimple.
pub fn spectral_radius_gelfand(a: &[f64], n: usize) -> f64 {
    const SQUARINGS: i32 = 40;
    let norm = max_abs(a);
    if norm == 0.0 {
        return 0.0;
    }
    let mut p = scale(a, 1.0 / norm);
    // ‖a^(2^j)‖ = exp(log_norm) · ‖p‖ with ‖p‖ = 1.
    let mut log_norm = norm.ln();
    for _ in 0..SQUARINGS {
        p = matmul(&p, &p, n, n, n);
        let norm = max_abs(&p);
        if norm == 0.0 {
            return 0.0; // nilpotent
        }
        p = scale(&p, 1.0 / norm);
        log_norm = 2.0 * log_norm + norm.ln();
    }
    (log_norm / 2f64.powi(SQUARINGS)).exp()
}

/// `|got − want| ≤ atol + rtol · |want|` elementwise (NaN matches NaN).
pub fn assert_close(what: &str, got: &[f64], want: &[f64], rtol: f64, atol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        let ok = (g.is_nan() && w.is_nan()) || (g - w).abs() <= atol + rtol * w.abs();
        assert!(ok, "{what}[{i}]: got {g}, want {w} (rtol {rtol}, atol {atol})");
    }
}

/// Bitwise equality of two float slices (so that NaN equals NaN and −0 differs from +0).
pub fn assert_bits_eq(what: &str, got: &[f64], want: &[f64]) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(g.to_bits() == w.to_bits(), "{what}[{i}]: got {g:e}, want {w:e} (not bit for bit)");
    }
}

/// A seeded random model with n states, m outputs: F of spectral radius 0.5–1.1, H normal, the
/// joint noise covariance [[Q, N], [N', R]] one random positive definite matrix (N kept when
/// `with_n`), B and D normal when k > 0. With `per_step = Some(T)`, F and Q are given per step
/// (F[t] = F (1 + 0.1 sin t), Q[t] = Q (1 + 0.5 t / T)).
pub fn random_model(
    rng: &mut Rng,
    n: usize,
    m: usize,
    k: usize,
    with_n: bool,
    per_step: Option<usize>,
) -> Result<kfast::LinearGaussian> {
    let f = rng.normals(n, n);
    let f = scale(&f, rng.range(0.5, 1.1) / spectral_radius_gelfand(&f, n).max(1e-9));
    let h = rng.normals(m, n);
    let w = rng.spd(n + m, 0.2);
    let block = |r0: usize, c0: usize, rows: usize, cols: usize| -> Vec<f64> {
        (0..rows * cols).map(|i| w[(r0 + i / cols) * (n + m) + c0 + i % cols]).collect()
    };
    let q = block(0, 0, n, n);
    let (f, q) = match per_step {
        None => (mat(n, n, &f)?, mat(n, n, &q)?),
        Some(steps) => {
            let fs = (0..steps).flat_map(|t| scale(&f, 1.0 + 0.1 * (t as f64).sin())).collect();
            let qs = (0..steps).flat_map(|t| scale(&q, 1.0 + 0.5 * t as f64 / steps as f64)).collect();
            (StepMatrix::per_step(steps, n, n, fs)?, StepMatrix::per_step(steps, n, n, qs)?)
        }
    };
    let mut mats = kfast::Matrices::new(f, mat(m, n, &h)?, q, mat(m, m, &block(n, n, m, m))?);
    if with_n {
        mats.n = Some(mat(n, m, &block(0, n, n, m))?);
    }
    if k > 0 {
        mats.b = Some(mat(n, k, &rng.normals(n, k))?);
        mats.d = Some(mat(m, k, &rng.normals(m, k))?);
    }
    kfast::LinearGaussian::new(mats)
}
