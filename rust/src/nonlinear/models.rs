//! Built-in nonlinear models written in Rust: the coordinated turn and the range–bearing
//! sensor. They are [`PointFunction`]s with closed-form Jacobians, and compose with each other
//! and with linear maps in one [`NonlinearModel`](super::NonlinearModel).

use super::function::PointFunction;
use super::trig::{self, LANES};
use crate::core::isa::run_wide;
use crate::error::{Error, Result};

/// Coordinated turn with unknown turn rate, state (p_x, p_y, v_x, v_y, ω): the exact
/// discretization over a step `dt` for a constant ω (Bar-Shalom, Li & Kirubarajan 2001, ch. 11;
/// Li & Jilkov 2003):
///
/// ```text
/// p_x' = p_x + s v_x − c v_y     v_x' = C v_x − S v_y     ω' = ω
/// p_y' = p_y + c v_x + s v_y     v_y' = S v_x + C v_y
/// s = sin(ω dt)/ω = dt sinc(ω dt),  c = (1 − cos ω dt)/ω = (ω dt²/2) sinc²(ω dt/2),
/// C = cos ω dt,  S = sin ω dt
/// ```
///
/// from one sine and cosine of ω dt, with 1 − C = S²/(1 + C) for |ω dt| ≤ π/2 so that
/// ω → 0 (the constant-velocity model) has no cancellation (ω = 0 exactly: s = dt, c = 0); the
/// Jacobian's ω column switches to its Taylor series below |ω dt| = 0.02.
#[derive(Debug, Clone, Copy)]
pub struct CoordinatedTurn {
    dt: f64,
}

impl CoordinatedTurn {
    /// The model for a time step `dt` > 0.
    pub fn new(dt: f64) -> Result<Self> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(Error::arg("dt", format!("must be a finite number > 0, got {dt}")));
        }
        Ok(CoordinatedTurn { dt })
    }

    /// f(x) into `out` (5), given (sin ω dt, cos ω dt).
    #[inline(always)]
    fn value_at(&self, x: &[f64], sin_cos: (f64, f64), out: &mut [f64]) {
        let [px, py, vx, vy, w] = [x[0], x[1], x[2], x[3], x[4]];
        let (s, c, cos, sin) = turn(w, self.dt, sin_cos);
        out.copy_from_slice(&[px + s * vx - c * vy, py + c * vx + s * vy, cos * vx - sin * vy, sin * vx + cos * vy, w]);
    }

    /// `write(x, (sin ω dt, cos ω dt), row)` for each of the `k` points and its `width`
    /// numbers of `out`, the sines and cosines four points at a time (in AVX2 registers where
    /// the CPU has them).
    #[inline(always)]
    fn each_point(
        &self,
        points: &[f64],
        k: usize,
        out: &mut [f64],
        width: usize,
        write: impl Fn(&[f64], (f64, f64), &mut [f64]),
    ) {
        run_wide(
            #[inline(always)]
            || {
                for (xs, os) in points[..k * 5].chunks(5 * LANES).zip(out[..k * width].chunks_mut(width * LANES)) {
                    let (sin, cos) = turn_angles(xs, self.dt);
                    for (l, (x, o)) in xs.chunks_exact(5).zip(os.chunks_exact_mut(width)).enumerate() {
                        write(x, (sin[l], cos[l]), o);
                    }
                }
            },
        )
    }

    /// ∂f/∂x at x into `out` (5 × 5), given (sin ω dt, cos ω dt).
    #[inline(always)]
    fn jacobian_at(&self, x: &[f64], sin_cos: (f64, f64), out: &mut [f64]) {
        let dt = self.dt;
        let [vx, vy, w] = [x[2], x[3], x[4]];
        let (s, c, cos, sin) = turn(w, dt, sin_cos);
        let a = w * dt;
        // s' = ds/dω and c' = dc/dω: Taylor series near 0 (the closed forms are 0/0 there)
        let (ds, dc) = if a.abs() < 0.02 {
            let (t2, w2) = (dt * dt, w * w);
            (
                -w * dt * t2 / 3.0 + w * w2 * t2 * t2 * dt / 30.0 - w * w2 * w2 * t2 * t2 * t2 * dt / 840.0,
                t2 / 2.0 - w2 * t2 * t2 / 8.0 + w2 * w2 * t2 * t2 * t2 / 144.0,
            )
        } else {
            ((a * cos - sin) / (w * w), (a * sin - c * w) / (w * w))
        };
        #[rustfmt::skip]
        out.copy_from_slice(&[
            1.0, 0.0, s, -c, ds * vx - dc * vy,
            0.0, 1.0, c, s, dc * vx + ds * vy,
            0.0, 0.0, cos, -sin, -dt * (sin * vx + cos * vy),
            0.0, 0.0, sin, cos, dt * (cos * vx - sin * vy),
            0.0, 0.0, 0.0, 0.0, 1.0,
        ]);
    }
}

/// (sin x, cos x) of one number, in one call of the C library where it has `sincos` (one
/// argument reduction for both), else two. For one point (the EKF) the C library's
/// table-driven routines are faster than [`trig::sin_cos`]'s polynomials on one lane.
#[inline]
fn sin_cos_one(x: f64) -> (f64, f64) {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        extern "C" {
            fn sincos(x: f64, sin: *mut f64, cos: *mut f64);
        }
        let (mut s, mut c) = (0.0, 0.0);
        // SAFETY: glibc's sincos writes the two numbers behind the pointers, nothing else.
        unsafe { sincos(x, &mut s, &mut c) };
        (s, c)
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        x.sin_cos()
    }
}

/// (s, c, C, S) of the turn by ω over dt (see [`CoordinatedTurn`]), given (sin ω dt, cos ω dt).
#[inline]
fn turn(w: f64, dt: f64, (sin, cos): (f64, f64)) -> (f64, f64, f64, f64) {
    if w == 0.0 {
        return (dt, 0.0, 1.0, 0.0);
    }
    // 1 − cos: from sin²/(1 + cos) near 0 (no cancellation), directly past ±π/2
    let one_minus_cos = if cos >= 0.0 { sin * sin / (1.0 + cos) } else { 1.0 - cos };
    (sin / w, one_minus_cos / w, cos, sin)
}

/// `(sin ω dt, cos ω dt)` for the up to [`LANES`] 5-state points in `xs` (ω the fifth number),
/// computed together (one point, as in the EKF, through the C library).
#[inline(always)]
fn turn_angles(xs: &[f64], dt: f64) -> ([f64; LANES], [f64; LANES]) {
    if xs.len() == 5 {
        let (sin, cos) = sin_cos_one(xs[4] * dt);
        return ([sin; LANES], [cos; LANES]);
    }
    let mut angle = [0.0; LANES];
    for (a, x) in angle.iter_mut().zip(xs.chunks_exact(5)) {
        *a = x[4] * dt;
    }
    trig::sin_cos(angle)
}

/// The bearings `atan2(d_y, d_x)` of the up to [`LANES`] points in `xs` (rows of n) as seen
/// from `sensor`, computed together (one point through the C library).
#[inline(always)]
fn bearings(xs: &[f64], n: usize, sensor: [f64; 2]) -> [f64; LANES] {
    if xs.len() == n {
        return [(xs[1] - sensor[1]).atan2(xs[0] - sensor[0]); LANES];
    }
    // unused lanes at (1, 0): the fast path
    let (mut dy, mut dx) = ([0.0; LANES], [1.0; LANES]);
    for (l, x) in xs.chunks_exact(n).enumerate() {
        (dx[l], dy[l]) = (x[0] - sensor[0], x[1] - sensor[1]);
    }
    trig::atan2(dy, dx)
}

/// `√(x² + y²)`: the square root where the squares neither overflow nor underflow (to a
/// rounding of the C library's `hypot`, at a fraction of its cost), `hypot` elsewhere.
#[inline]
fn norm2(x: f64, y: f64) -> f64 {
    let sum = x * x + y * y;
    if squares_in_range(sum) {
        sum.sqrt()
    } else {
        x.hypot(y)
    }
}

/// Whether a sum of squares neither overflowed nor underflowed (far from both), so that its
/// square root is the norm to a rounding.
#[inline]
fn squares_in_range(sum: f64) -> bool {
    sum < 1e300 && sum > 1e-300
}

impl PointFunction for CoordinatedTurn {
    fn dim_in(&self) -> usize {
        5
    }

    fn dim_out(&self) -> usize {
        5
    }

    fn eval(&self, points: &[f64], k: usize, _t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Result<()> {
        self.each_point(points, k, out, 5, |x, sin_cos, o| self.value_at(x, sin_cos, o));
        Ok(())
    }

    fn jacobian(&self, points: &[f64], k: usize, _t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Option<Result<()>> {
        self.each_point(points, k, out, 25, |x, sin_cos, j| self.jacobian_at(x, sin_cos, j));
        Some(Ok(()))
    }

    fn eval_with_jacobian(
        &self,
        x: &[f64],
        _t: usize,
        _u: Option<&[f64]>,
        value: &mut [f64],
        jac: &mut [f64],
    ) -> Option<Result<()>> {
        // one sine and cosine for both (the EKF's time update)
        let sin_cos = sin_cos_one(x[4] * self.dt);
        self.value_at(x, sin_cos, &mut value[..5]);
        self.jacobian_at(x, sin_cos, &mut jac[..25]);
        Some(Ok(()))
    }
}

/// A range–bearing sensor at `sensor` = (s_x, s_y) seeing the position (x₀, x₁) of an n-state:
/// `y = (r, θ)` with `r = |d|`, `θ = atan2(d_y, d_x)` (the mathematical angle, from the x axis
/// counter-clockwise, in (−π, π]), `d = (x₀ − s_x, x₁ − s_y)`. The bearing is an angle: declare
/// it (`angles = [1]`) so that innovations are wrapped.
#[derive(Debug, Clone, Copy)]
pub struct RangeBearing {
    sensor: [f64; 2],
    n: usize,
}

impl RangeBearing {
    /// The sensor at `sensor` for a state of `n ≥ 2` components whose first two are the position.
    pub fn new(sensor: [f64; 2], n: usize) -> Result<Self> {
        if sensor.iter().any(|v| !v.is_finite()) {
            return Err(Error::arg("sensor", format!("must be finite, got {sensor:?}")));
        }
        if n < 2 {
            return Err(Error::arg("n", format!("a range-bearing sensor needs a position (n ≥ 2), got n = {n}")));
        }
        Ok(RangeBearing { sensor, n })
    }

    fn offset(&self, x: &[f64]) -> (f64, f64) {
        (x[0] - self.sensor[0], x[1] - self.sensor[1])
    }
}

/// The range–bearing Jacobian (2 × n) at the offset `(dx, dy)` from the sensor, with r² and r:
/// ∂r/∂p = d/r, ∂θ/∂p = (−d_y, d_x)/r², zero for the other components.
#[inline]
fn write_jacobian(j: &mut [f64], n: usize, (dx, dy): (f64, f64), r2: f64, r: f64) {
    j.fill(0.0);
    j[..2].copy_from_slice(&[dx / r, dy / r]);
    j[n..n + 2].copy_from_slice(&[-dy / r2, dx / r2]);
}

impl PointFunction for RangeBearing {
    fn dim_in(&self) -> usize {
        self.n
    }

    fn dim_out(&self) -> usize {
        2
    }

    fn eval(&self, points: &[f64], k: usize, _t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Result<()> {
        let n = self.n;
        run_wide(
            #[inline(always)]
            || {
                for (xs, os) in points[..k * n].chunks(n * LANES).zip(out[..k * 2].chunks_mut(2 * LANES)) {
                    let bearing = bearings(xs, n, self.sensor);
                    for (l, (x, o)) in xs.chunks_exact(n).zip(os.chunks_exact_mut(2)).enumerate() {
                        let (dx, dy) = self.offset(x);
                        o.copy_from_slice(&[norm2(dx, dy), bearing[l]]);
                    }
                }
            },
        );
        Ok(())
    }

    fn jacobian(&self, points: &[f64], k: usize, t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Option<Result<()>> {
        let n = self.n;
        for (x, j) in points.chunks_exact(n).zip(out.chunks_exact_mut(2 * n)).take(k) {
            let (dx, dy) = self.offset(x);
            let r2 = dx * dx + dy * dy;
            if r2.is_nan() || r2 <= 0.0 {
                return Some(Err(Error::arg_at(
                    "h",
                    t,
                    "the range-bearing Jacobian is undefined at the sensor's position (range 0)",
                )));
            }
            write_jacobian(&mut j[..2 * n], n, (dx, dy), r2, r2.sqrt());
        }
        Some(Ok(()))
    }

    fn eval_with_jacobian(
        &self,
        x: &[f64],
        t: usize,
        u: Option<&[f64]>,
        value: &mut [f64],
        jac: &mut [f64],
    ) -> Option<Result<()>> {
        // the range is the Jacobian's r where the squares are in range (as in norm2)
        let (dx, dy) = self.offset(x);
        let r2 = dx * dx + dy * dy;
        if !squares_in_range(r2) {
            // out of that range, or at the sensor: the two apart, with their checks
            if let Err(e) = self.eval(x, 1, t, u, value) {
                return Some(Err(e));
            }
            return self.jacobian(x, 1, t, u, jac);
        }
        let (n, r) = (self.n, r2.sqrt());
        value[..2].copy_from_slice(&[r, dy.atan2(dx)]);
        write_jacobian(&mut jac[..2 * n], n, (dx, dy), r2, r);
        Some(Ok(()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The EKF's value and Jacobian at one point together are the bits of `eval` and `jacobian`
    /// called apart, and a batch of points (4-lane sines and cosines) agrees with one point at
    /// a time (the C library's) to a few ulp.
    #[test]
    fn coordinated_turn_value_with_jacobian_and_batches() {
        let ct = CoordinatedTurn::new(0.1).unwrap();
        let points: Vec<f64> = (0..11).flat_map(|i| [1.0, -2.0, 3.0, 0.5, 0.3 * i as f64 - 1.4]).collect();
        let (mut batch, mut batch_jac) = (vec![0.0; 55], vec![0.0; 275]);
        ct.eval(&points, 11, 0, None, &mut batch).unwrap();
        ct.jacobian(&points, 11, 0, None, &mut batch_jac).unwrap().unwrap();
        for (i, x) in points.chunks_exact(5).enumerate() {
            let (mut value, mut jac, mut both, mut both_jac) = ([0.0; 5], [0.0; 25], [0.0; 5], [0.0; 25]);
            ct.eval(x, 1, 0, None, &mut value).unwrap();
            ct.jacobian(x, 1, 0, None, &mut jac).unwrap().unwrap();
            ct.eval_with_jacobian(x, 0, None, &mut both, &mut both_jac).unwrap().unwrap();
            assert_eq!((value, jac), (both, both_jac));
            for (one, many) in
                value.iter().chain(&jac).zip(batch[i * 5..][..5].iter().chain(&batch_jac[i * 25..][..25]))
            {
                assert!((one - many).abs() <= 1e-15 * one.abs().max(1.0), "point {i}: {one} vs {many}");
            }
        }
    }

    /// The range–bearing value and Jacobian together are the bits of `eval` and `jacobian`
    /// apart, in and out of the squares' range; at the sensor it is the Jacobian's error.
    #[test]
    fn range_bearing_value_with_jacobian() {
        let cases = [
            ([1.0, -2.0], [3.0, 4.0, 0.5, 0.1]),
            ([1.0, -2.0], [-1e200, 3e199, 0.0, 0.0]),
            ([0.0, 0.0], [1e-160, -2e-160, 0.0, 0.0]),
        ];
        for (sensor, x) in cases {
            let rb = RangeBearing::new(sensor, 4).unwrap();
            let (mut value, mut jac, mut both, mut both_jac) = ([0.0; 2], [0.0; 8], [0.0; 2], [0.0; 8]);
            rb.eval(&x, 1, 0, None, &mut value).unwrap();
            rb.jacobian(&x, 1, 0, None, &mut jac).unwrap().unwrap();
            rb.eval_with_jacobian(&x, 0, None, &mut both, &mut both_jac).unwrap().unwrap();
            assert_eq!((value, jac), (both, both_jac), "{x:?}");
        }
        let rb = RangeBearing::new([1.0, -2.0], 4).unwrap();
        let (mut value, mut jac) = ([0.0; 2], [0.0; 8]);
        let at_sensor = rb.eval_with_jacobian(&[1.0, -2.0, 0.0, 0.0], 7, None, &mut value, &mut jac).unwrap();
        assert!(at_sensor.unwrap_err().to_string().contains("range 0"));
    }

    /// The ω column of the turn's Jacobian is continuous across the switch to its Taylor
    /// series and matches differences of the closed form on both sides; at ω = 0 it is the
    /// constant-velocity limit (−dt² v_y/2, dt² v_x/2, −dt v_y, dt v_x).
    #[test]
    fn coordinated_turn_jacobian_near_zero_turn_rate() {
        let dt = 0.5;
        let ct = CoordinatedTurn::new(dt).unwrap();
        let jac = |w: f64| {
            let mut j = [0.0; 25];
            ct.jacobian(&[1.0, 2.0, 3.0, -4.0, w], 1, 0, None, &mut j).unwrap().unwrap();
            [j[4], j[9], j[14], j[19]]
        };
        let at0 = jac(0.0);
        let (vx, vy) = (3.0, -4.0);
        let want = [-dt * dt * vy / 2.0, dt * dt * vx / 2.0, -dt * vy, dt * vx];
        for (g, w) in at0.iter().zip(want) {
            assert!((g - w).abs() < 1e-15, "{at0:?} vs {want:?}");
        }
        let switch = 0.02 / dt;
        let (below, above) = (jac(switch * (1.0 - 1e-12)), jac(switch * (1.0 + 1e-12)));
        for (b, a) in below.iter().zip(above) {
            assert!((b - a).abs() < 1e-12 * a.abs().max(1.0), "{below:?} vs {above:?}");
        }
        for w in [1e-3, 0.039, 0.041, 0.7] {
            let h = 1e-6;
            let f = |w: f64| {
                let mut o = [0.0; 5];
                ct.eval(&[1.0, 2.0, 3.0, -4.0, w], 1, 0, None, &mut o).unwrap();
                o
            };
            let (plus, minus) = (f(w + h), f(w - h));
            let got = jac(w);
            for i in 0..4 {
                let diff = (plus[i] - minus[i]) / (2.0 * h);
                assert!((got[i] - diff).abs() < 1e-7, "w = {w}, row {i}: {} vs {diff}", got[i]);
            }
        }
    }
}

/// A bearings-only sensor at `sensor` = (s_x, s_y): `y = atan2(d_y, d_x)` of the position
/// (x₀, x₁) of an n-state, `d = (x₀ − s_x, x₁ − s_y)`: the bearing row of [`RangeBearing`].
#[derive(Debug, Clone, Copy)]
pub struct Bearing(RangeBearing);

impl Bearing {
    /// The sensor at `sensor` for a state of `n ≥ 2` components whose first two are the position.
    pub fn new(sensor: [f64; 2], n: usize) -> Result<Self> {
        Ok(Bearing(RangeBearing::new(sensor, n)?))
    }
}

impl PointFunction for Bearing {
    fn dim_in(&self) -> usize {
        self.0.n
    }

    fn dim_out(&self) -> usize {
        1
    }

    fn eval(&self, points: &[f64], k: usize, _t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Result<()> {
        let n = self.0.n;
        run_wide(
            #[inline(always)]
            || {
                for (xs, os) in points[..k * n].chunks(n * LANES).zip(out[..k].chunks_mut(LANES)) {
                    let bearing = bearings(xs, n, self.0.sensor);
                    os.copy_from_slice(&bearing[..os.len()]);
                }
            },
        );
        Ok(())
    }

    fn jacobian(&self, points: &[f64], k: usize, t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Option<Result<()>> {
        let n = self.0.n;
        for (x, j) in points.chunks_exact(n).zip(out.chunks_exact_mut(n)).take(k) {
            let (dx, dy) = self.0.offset(x);
            let r2 = dx * dx + dy * dy;
            if r2.is_nan() || r2 <= 0.0 {
                return Some(Err(Error::arg_at("h", t, "the bearing is undefined at the sensor's position (range 0)")));
            }
            j.fill(0.0);
            j[..2].copy_from_slice(&[-dy / r2, dx / r2]);
        }
        Some(Ok(()))
    }
}

/// A 3-D range–bearing–elevation sensor at `sensor` = (s_x, s_y, s_z) seeing the position
/// (x₀, x₁, x₂) of an n-state: `y = (r, θ, φ)` with `d = p − s`, `ρ = √(d_x² + d_y²)`,
/// `r = √(ρ² + d_z²)`, azimuth `θ = atan2(d_y, d_x)` and elevation `φ = atan2(d_z, ρ)`.
/// The azimuth is an angle (wrap it: `angles = [1]`).
#[derive(Debug, Clone, Copy)]
pub struct RangeBearingElevation {
    sensor: [f64; 3],
    n: usize,
}

impl RangeBearingElevation {
    /// The sensor at `sensor` for a state of `n ≥ 3` components whose first three are the
    /// position.
    pub fn new(sensor: [f64; 3], n: usize) -> Result<Self> {
        if sensor.iter().any(|v| !v.is_finite()) {
            return Err(Error::arg("sensor", format!("must be finite, got {sensor:?}")));
        }
        if n < 3 {
            return Err(Error::arg("n", format!("a 3-D sensor needs a 3-D position (n ≥ 3), got n = {n}")));
        }
        Ok(RangeBearingElevation { sensor, n })
    }
}

impl PointFunction for RangeBearingElevation {
    fn dim_in(&self) -> usize {
        self.n
    }

    fn dim_out(&self) -> usize {
        3
    }

    fn eval(&self, points: &[f64], k: usize, _t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Result<()> {
        for (x, o) in points.chunks_exact(self.n).zip(out.chunks_exact_mut(3)).take(k) {
            let [dx, dy, dz] = [x[0] - self.sensor[0], x[1] - self.sensor[1], x[2] - self.sensor[2]];
            let rho = norm2(dx, dy);
            o.copy_from_slice(&[norm2(rho, dz), dy.atan2(dx), dz.atan2(rho)]);
        }
        Ok(())
    }

    fn jacobian(&self, points: &[f64], k: usize, t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Option<Result<()>> {
        let n = self.n;
        for (x, j) in points.chunks_exact(n).zip(out.chunks_exact_mut(3 * n)).take(k) {
            let [dx, dy, dz] = [x[0] - self.sensor[0], x[1] - self.sensor[1], x[2] - self.sensor[2]];
            let rho2 = dx * dx + dy * dy;
            let r2 = rho2 + dz * dz;
            if rho2.is_nan() || rho2 <= 0.0 {
                return Some(Err(Error::arg_at(
                    "h",
                    t,
                    "the azimuth is undefined with the target straight above or below the sensor",
                )));
            }
            let (rho, r) = (rho2.sqrt(), r2.sqrt());
            j.fill(0.0);
            j[..3].copy_from_slice(&[dx / r, dy / r, dz / r]);
            j[n..n + 2].copy_from_slice(&[-dy / rho2, dx / rho2]);
            j[2 * n..2 * n + 3].copy_from_slice(&[-dx * dz / (r2 * rho), -dy * dz / (r2 * rho), rho / r2]);
        }
        Some(Ok(()))
    }
}

/// The univariate nonstationary growth model (Kitagawa 1996; Gordon, Salmond & Smith 1993):
/// `x[t+1] = x/2 + 25 x/(1 + x²) + 8 cos(1.2 t)` (t the step of the transition t → t+1) as f,
/// or its measurement `y = x²/20` as h ([`Ungm::measurement`]).
#[derive(Debug, Clone, Copy)]
pub struct Ungm {
    measurement: bool,
}

impl Ungm {
    /// The transition f.
    pub fn transition() -> Self {
        Ungm { measurement: false }
    }

    /// The measurement h.
    pub fn measurement() -> Self {
        Ungm { measurement: true }
    }
}

impl PointFunction for Ungm {
    fn dim_in(&self) -> usize {
        1
    }

    fn dim_out(&self) -> usize {
        1
    }

    fn eval(&self, points: &[f64], k: usize, t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Result<()> {
        let forcing = 8.0 * (1.2 * t as f64).cos();
        for (x, o) in points.iter().zip(out.iter_mut()).take(k) {
            *o = if self.measurement { x * x / 20.0 } else { x / 2.0 + 25.0 * x / (1.0 + x * x) + forcing };
        }
        Ok(())
    }

    fn jacobian(&self, points: &[f64], k: usize, _t: usize, _u: Option<&[f64]>, out: &mut [f64]) -> Option<Result<()>> {
        for (x, o) in points.iter().zip(out.iter_mut()).take(k) {
            let q = 1.0 + x * x;
            *o = if self.measurement { x / 10.0 } else { 0.5 + 25.0 * (1.0 - x * x) / (q * q) };
        }
        Some(Ok(()))
    }
}
