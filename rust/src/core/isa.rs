//! The instruction sets a loop is compiled for, chosen at run time, and whether its
//! multiply-adds are fused.
//!
//! The kernels' multiply-adds are fused ([`Fused`](crate::core::dims::Fused) sizes: each
//! `c + a b` rounded once), wherever the CPU can: a fused multiply-add is one IEEE operation,
//! so every CPU computes the same bits from the same operations in the same order, whichever
//! instructions carry them out. [`run_best!`] picks the loop once per call:
//!
//! - x86-64 with AVX2 and FMA (nearly every x86-64 CPU since 2013–2015): the loops compiled
//!   for AVX2 + FMA, with compile-time sizes (`with_dims!`);
//! - every other target: the loops compiled for its baseline, fused (aarch64's baseline has
//!   FMA), with compile-time sizes;
//! - an x86-64 CPU without FMA: the loops of run-time sizes only, with separate multiplies and
//!   adds (compiled for AVX2 where the CPU has it) — or, in deterministic mode, fused in
//!   software (slow, and the same bits as everywhere else). Compile-time sizes are not
//!   compiled for such CPUs: a second instance of every loop of every size doubled the
//!   release build (docs/decisions.md, "One arithmetic").
//!
//! Deterministic mode ([`set_deterministic`], or the environment variable
//! `KFAST_DETERMINISTIC=1` read at the first call) also keeps the products of run-time sizes
//! out of faer, whose kernels (and so rounding) depend on the CPU: then every CPU computes the
//! same bits. Outside it, results differ from deterministic ones only above n = 12, by
//! rounding. Every path of one recursion (the filter, the batch filter, the streaming filter,
//! the smoothers) computes in the same order, so they agree to the bit with each other.

use std::sync::atomic::{AtomicU8, Ordering};

use crate::core::dims::Dims;
use crate::core::home::Home;

/// The loops a call can run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kernel {
    /// The target's baseline instructions (SSE2 on x86-64), separate multiplies and adds: an
    /// x86-64 CPU without AVX2, outside deterministic mode. Run-time sizes only.
    Baseline,
    /// x86-64 with AVX2, separate multiplies and adds: a CPU without FMA, outside deterministic
    /// mode. Run-time sizes only.
    Avx2,
    /// x86-64 with AVX2 and fused multiply-adds.
    Avx2Fma,
    /// Fused multiply-adds in the target's baseline instructions: every target but x86-64
    /// (hardware FMA on aarch64), and deterministic mode on an x86-64 CPU without FMA
    /// (software FMA, run-time sizes only).
    BaselineFma,
}

impl Kernel {
    /// Its name in `kfast._kfast.kernel_info()` and the benchmarks.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Kernel::Baseline => "baseline",
            Kernel::Avx2 => "avx2",
            Kernel::Avx2Fma => "avx2+fma",
            Kernel::BaselineFma => "baseline+fma",
        }
    }

    /// Whether its multiply-adds are fused ([`Fused`](crate::core::dims::Fused) sizes).
    #[inline(always)]
    pub(crate) fn fused(self) -> bool {
        matches!(self, Kernel::Avx2Fma | Kernel::BaselineFma)
    }

    /// Whether its loops are compiled for compile-time sizes (`with_dims!` gives run-time
    /// sizes otherwise): on x86-64 only the AVX2 + FMA loops are, and with the
    /// `unfused-sizes` feature the unfused ones too (one baseline instance serves both).
    #[inline(always)]
    pub(crate) fn fixed_sizes(self) -> bool {
        cfg!(not(target_arch = "x86_64"))
            || self == Kernel::Avx2Fma
            || (UNFUSED_SIZES && matches!(self, Kernel::Avx2 | Kernel::Baseline))
    }
}

/// Whether the unfused loops (x86-64 CPUs without FMA) have compile-time sizes too (the
/// `unfused-sizes` feature).
pub(crate) const UNFUSED_SIZES: bool = cfg!(feature = "unfused-sizes");

/// Where a loop of compile-time sizes would run for an instruction set it is not compiled
/// for: [`Kernel::fixed_sizes`], which `with_dims!` follows, rules it out. Callers reach it
/// only under a constant condition on the sizes (`D::FIXED`), which rustc prunes before
/// code generation, so the loop it stands for is never compiled.
#[cold]
#[inline(never)]
pub(crate) fn not_compiled() -> ! {
    unreachable!("compile-time sizes run only the AVX2 + FMA loops on x86-64 (Kernel::fixed_sizes)")
}

/// 0: not read yet; 1: off; 2: on.
static DETERMINISTIC: AtomicU8 = AtomicU8::new(0);
/// A forced kernel for tests and benchmarks (0: none; 1 + the `Kernel` in declaration order).
static FORCED: AtomicU8 = AtomicU8::new(0);

/// Whether the results are the same bits on every CPU: the products of run-time sizes above
/// 12 stay out of faer (off by default; `KFAST_DETERMINISTIC=1` turns it on for the process).
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
/// the previous setting. Calls already running keep their loops; a call with run-time sizes
/// above 12 running while the mode changes may compute some products each way (the same
/// numbers to rounding). A streaming filter keeps the loops it was created with.
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
        Some(Kernel::BaselineFma) => 4,
    };
    FORCED.store(code, Ordering::Relaxed);
    true
}

fn supported(kernel: Kernel) -> bool {
    match kernel {
        Kernel::BaselineFma => true,
        #[cfg(target_arch = "x86_64")]
        Kernel::Baseline => true,
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2Fma => has_avx2_fma(),
        #[cfg(not(target_arch = "x86_64"))]
        _ => false,
    }
}

/// Whether this x86-64 CPU has AVX2 and FMA (the answer is cached by the standard library).
#[cfg(target_arch = "x86_64")]
#[inline]
fn has_avx2_fma() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
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
        4 => return Kernel::BaselineFma,
        _ => {}
    }
    #[cfg(target_arch = "x86_64")]
    {
        if supported(Kernel::Avx2Fma) {
            Kernel::Avx2Fma
        } else if deterministic() {
            Kernel::BaselineFma
        } else if supported(Kernel::Avx2) {
            Kernel::Avx2
        } else {
            Kernel::Baseline
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    Kernel::BaselineFma
}

/// The loops a call starting now runs on this CPU: `"avx2+fma"` (x86-64 with AVX2 and FMA),
/// `"baseline+fma"` (every other target, fused multiply-adds in its baseline instructions;
/// an x86-64 CPU without FMA in deterministic mode, in software), `"avx2"` or `"baseline"`
/// (an x86-64 CPU without FMA, separate multiplies and adds, which give the same bits as
/// each other). The fused loops give the same bits as each other.
pub fn instruction_set() -> &'static str {
    kernel().name()
}

/// Evaluates `$body` with `$d` bound to the sizes `$sizes` compiled for `$kernel` (a
/// [`Kernel`], usually [`kernel()`] read once at the start of the call; the sizes from
/// `with_dims!` for the same kernel) — wrapped in [`Fused`](crate::core::dims::Fused) for a
/// fused kernel — in its own function with that instruction set enabled, a runner of the
/// sizes' [`Home`](crate::core::home::Home): `run_best!(self.kernel, d, |d|
/// self.filter_plain(d, out))`. The body must inline what it calls (the kernels are
/// `#[inline(always)]`) so that all of it is compiled for that instruction set; each call
/// site compiles its loop separately. The body's captures reach the loop as fields of a
/// closure, not as arguments: the compiler no longer knows that two captured `&mut` slices
/// do not overlap, which slowed the RTS smoother's backward pass (whose arrays are
/// arguments) by 12%; such a loop keeps its own `#[target_feature]` methods, chosen by the
/// same [`Kernel`].
macro_rules! run_best {
    ($kernel:expr, $sizes:expr, |$d:ident| $body:expr) => {{
        let (kernel, sizes) = ($kernel, $sizes);
        if kernel.fused() {
            // SAFETY: kernel() returns a kernel only on CPUs that run it.
            unsafe {
                $crate::core::isa::run_fused(
                    sizes,
                    kernel,
                    #[inline(always)]
                    move || {
                        let $d = $crate::core::dims::Fused(sizes);
                        $body
                    },
                )
            }
        } else {
            // SAFETY: as above.
            unsafe {
                $crate::core::isa::run_unfused(
                    sizes,
                    kernel,
                    #[inline(always)]
                    move || {
                        let $d = sizes;
                        $body
                    },
                )
            }
        }
    }};
}
pub(crate) use run_best;

/// `job` in the fused loop of sizes `D` for the fused `kernel` (`run_best!`). Compile-time
/// sizes on x86-64 have only the AVX2 + FMA loop: the other is not compiled for them
/// (`Kernel::fixed_sizes`).
///
/// # Safety
/// `kernel` must be supported by the CPU.
#[doc(hidden)]
#[inline(always)]
pub(crate) unsafe fn run_fused<D: Dims, R>(_sizes: D, kernel: Kernel, job: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        if kernel == Kernel::Avx2Fma {
            // SAFETY: as the caller's.
            return unsafe { D::Home::run_avx2_fma(job) };
        }
        if D::FIXED {
            not_compiled();
        }
    }
    let _ = kernel;
    D::Home::run_baseline(job)
}

/// `job` in the loop of sizes `D` with separate multiplies and adds, for `kernel`
/// (`run_best!`): run-time sizes on x86-64 only (`Kernel::fixed_sizes`).
///
/// # Safety
/// `kernel` must be supported by the CPU.
#[doc(hidden)]
#[inline(always)]
pub(crate) unsafe fn run_unfused<D: Dims, R>(_sizes: D, kernel: Kernel, job: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        if D::FIXED {
            if !UNFUSED_SIZES {
                not_compiled();
            }
            // One instance for both unfused kernels: the same bits.
            return D::Home::run_baseline(job);
        }
        if kernel == Kernel::Avx2 {
            // SAFETY: as the caller's.
            return unsafe { D::Home::run_unfused_avx2(job) };
        }
        D::Home::run_baseline(job)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (kernel, job);
        unreachable!("every loop is fused on this target");
    }
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
        if matches!(kernel(), Kernel::Avx2 | Kernel::Avx2Fma) {
            // SAFETY: kernel() is Avx2 or Avx2Fma only on CPUs with AVX2.
            return unsafe { avx2(job) };
        }
    }
    job()
}

/// Runs `job` — work on buffers of sizes `D` outside a [`run_best!`] loop (a streaming
/// filter's step, a rare step out of line) — in a function of its own in `D`'s home, with
/// FMA enabled if `D` is [`Fused`](crate::core::dims::Fused) and the CPU has it (fused
/// arithmetic gives the same bits either way; compile-time sizes on x86-64 are always fused
/// and only made on CPUs with AVX2 and FMA, `Kernel::fixed_sizes`).
#[inline(always)]
pub(crate) fn run_out_of_line<D: Dims, R>(job: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        if D::FUSED && (D::FIXED || has_avx2_fma()) {
            // SAFETY: checked above; compile-time sizes exist only on such CPUs.
            return unsafe { D::Home::run_avx2_fma(job) };
        }
        if D::FIXED && !UNFUSED_SIZES {
            not_compiled();
        }
    }
    D::Home::run_baseline(job)
}
