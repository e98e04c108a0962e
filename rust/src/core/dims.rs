//! Sizes known at compile time or at run time, and scratch buffers of either kind.
//!
//! The small dense kernels of [`super::dense`] take their sizes as arguments; called with
//! [`Fixed`] sizes (compile-time constants) they are unrolled and vectorized for the common
//! small state and output dimensions, with [`Dyn`] sizes they serve every other size. The
//! arithmetic is identical either way, so results are the same bits. [`Fused`] wraps either
//! to make the kernels round each multiply-add once (see `core::isa`).

use crate::core::home::{FixedHome, Home};

/// The state and output sizes (n, m) of a step, and the buffer types that hold its vectors
/// and matrices: local arrays for [`Fixed`] sizes (which the compiler can keep in registers),
/// heap vectors for [`Dyn`]. A [`Fixed`] buffer of m rows also holds any block of `mo ≤ m`
/// observed components (its leading `mo`-row part).
pub(crate) trait Dims: Copy + Send + Sync {
    /// An n-vector.
    type Vector: Buf;
    /// An n × n matrix.
    type Square: Buf;
    /// An m-vector.
    type Obs: Buf;
    /// An m × m matrix.
    type ObsSquare: Buf;
    /// An n × m (or m × n) matrix.
    type StateObs: Buf;

    /// Whether the buffers are local arrays of compile-time size. A time loop over such a
    /// workspace keeps it in registers only if nothing of run-time size touches it and its
    /// address never leaves the loop (see `Run::steps` in `linear/filter`).
    const FIXED: bool;

    /// Whether the matrix products should be plain loops for the compiler to unroll whole
    /// (compile-time sizes up to 8); otherwise they run in register blocks
    /// (`core::dense`), which also compile to much less code.
    const UNROLL: bool;

    /// Whether each multiply-add of the kernels rounds once (`a.mul_add(b, c)`, [`Fused`]) or
    /// twice (`c + a * b`). Fused sizes run in loops compiled with FMA enabled (`core::isa`),
    /// except in deterministic mode on an x86-64 CPU without FMA, where `mul_add` is a
    /// library call (slow, and the same bits).
    const FUSED: bool;

    /// Whether products of run-time sizes above 12 may go to faer (`core::dense`), whose
    /// kernels, and so rounding, depend on the CPU: with fused run-time sizes outside
    /// deterministic mode, and for the matrix-equation solvers ([`Solver`]).
    const FAER: bool;

    /// Where the loops of these sizes are compiled ([`core::home`](crate::core::home)).
    type Home: Home;

    /// The state size n.
    fn n(self) -> usize;
    /// The output size m.
    fn m(self) -> usize;

    fn vector(self) -> Self::Vector {
        Buf::zeroed(self.n())
    }
    fn square(self) -> Self::Square {
        Buf::zeroed(self.n() * self.n())
    }
    fn obs(self) -> Self::Obs {
        Buf::zeroed(self.m())
    }
    fn obs_square(self) -> Self::ObsSquare {
        Buf::zeroed(self.m() * self.m())
    }
    fn state_obs(self) -> Self::StateObs {
        Buf::zeroed(self.n() * self.m())
    }
}

/// Sizes known at run time.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Dyn {
    pub n: usize,
    pub m: usize,
}

impl Dims for Dyn {
    type Vector = Vec<f64>;
    type Square = Vec<f64>;
    type Obs = Vec<f64>;
    type ObsSquare = Vec<f64>;
    type StateObs = Vec<f64>;

    type Home = crate::core::home::dynamic::Home;

    const FIXED: bool = false;
    const UNROLL: bool = false;
    const FUSED: bool = false;
    const FAER: bool = false;

    #[inline(always)]
    fn n(self) -> usize {
        self.n
    }
    #[inline(always)]
    fn m(self) -> usize {
        self.m
    }
}

/// Sizes known at compile time.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fixed<const N: usize, const M: usize>;

impl<const N: usize, const M: usize> Dims for Fixed<N, M>
where
    Self: FixedHome,
{
    type Vector = [[f64; N]; 1];
    type Square = [[f64; N]; N];
    type Obs = [[f64; M]; 1];
    type ObsSquare = [[f64; M]; M];
    type StateObs = [[f64; M]; N];
    type Home = <Self as FixedHome>::Home;

    const FIXED: bool = true;
    const UNROLL: bool = N <= 8;
    const FUSED: bool = false;
    const FAER: bool = false;

    #[inline(always)]
    fn n(self) -> usize {
        N
    }
    #[inline(always)]
    fn m(self) -> usize {
        M
    }
}

/// The sizes `D` with fused multiply-adds: the same buffers, the same order of operations,
/// each `c + a * b` rounded once.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fused<D>(pub D);

impl<D: Dims> Dims for Fused<D> {
    type Vector = D::Vector;
    type Square = D::Square;
    type Obs = D::Obs;
    type ObsSquare = D::ObsSquare;
    type StateObs = D::StateObs;
    type Home = D::Home;

    const FIXED: bool = D::FIXED;
    const UNROLL: bool = D::UNROLL;
    const FUSED: bool = true;
    const FAER: bool = !D::FIXED;

    #[inline(always)]
    fn n(self) -> usize {
        self.0.n()
    }
    #[inline(always)]
    fn m(self) -> usize {
        self.0.m()
    }
}

/// Run-time sizes for the matrix-equation solvers (the DARE's doubling): as [`Dyn`], with
/// large products in faer (the solvers are outside deterministic mode, docs/conventions.md).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Solver(pub Dyn);

impl Dims for Solver {
    type Vector = Vec<f64>;
    type Square = Vec<f64>;
    type Obs = Vec<f64>;
    type ObsSquare = Vec<f64>;
    type StateObs = Vec<f64>;

    type Home = crate::core::home::dynamic::Home;

    const FIXED: bool = false;
    const UNROLL: bool = false;
    const FUSED: bool = false;
    const FAER: bool = true;

    #[inline(always)]
    fn n(self) -> usize {
        self.0.n
    }
    #[inline(always)]
    fn m(self) -> usize {
        self.0.m
    }
}

/// A scratch buffer of `f64`s seen as one slice.
pub(crate) trait Buf: Clone + std::fmt::Debug + Send {
    /// `len` zeros (a fixed-size buffer ignores `len`: its size is its type's).
    fn zeroed(len: usize) -> Self;
    fn get(&self) -> &[f64];
    fn get_mut(&mut self) -> &mut [f64];
}

impl Buf for Vec<f64> {
    fn zeroed(len: usize) -> Self {
        vec![0.0; len]
    }
    #[inline(always)]
    fn get(&self) -> &[f64] {
        self
    }
    #[inline(always)]
    fn get_mut(&mut self) -> &mut [f64] {
        self
    }
}

impl<const R: usize, const C: usize> Buf for [[f64; C]; R] {
    #[inline(always)]
    fn zeroed(_len: usize) -> Self {
        [[0.0; C]; R]
    }
    #[inline(always)]
    fn get(&self) -> &[f64] {
        self.as_flattened()
    }
    #[inline(always)]
    fn get_mut(&mut self) -> &mut [f64] {
        self.as_flattened_mut()
    }
}

/// The sizes [`with_dims!`] compiles, in words (for `kfast._kfast.kernel_info()`).
#[cfg(all(feature = "python", not(kfast_dev_sizes), not(feature = "unfused-sizes")))]
pub(crate) const FIXED_SIZES: &str =
    "n <= 12 with m <= min(n, 4) in the fused loops (compile-time sizes; others, and the unfused loops, run-time)";
#[cfg(all(feature = "python", not(kfast_dev_sizes), feature = "unfused-sizes"))]
pub(crate) const FIXED_SIZES: &str =
    "n <= 12 with m <= min(n, 4) in the fused and the unfused loops (compile-time sizes; others run-time)";
#[cfg(all(feature = "python", kfast_dev_sizes))]
pub(crate) const FIXED_SIZES: &str = "(1, 1), (2, 1), (4, 2), (5, 2), (9, 2) only (a kfast_dev_sizes build)";

/// Evaluates `$body` with `$d` bound to compile-time sizes for n ≤ 12 and m ≤ min(n, 4), so
/// that the kernels are unrolled for them, and to the run-time sizes otherwise:
/// `with_dims!(kernel, n, m, |d| run.filter(d, &mut out))`. Compile-time sizes only for a
/// `kernel` whose loops are compiled for them ([`Kernel::fixed_sizes`](crate::core::isa::Kernel::fixed_sizes)):
/// the body must run its loops with that kernel. The body is compiled once per size; the
/// arithmetic is the same either way.
///
/// Why every pair up to 12 × 4: a step with run-time sizes costs 2.5–4× one with compile-time
/// sizes (loop control and bounds checks on loops of 5–12 trips, sums that wait on each
/// other), so any size left out is a cliff between its neighbours (issue 11 measured n = 5
/// at 9× n = 4). Each pair costs ~25 s of CPU time in the release build (its loops compile in a
/// codegen unit of their own, `core::home`); for quick experiments,
/// `RUSTFLAGS="--cfg kfast_dev_sizes"` compiles only (1, 1), (2, 1), (4, 2), (5, 2) and (9, 2)
/// (with a separate `CARGO_TARGET_DIR`, as the flag rebuilds every dependency).
macro_rules! with_dims {
    ($kernel:expr, $n:expr, $m:expr, |$d:ident| $body:expr) => {{
        use $crate::core::dims::{Dyn, Fixed};
        match ($crate::core::isa::Kernel::fixed_sizes($kernel), $n, $m) {
            (true, 1, 1) => with_dims!(@fixed 1, 1, $d, $body),
            (true, 2, 1) => with_dims!(@fixed 2, 1, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 2, 2) => with_dims!(@fixed 2, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 3, 1) => with_dims!(@fixed 3, 1, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 3, 2) => with_dims!(@fixed 3, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 3, 3) => with_dims!(@fixed 3, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 4, 1) => with_dims!(@fixed 4, 1, $d, $body),
            (true, 4, 2) => with_dims!(@fixed 4, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 4, 3) => with_dims!(@fixed 4, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 4, 4) => with_dims!(@fixed 4, 4, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 5, 1) => with_dims!(@fixed 5, 1, $d, $body),
            (true, 5, 2) => with_dims!(@fixed 5, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 5, 3) => with_dims!(@fixed 5, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 5, 4) => with_dims!(@fixed 5, 4, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 6, 1) => with_dims!(@fixed 6, 1, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 6, 2) => with_dims!(@fixed 6, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 6, 3) => with_dims!(@fixed 6, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 6, 4) => with_dims!(@fixed 6, 4, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 7, 1) => with_dims!(@fixed 7, 1, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 7, 2) => with_dims!(@fixed 7, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 7, 3) => with_dims!(@fixed 7, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 7, 4) => with_dims!(@fixed 7, 4, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 8, 1) => with_dims!(@fixed 8, 1, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 8, 2) => with_dims!(@fixed 8, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 8, 3) => with_dims!(@fixed 8, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 8, 4) => with_dims!(@fixed 8, 4, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 9, 1) => with_dims!(@fixed 9, 1, $d, $body),
            (true, 9, 2) => with_dims!(@fixed 9, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 9, 3) => with_dims!(@fixed 9, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 9, 4) => with_dims!(@fixed 9, 4, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 10, 1) => with_dims!(@fixed 10, 1, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 10, 2) => with_dims!(@fixed 10, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 10, 3) => with_dims!(@fixed 10, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 10, 4) => with_dims!(@fixed 10, 4, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 11, 1) => with_dims!(@fixed 11, 1, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 11, 2) => with_dims!(@fixed 11, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 11, 3) => with_dims!(@fixed 11, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 11, 4) => with_dims!(@fixed 11, 4, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 12, 1) => with_dims!(@fixed 12, 1, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 12, 2) => with_dims!(@fixed 12, 2, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 12, 3) => with_dims!(@fixed 12, 3, $d, $body),
            #[cfg(not(kfast_dev_sizes))]
            (true, 12, 4) => with_dims!(@fixed 12, 4, $d, $body),
            (_, n, m) => {
                let $d = Dyn { n, m };
                $body
            }
        }
    }};
    (@fixed $n:literal, $m:literal, $d:ident, $body:expr) => {{
        let $d = Fixed::<$n, $m>;
        $body
    }};
}
pub(crate) use with_dims;
