//! Triangular factors for the square-root UKF (van der Merwe & Wan 2001): the factor of a sum
//! of outer products, and the rank-one downdate of a factor.

/// The lower-triangular `l` (n × n, diagonal ≥ 0) with `L L' = A A'` for `a` (n × c, row-major,
/// c ≥ n), by the LQ decomposition of A with Householder reflections (Q never formed); `a` is
/// overwritten and `v` is scratch (c numbers). Written `tria(A)` in the square-root filtering
/// literature: L L' = Σ_j a_j a_j' for the columns a_j, with no product formed, so it stays
/// positive semidefinite in floating point.
pub(crate) fn tria(a: &mut [f64], n: usize, c: usize, v: &mut [f64], l: &mut [f64]) {
    debug_assert!(c >= n && a.len() >= n * c && v.len() >= c && l.len() >= n * n);
    for i in 0..n {
        let row = &a[i * c..][..c];
        let norm = row[i..].iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm == 0.0 {
            continue; // row i is already zero from column i on
        }
        // H = I − 2 v v' / (v'v) with v = x − α e_i maps row i's tail x onto α e_i; α takes the
        // sign opposite to x_i so that v_i = x_i − α does not cancel
        let alpha = if row[i] > 0.0 { -norm } else { norm };
        v[i..c].copy_from_slice(&row[i..]);
        v[i] -= alpha;
        let vv: f64 = v[i..c].iter().map(|x| x * x).sum();
        for k in i + 1..n {
            let rk = &mut a[k * c..][..c];
            let dot: f64 = rk[i..].iter().zip(&v[i..c]).map(|(r, v)| r * v).sum();
            let scale = 2.0 * dot / vv;
            for (r, v) in rk[i..].iter_mut().zip(&v[i..c]) {
                *r -= scale * v;
            }
        }
        a[i * c + i] = alpha;
        a[i * c + i + 1..(i + 1) * c].fill(0.0);
    }
    // L = the first n columns; columns with a negative diagonal flipped (L L' is unchanged)
    for i in 0..n {
        for j in 0..n {
            l[i * n + j] = if j <= i { a[i * c + j] } else { 0.0 };
        }
    }
    for j in 0..n {
        if l[j * n + j] < 0.0 {
            for i in j..n {
                l[i * n + j] = -l[i * n + j];
            }
        }
    }
}

/// `L L' − x x'` in place: `l` (n × n lower, diagonal ≥ 0) becomes the factor of the downdated
/// matrix; `x` is destroyed. `Err(j)` when pivot j would not stay positive (the difference is
/// not positive definite to working precision); `l` is then partly updated.
pub(crate) fn downdate(l: &mut [f64], x: &mut [f64], n: usize) -> Result<(), usize> {
    for j in 0..n {
        if x[j] == 0.0 {
            continue; // nothing to remove along pivot j (also where it is 0: a singular factor)
        }
        let ljj = l[j * n + j];
        let r2 = (ljj - x[j]) * (ljj + x[j]);
        if !(r2 > 0.0 && r2.is_finite()) {
            return Err(j);
        }
        // a hyperbolic rotation of (L e_j, x) that zeroes x_j
        let r = r2.sqrt();
        let (c, s) = (r / ljj, x[j] / ljj);
        l[j * n + j] = r;
        for i in j + 1..n {
            let lij = (l[i * n + j] - s * x[i]) / c;
            x[i] = c * x[i] - s * lij;
            l[i * n + j] = lij;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn product(l: &[f64], n: usize) -> Vec<f64> {
        let mut p = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                p[i * n + j] = (0..n).map(|k| l[i * n + k] * l[j * n + k]).sum();
            }
        }
        p
    }

    fn close(a: &[f64], b: &[f64]) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() < 1e-12 * (1.0 + y.abs()), "{x} vs {y}");
        }
    }

    #[test]
    fn tria_factors_a_a_transposed_and_downdate_removes_an_outer_product() {
        let (n, c) = (3, 5);
        let a: Vec<f64> = (0..n * c).map(|i| ((i * 7 % 11) as f64 - 5.0) / 3.0).collect();
        let mut aat = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                aat[i * n + j] = (0..c).map(|k| a[i * c + k] * a[j * c + k]).sum();
            }
        }
        let (mut work, mut v, mut l) = (a.clone(), vec![0.0; c], vec![0.0; n * n]);
        tria(&mut work, n, c, &mut v, &mut l);
        close(&product(&l, n), &aat);
        assert!((0..n).all(|i| l[i * n + i] >= 0.0 && (i + 1..n).all(|j| l[i * n + j] == 0.0)));
        // remove the first column's outer product again
        let mut x: Vec<f64> = (0..n).map(|i| a[i * c]).collect();
        let want: Vec<f64> = (0..n * n).map(|k| aat[k] - a[(k / n) * c] * a[(k % n) * c]).collect();
        downdate(&mut l, &mut x, n).unwrap();
        close(&product(&l, n), &want);
        // removing more than there is fails, naming the pivot
        let mut big = vec![10.0, 0.0, 0.0];
        assert_eq!(downdate(&mut l, &mut big, n), Err(0));
    }
}
