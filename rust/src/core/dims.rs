//! Sizes known at compile time or at run time, and scratch buffers of either kind.
//!
//! The small dense kernels of [`super::dense`] take their sizes as arguments; called with
//! [`Fixed`] sizes (compile-time constants) they are unrolled and vectorized for the common
//! small state and output dimensions, with [`Dyn`] sizes they serve every other size. The
//! arithmetic is identical either way, so results are the same bits.

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

    const FIXED: bool = false;

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

impl<const N: usize, const M: usize> Dims for Fixed<N, M> {
    type Vector = [[f64; N]; 1];
    type Square = [[f64; N]; N];
    type Obs = [[f64; M]; 1];
    type ObsSquare = [[f64; M]; M];
    type StateObs = [[f64; M]; N];

    const FIXED: bool = true;

    #[inline(always)]
    fn n(self) -> usize {
        N
    }
    #[inline(always)]
    fn m(self) -> usize {
        M
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

/// Evaluates `$body` with `$d` bound to the compile-time sizes when (n, m) is one of the common
/// small ones, so that the kernels are unrolled for them, and to the run-time sizes otherwise:
/// `with_dims!(n, m, |d| run.filter(d, &mut out))`. The body is compiled once per size; the
/// arithmetic is the same either way.
macro_rules! with_dims {
    ($n:expr, $m:expr, |$d:ident| $body:expr) => {{
        use $crate::core::dims::{Dyn, Fixed};
        match ($n, $m) {
            (1, 1) => {
                let $d = Fixed::<1, 1>;
                $body
            }
            (2, 1) => {
                let $d = Fixed::<2, 1>;
                $body
            }
            (2, 2) => {
                let $d = Fixed::<2, 2>;
                $body
            }
            (3, 1) => {
                let $d = Fixed::<3, 1>;
                $body
            }
            (3, 2) => {
                let $d = Fixed::<3, 2>;
                $body
            }
            (3, 3) => {
                let $d = Fixed::<3, 3>;
                $body
            }
            (4, 1) => {
                let $d = Fixed::<4, 1>;
                $body
            }
            (4, 2) => {
                let $d = Fixed::<4, 2>;
                $body
            }
            (4, 4) => {
                let $d = Fixed::<4, 4>;
                $body
            }
            (6, 2) => {
                let $d = Fixed::<6, 2>;
                $body
            }
            (6, 3) => {
                let $d = Fixed::<6, 3>;
                $body
            }
            (8, 4) => {
                let $d = Fixed::<8, 4>;
                $body
            }
            (n, m) => {
                let $d = Dyn { n, m };
                $body
            }
        }
    }};
}
pub(crate) use with_dims;
