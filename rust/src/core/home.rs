//! Where the loops of each size are compiled: one module per compile-time size, and one for
//! run-time sizes, so that the release build spreads them over its codegen units.
//!
//! rustc puts an instance of a generic function into the codegen unit of the module that
//! defines it (for a method, of its self type), whatever its type arguments. A time loop is
//! such an instance: a runner that enables an instruction set, with the loop inlined into it
//! (`core::isa`). With one set of runners for every size, the loops of all 42 compile-time
//! sizes landed in one codegen unit, which LLVM optimizes on one core: the release build
//! took 13.5 minutes on a 2-core machine. Here every size has its own runners, methods of a
//! type of its own module ([`Dims::Home`](crate::core::dims::Dims::Home)), so their
//! instances spread over the codegen units and the cores.
//!
//! The runners are not inlined: each runs its job, inlined, in its own function, which is
//! what lets the compiler keep a loop's small buffers in registers and compile it for the
//! instruction set (see `core::isa`). On x86-64 a compile-time size has only the AVX2 + FMA
//! runner instantiated (`core::isa`, `Kernel::fixed_sizes`): its other runners exist, but no
//! loop is ever compiled into them.

/// The runners of one size's loops (see the module docs).
pub(crate) trait Home {
    /// `job` in a function of its own, for the target's baseline instruction set.
    fn run_baseline<R>(job: impl FnOnce() -> R) -> R;

    /// `job` for x86-64 with AVX2, separate multiplies and adds (the same bits as
    /// [`run_baseline`](Self::run_baseline) with separate ones): run-time sizes only.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    unsafe fn run_unfused_avx2<R>(job: impl FnOnce() -> R) -> R;

    /// `job` for x86-64 with AVX2 and FMA.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    unsafe fn run_avx2_fma<R>(job: impl FnOnce() -> R) -> R;
}

/// The home of compile-time sizes `Fixed<N, M>` (implemented for those `with_dims!` compiles).
pub(crate) trait FixedHome {
    type Home: Home;
}

/// A runner: `job` in a function of its own (not inlined), for the baseline instruction set
/// or, on x86-64, with the given target features.
macro_rules! runner {
    ($vis:vis fn $name:ident) => {
        #[inline(never)]
        $vis fn $name<R>(job: impl FnOnce() -> R) -> R {
            job()
        }
    };
    ($vis:vis unsafe fn $name:ident, $features:literal) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        #[inline(never)]
        $vis unsafe fn $name<R>(job: impl FnOnce() -> R) -> R {
            job()
        }
    };
}

/// Run-time sizes. Each instruction set's runners are free functions of a module of their
/// own, so that the run-time loops (~2 MB of code) spread over three codegen units: in one
/// they made the largest unit, optimized on one core while the other waited
/// (docs/decisions.md, "The first install on 2 cores").
pub(crate) mod dynamic {
    pub(crate) struct Home;

    impl super::Home for Home {
        #[inline(always)]
        fn run_baseline<R>(job: impl FnOnce() -> R) -> R {
            baseline::run(job)
        }

        #[cfg(target_arch = "x86_64")]
        #[inline(always)]
        unsafe fn run_unfused_avx2<R>(job: impl FnOnce() -> R) -> R {
            // SAFETY: as the caller's.
            unsafe { unfused_avx2::run(job) }
        }

        #[cfg(target_arch = "x86_64")]
        #[inline(always)]
        unsafe fn run_avx2_fma<R>(job: impl FnOnce() -> R) -> R {
            // SAFETY: as the caller's.
            unsafe { avx2_fma::run(job) }
        }
    }

    mod baseline {
        runner!(pub(super) fn run);
    }

    mod unfused_avx2 {
        runner!(pub(super) unsafe fn run, "avx2");
    }

    mod avx2_fma {
        runner!(pub(super) unsafe fn run, "avx2,fma");
    }
}

macro_rules! fixed_homes {
    ($(($n:literal, $m:literal) $name:ident),* $(,)?) => {$(
        pub(crate) mod $name {
            pub(crate) struct Home;

            impl super::Home for Home {
                runner!(fn run_baseline);
                runner!(unsafe fn run_avx2_fma, "avx2,fma");

                #[cfg(target_arch = "x86_64")]
                #[inline(always)]
                unsafe fn run_unfused_avx2<R>(job: impl FnOnce() -> R) -> R {
                    <Self as super::Home>::run_baseline(job)
                }
            }

            impl super::FixedHome for crate::core::dims::Fixed<$n, $m> {
                type Home = Home;
            }
        }
    )*};
}

// The sizes of `with_dims!` (a size missing here fails to compile there).
fixed_homes! {
    (1, 1) n1m1, (2, 1) n2m1, (2, 2) n2m2, (3, 1) n3m1, (3, 2) n3m2, (3, 3) n3m3,
    (4, 1) n4m1, (4, 2) n4m2, (4, 3) n4m3, (4, 4) n4m4, (5, 1) n5m1, (5, 2) n5m2,
    (5, 3) n5m3, (5, 4) n5m4, (6, 1) n6m1, (6, 2) n6m2, (6, 3) n6m3, (6, 4) n6m4,
    (7, 1) n7m1, (7, 2) n7m2, (7, 3) n7m3, (7, 4) n7m4, (8, 1) n8m1, (8, 2) n8m2,
    (8, 3) n8m3, (8, 4) n8m4, (9, 1) n9m1, (9, 2) n9m2, (9, 3) n9m3, (9, 4) n9m4,
    (10, 1) n10m1, (10, 2) n10m2, (10, 3) n10m3, (10, 4) n10m4, (11, 1) n11m1,
    (11, 2) n11m2, (11, 3) n11m3, (11, 4) n11m4, (12, 1) n12m1, (12, 2) n12m2,
    (12, 3) n12m3, (12, 4) n12m4,
}
