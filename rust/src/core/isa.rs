//! The instruction sets a loop is compiled for, chosen at run time.
//!
//! A time loop is compiled once for the baseline of the target and, on x86-64, once more
//! with AVX2 enabled, and [`run_best`] picks the widest the CPU has. Enabling an instruction
//! set changes how the compiler vectorizes, never the arithmetic: no fused multiply-adds, no
//! reordered sums, so every CPU gives the same bits.

/// Runs `job` compiled for the widest instruction set this CPU supports. `job` must be an
/// `#[inline(always)]` closure whose body inlines what it calls (the kernels are
/// `#[inline(always)]`), so that all of it is compiled for that instruction set; each call
/// site of `run_best` compiles its loop separately, into its own function. The closure's
/// captures reach the loop as fields, not as arguments: the compiler no longer knows that
/// two captured `&mut` slices do not overlap, which slowed the RTS smoother's backward pass
/// (whose arrays are arguments) by 12%; such a loop keeps its own `#[target_feature]` method.
#[inline(always)]
pub(crate) fn run_best<R>(job: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { run_avx2(job) };
    }
    run_baseline(job)
}

#[inline(never)]
fn run_baseline<R>(job: impl FnOnce() -> R) -> R {
    job()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline(never)]
unsafe fn run_avx2<R>(job: impl FnOnce() -> R) -> R {
    job()
}

/// The instruction set the time loops run with on this CPU: `"avx2"` (x86-64 with AVX2) or
/// `"baseline"` (the target's default: SSE2 on x86-64, NEON on aarch64). Results are the same
/// bits either way.
pub fn instruction_set() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        return "avx2";
    }
    "baseline"
}
