//! The instruction sets a loop is compiled for, chosen at run time, and whether its
//! multiply-adds are fused.
//!
//! A time loop is compiled for the baseline of the target and, on x86-64, twice more: with
//! AVX2 and separate multiplies and adds, and with AVX2 and FMA, its kernels' multiply-adds
//! fused ([`Fused`](crate::core::dims::Fused) sizes: `c + a b` rounded once). [`run_best!`]
//! picks the loop once per call:
//!
//! - by default the fastest the CPU has: AVX2 + FMA where there is FMA;
//! - in deterministic mode ([`set_deterministic`], or the environment variable
//!   `KFAST_DETERMINISTIC=1` read at the first call) never a fused loop: the AVX2 or the
//!   baseline loop, which give the same bits as each other — on every CPU, the same bits.
//!
//! Fused results differ from deterministic ones by rounding (each fused multiply-add rounds
//! once instead of twice); both are computed in the same order on every path, so the filter,
//! the batch filter, the streaming filter and the smoothers agree to the bit with each other
//! in either mode.

use std::sync::atomic::{AtomicU8, Ordering};

use crate::core::dims::Dims;
use crate::core::home::Home;

/// The loops a call can run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kernel {
    /// The target's default instruction set (SSE2 on x86-64, NEON on aarch64).
    Baseline,
    /// x86-64 with AVX2, separate multiplies and adds (the same bits as `Baseline`): the
    /// loops of run-time sizes compiled for AVX2, those of compile-time sizes the baseline
    /// ones (`Home::run_unfused_avx2`: build time).
    Avx2,
    /// x86-64 with AVX2 and fused multiply-adds.
    Avx2Fma,
}

impl Kernel {
    /// Its name in `kfast._kfast.kernel_info()` and the benchmarks.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Kernel::Baseline => "baseline",
            Kernel::Avx2 => "avx2",
            Kernel::Avx2Fma => "avx2+fma",
        }
    }
}

/// 0: not read yet; 1: off; 2: on.
static DETERMINISTIC: AtomicU8 = AtomicU8::new(0);
/// A forced kernel for tests and benchmarks (0: none; 1 + the `Kernel` in declaration order).
static FORCED: AtomicU8 = AtomicU8::new(0);

/// Whether the loops avoid fused multiply-adds, so that every CPU computes the same bits
/// (off by default; `KFAST_DETERMINISTIC=1` turns it on for the process).
pub fn deterministic() -> bool {
    match DETERMINISTIC.load(Ordering::Relaxed) {
        0 => {
            let on = std::env::var("KFAST_DETERMINISTIC").is_ok_and(|v| !matches!(v.trim(), "" | "0"));
            // A concurrent set_deterministic wins over the environment.
            let _ = DETERMINISTIC.compare_exchange(0, 1 + on as u8, Ordering::Relaxed, Ordering::Relaxed);
            DETERMINISTIC.load(Ordering::Relaxed) == 2
        }
        v => v == 2,
    }
}

/// Turns deterministic mode on or off for the whole process (see the module docs); returns
/// the previous setting. Calls already running keep the loop they started with; a streaming
/// filter keeps the arithmetic it was created with.
pub fn set_deterministic(on: bool) -> bool {
    let previous = deterministic();
    DETERMINISTIC.store(1 + on as u8, Ordering::Relaxed);
    previous
}

/// Forces the loops of every later call to `kernel` (`None`: back to the choice above), for
/// tests of bit-identity between instruction sets and for benchmark rows. Refused (returns
/// `false`) if this CPU cannot run it.
#[cfg(feature = "python")]
pub(crate) fn force_kernel(kernel: Option<Kernel>) -> bool {
    let code = match kernel {
        None => 0,
        Some(k) if !supported(k) => return false,
        Some(Kernel::Baseline) => 1,
        Some(Kernel::Avx2) => 2,
        Some(Kernel::Avx2Fma) => 3,
    };
    FORCED.store(code, Ordering::Relaxed);
    true
}

fn supported(kernel: Kernel) -> bool {
    match kernel {
        Kernel::Baseline => true,
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2Fma => std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma"),
        #[cfg(not(target_arch = "x86_64"))]
        _ => false,
    }
}

/// The instruction sets of this CPU that the loops can use, by name (for bug reports).
#[cfg(feature = "python")]
pub(crate) fn cpu_features() -> String {
    #[cfg(target_arch = "x86_64")]
    {
        let mut names = Vec::new();
        macro_rules! detect {
            ($($f:tt),*) => {$(
                if std::arch::is_x86_feature_detected!($f) {
                    names.push($f);
                }
            )*};
        }
        detect!("sse2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512vl");
        names.join(" ")
    }
    #[cfg(not(target_arch = "x86_64"))]
    String::from(std::env::consts::ARCH)
}

/// The loop a call starting now runs.
#[inline]
pub(crate) fn kernel() -> Kernel {
    match FORCED.load(Ordering::Relaxed) {
        1 => return Kernel::Baseline,
        2 => return Kernel::Avx2,
        3 => return Kernel::Avx2Fma,
        _ => {}
    }
    if !deterministic() && supported(Kernel::Avx2Fma) {
        Kernel::Avx2Fma
    } else if supported(Kernel::Avx2) {
        Kernel::Avx2
    } else {
        Kernel::Baseline
    }
}

/// The loop a call starting now runs on this CPU: `"avx2+fma"` (x86-64 with AVX2 and FMA, the
/// default there), `"avx2"` (AVX2 without FMA, or deterministic mode) or `"baseline"` (the
/// target's default: SSE2 on x86-64, NEON on aarch64). `"avx2"` and `"baseline"` give the
/// same bits.
pub fn instruction_set() -> &'static str {
    kernel().name()
}

/// Evaluates `$body` with `$d` bound to the sizes `$sizes` compiled for `$kernel` (a
/// [`Kernel`], usually [`kernel()`] read once at the start of the call) — for `Avx2Fma`
/// wrapped in [`Fused`](crate::core::dims::Fused) — in its own function with that
/// instruction set enabled, a runner of the sizes' [`Home`](crate::core::home::Home):
/// `run_best!(self.kernel, d, |d| self.filter_plain(d, out))`. The body must inline what it
/// calls (the kernels are `#[inline(always)]`) so that all of it is compiled for that
/// instruction set; each call site compiles its loop separately. The body's captures reach
/// the loop as fields of a closure, not as arguments: the compiler no longer knows that two
/// captured `&mut` slices do not overlap, which slowed the RTS smoother's backward pass
/// (whose arrays are arguments) by 12%; such a loop keeps its own `#[target_feature]`
/// methods, chosen by the same [`Kernel`].
macro_rules! run_best {
    ($kernel:expr, $sizes:expr, |$d:ident| $body:expr) => {{
        let (kernel, sizes) = ($kernel, $sizes);
        match kernel {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: kernel() returns Avx2Fma only on CPUs with AVX2 and FMA.
            $crate::core::isa::Kernel::Avx2Fma => unsafe {
                $crate::core::isa::run_fused(
                    sizes,
                    #[inline(always)]
                    move || {
                        let $d = $crate::core::dims::Fused(sizes);
                        $body
                    },
                )
            },
            // One closure for the AVX2 and the baseline loop: compile-time sizes run the same
            // (baseline) instance for both.
            // SAFETY: kernel() returns Avx2 only on CPUs with AVX2.
            _ => unsafe {
                $crate::core::isa::run_unfused(
                    sizes,
                    kernel,
                    #[inline(always)]
                    move || {
                        let $d = sizes;
                        $body
                    },
                )
            },
        }
    }};
}
pub(crate) use run_best;

/// `job` in the fused loop of sizes `D` (`run_best!`).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[doc(hidden)]
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn run_fused<D: Dims, R>(_sizes: D, job: impl FnOnce() -> R) -> R {
    // SAFETY: as the caller's.
    unsafe { D::Home::run_avx2_fma(job) }
}

/// `job` in the unfused loop of sizes `D` for `kernel` (`run_best!`).
///
/// # Safety
/// `kernel` must be supported by the CPU.
#[doc(hidden)]
#[inline(always)]
pub(crate) unsafe fn run_unfused<D: Dims, R>(_sizes: D, kernel: Kernel, job: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if kernel == Kernel::Avx2 {
        // SAFETY: as the caller's.
        return unsafe { D::Home::run_unfused_avx2(job) };
    }
    let _ = kernel;
    D::Home::run_baseline(job)
}

/// Runs `job` compiled with AVX2 where the CPU has it and the loops may use it (not
/// [`Kernel::Baseline`] forced): for lane-wise arithmetic on short arrays (the built-in
/// models' sines and bearings, four points at a time), which the baseline compiles to two
/// SSE2 halves and bitwise selects. Separate multiplies and adds only, so the same bits as
/// the baseline: deterministic mode does not need to avoid it. Mark the closure
/// `#[inline(always)]`: LLVM may otherwise keep it a function of its own, compiled for the
/// baseline (seen with the particle filter's loops: SSE2 inside the AVX2 wrapper).
#[inline(always)]
pub(crate) fn run_wide<R>(job: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2")]
        unsafe fn avx2<R>(job: impl FnOnce() -> R) -> R {
            job()
        }
        if kernel() != Kernel::Baseline {
            // SAFETY: kernel() is Avx2 or Avx2Fma only on CPUs with AVX2.
            return unsafe { avx2(job) };
        }
    }
    job()
}

/// Runs `job` — work on buffers of sizes `D` outside a [`run_best!`] loop (a streaming
/// filter's step, a rare step out of line) — in a function of its own in `D`'s home, with
/// FMA enabled if `D` is [`Fused`](crate::core::dims::Fused). Fused sizes are only made by
/// [`run_best!`] and the streaming filter for [`Kernel::Avx2Fma`], so on CPUs with FMA.
#[inline(always)]
pub(crate) fn run_out_of_line<D: Dims, R>(job: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if D::FUSED {
        // SAFETY: fused sizes exist only on CPUs with AVX2 and FMA (above).
        return unsafe { D::Home::run_avx2_fma(job) };
    }
    D::Home::run_baseline(job)
}
