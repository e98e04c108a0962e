#!/usr/bin/env python
"""kfast benchmark harness: W1 (filter), W2 (RTS smoother), W3 (log-likelihood),
W7 (streaming), plus W4 (n = 20 filter), W5 (many series), W8 (scaling in n) and
MEM (peak RSS) from bench_more.py, and W6 (the DARE) from bench_riccati.py.

    python benches/bench_filter.py            # full run (~2.5 min on 2 cores)
    python benches/bench_filter.py --quick    # smoke run (~15 s)
    python benches/bench_filter.py --write    # full run, then rewrite the
                                              # results blocks of BENCHMARKS.md
                                              # and benches/plots/*.png
    python benches/bench_filter.py --only W4,W8   # a subset (W1-W8, MEM)

Model "CV" (2-D constant velocity, n=4, m=2, dt=0.1, q=1, R=I, float64),
data simulated from the model with a fixed seed.

Contenders are timed interleaved (round-robin A B C A B C ...) and each
reports the median ns/step over all its samples; ratios are kfast/peer from
the same run, so < 1 means kfast is faster.  Peers that are not installed (or
fail) are reported as such; the benchmark never raises.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import gc
import importlib
import importlib.metadata as _md
import io
import os
import platform
import re
import statistics
import subprocess
import sys
import time
import traceback
import warnings

# Single-threaded BLAS: no contender does a matrix product big enough for
# OpenBLAS to thread (n = 4), but idle OpenBLAS worker threads spin after the
# data simulation and steal the second of our 2 cores.  Set before numpy loads.
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402


def keep_freed_memory():
    """Keep memory the process frees inside it, so that a contender's next call does not
    fault it in again from the operating system.

    On the Firecracker VMs this bench runs on, the guest hands every freed page block back to
    the host at once (free-page reporting), and touching such memory again costs about 10 ms
    per MB (measured: 1.6-2.0 s to fill a fresh 160 MB array, 0.012 s for memory the process
    already holds) -- a hundred times a page fault on bare metal. Any call that allocates its
    outputs then times the VM, not the code (W5: 80-300 ns per series-step instead of 35).
    glibc returns large blocks through munmap and trims its heap; with mmap off for chunks
    and a trim threshold of 2 GB, freed blocks stay in the heap for the next call. Applies to
    every contender alike. Returns a note for the header, or "" if mallopt is unavailable."""
    try:
        import ctypes
        libc = ctypes.CDLL(None)
        M_TRIM_THRESHOLD, M_MMAP_MAX = -1, -4
        ok = libc.mallopt(M_MMAP_MAX, 0) and libc.mallopt(M_TRIM_THRESHOLD, 2**31 - 1)
    except (OSError, AttributeError):
        return ""
    return "freed memory kept in the process (mallopt)" if ok else ""

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)

warnings.filterwarnings("ignore")

# --------------------------------------------------------------------------
# Model and data
# --------------------------------------------------------------------------
DT = 0.1
SEED = 20240601


def cv_model(dt: float = DT, q: float = 1.0):
    F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    H = np.array([[1, 0, 0, 0], [0, 1, 0, 0]], float)
    Q = np.zeros((4, 4))
    Q[0, 0] = Q[1, 1] = q * dt**3 / 3
    Q[0, 2] = Q[2, 0] = Q[1, 3] = Q[3, 1] = q * dt**2 / 2
    Q[2, 2] = Q[3, 3] = q * dt
    R = np.eye(2)
    x0 = np.array([1.0, -1.0, 0.5, 0.2])
    P0 = np.diag([10.0, 10.0, 1.0, 1.0])
    return F, H, Q, R, x0, P0


def simulate(T: int, seed: int = SEED):
    F, H, Q, R, x0, P0 = cv_model()
    rng = np.random.default_rng(seed)
    LQ, LR, LP = np.linalg.cholesky(Q), np.linalg.cholesky(R), np.linalg.cholesky(P0)
    w = rng.standard_normal((T, 4)) @ LQ.T
    v = rng.standard_normal((T, 2)) @ LR.T
    x = x0 + LP @ rng.standard_normal(4)
    y = np.empty((T, 2))
    for t in range(T):
        y[t] = H @ x + v[t]
        x = F @ x + w[t]
    return np.ascontiguousarray(y)


# --------------------------------------------------------------------------
# Timing machinery
# --------------------------------------------------------------------------
class Contender:
    """One timed thing.  `fn()` runs the whole workload on `steps` steps."""

    def __init__(self, name, fn, steps, note="", group="peer"):
        self.name, self.fn, self.steps, self.note, self.group = name, fn, steps, note, group
        self.samples: list[float] = []  # seconds per call
        self.error: str | None = None
        self.per_round = 1

    @property
    def ok(self):
        return self.error is None and bool(self.samples)

    def ns_per_step(self):
        return statistics.median(self.samples) / self.steps * 1e9

    def spread(self):
        """(q25, q75) in ns/step."""
        s = sorted(self.samples)
        if len(s) < 4:
            return (s[0] / self.steps * 1e9, s[-1] / self.steps * 1e9)
        q = statistics.quantiles(s, n=4)
        return (q[0] / self.steps * 1e9, q[2] / self.steps * 1e9)


class Unavailable(Exception):
    pass


def _short_err(e: BaseException) -> str:
    msg = f"{type(e).__name__}: {e}".strip().splitlines()[0]
    return msg[:110]


def time_once(fn) -> float:
    gcold = gc.isenabled()
    gc.disable()
    try:
        t0 = time.perf_counter()
        fn()
        return time.perf_counter() - t0
    finally:
        if gcold:
            gc.enable()


def run_interleaved(contenders, rounds, target_s=0.04, warmup=2, log=print):
    """Warm up each contender, then `rounds` round-robin passes.

    Within a round, a contender whose call takes < target_s is called several
    times (each call is one sample) so fast contenders get more samples
    without stretching the wall-clock time of slow ones."""
    live = []
    for c in contenders:
        if c.error:
            continue
        try:
            t = min(time_once(c.fn) for _ in range(warmup))
            c.per_round = max(1, min(50, int(target_s / max(t, 1e-7))))
            live.append(c)
        except Exception as e:  # noqa: BLE001
            c.error = "failed: " + _short_err(e)
            log(f"    [{c.name}] {c.error}")
    for _ in range(rounds):
        for c in live:
            if c.error:
                continue
            try:
                for _ in range(c.per_round):
                    c.samples.append(time_once(c.fn))
            except Exception as e:  # noqa: BLE001
                c.error = "failed: " + _short_err(e)


# --------------------------------------------------------------------------
# Contender factories.  Each returns a callable or raises Unavailable.
# --------------------------------------------------------------------------
def _import(name):
    try:
        return importlib.import_module(name)
    except Exception as e:  # noqa: BLE001
        if isinstance(e, ModuleNotFoundError) and e.name == name.split(".")[0]:
            raise Unavailable("not installed")
        raise Unavailable("import failed: " + _short_err(e))


def version_of(dist):
    try:
        return _md.version(dist)
    except Exception:  # noqa: BLE001
        return None


# ---- kfast -----------------------------------------------------------------
def kfast_module():
    kf = _import("kfast")
    if not hasattr(kf, "LinearGaussian"):
        raise Unavailable("kfast imported but has no LinearGaussian (extension not built?)")
    return kf


def kfast_version():
    try:
        kf = importlib.import_module("kfast")
        return getattr(kf, "__version__", None) or version_of("kfast") or "?"
    except Exception:  # noqa: BLE001
        return None


def mk_kfast_filter(y, form, outputs=None):
    kf = kfast_module()
    F, H, Q, R, x0, P0 = cv_model()
    m = kf.LinearGaussian(F, H, Q, R)
    return lambda: m.filter(y, x0, P0, form=form, outputs=outputs)


def without_fma(mk):
    """`mk`'s call in the loops an x86-64 CPU without FMA runs (run-time sizes, separate
    multiplies and adds; forced with kfast._kfast._force_kernel("avx2")). The default rows run
    the fused loops of compile-time sizes, which deterministic mode keeps (it changes only
    products above n = 12, docs/conventions.md "Arithmetic")."""
    def make(yy, *args, **kwargs):
        call = mk(yy, *args, **kwargs)
        kf = kfast_module()
        force = getattr(kf._kfast, "_force_kernel", None)
        if force is None:
            raise Unavailable("kfast has no _force_kernel (older build)")
        try:
            force("avx2")
            force(None)
        except ValueError as e:
            raise Unavailable(f"this CPU cannot run the AVX2 loops: {e}") from None

        def run():
            force("avx2")
            try:
                return call()
            finally:
                force(None)
        return run
    return make


def mk_kfast_smooth(y, form, outputs=None):
    kf = kfast_module()
    F, H, Q, R, x0, P0 = cv_model()
    m = kf.LinearGaussian(F, H, Q, R)
    if not hasattr(m, "smooth"):
        raise Unavailable("kfast has no LinearGaussian.smooth (rebuild: pip install -e .)")
    return lambda: m.smooth(y, x0, P0, form=form, outputs=outputs)


W1_OUT = ("x_filt", "P_filt")
W2_OUT = ("x_smooth", "P_smooth")
# The robust update forms (docs/algorithms.md, "Update forms"), benchmarked beside the covariance forms.
ROBUST_FORMS = ("sqrt", "ud", "information", "sequential")


def mk_kfast_loglik(y, form=None):
    kf = kfast_module()
    F, H, Q, R, x0, P0 = cv_model()
    m = kf.LinearGaussian(F, H, Q, R)
    if form is None:
        return lambda: m.loglik(y, x0, P0)
    return lambda: m.loglik(y, x0, P0, form=form)


def mk_kfast_stream(y, read_x=False):
    kf = kfast_module()
    F, H, Q, R, x0, P0 = cv_model()
    m = kf.LinearGaussian(F, H, Q, R)
    rows = list(y)  # 1-D float64 arrays, made outside the timed loop

    def run():
        f = kf.KalmanFilter(m, x0, P0)
        upd, pred = f.update, f.predict
        if read_x:
            for r in rows:
                upd(r)
                pred()
                f.x
        else:
            for r in rows:
                upd(r)
                pred()
        return f

    return run


# ---- statsmodels -------------------------------------------------------------
def _sm_kf(y, **kw):
    # NB: pass `tolerance` to the constructor.  In statsmodels 0.15.0
    # KalmanFilter._filter() hands (filter_timing, tolerance) positionally to
    # _initialize_filter(..., tolerance, filter_timing, ...), so a `tolerance=`
    # given to filter()/loglike()/_filter() silently lands in filter_timing.
    kfm = _import("statsmodels.tsa.statespace.kalman_filter")
    F, H, Q, R, x0, P0 = cv_model()
    kf = kfm.KalmanFilter(k_endog=2, k_states=4, k_posdef=4, **kw)
    kf.bind(y.copy())
    kf["design"] = H
    kf["obs_cov"] = R
    kf["transition"] = F
    kf["selection"] = np.eye(4)
    kf["state_cov"] = Q
    kf.initialize_known(x0, P0)
    return kfm, kf


def mk_sm_filter_default(y):
    _, kf = _sm_kf(y)

    def run():
        r = kf.filter()
        return r.filtered_state, r.filtered_state_cov

    return run


# "tuned" = the fastest options found by measurement on this model (see
# BENCHMARKS.md for the table):
#  * filter_method=FILTER_UNIVARIATE (treats y_t one element at a time; exact
#    here because R is diagonal) -- about 2x on its own;
#  * stability_method=0 (no forced symmetrisation of P_pred) -- another ~15%;
#  * conserve_memory: store only what the workload returns;
#  * W1 calls the Cython filter via kf._filter() (skips building FilterResults).
#  * The steady-state shortcut (tolerance=1e-19, on by default) is kept; the
#    "no steady" rows switch it off (tolerance=0) to compare like with like,
#    since kfast's defaults (what the bench times) run the full recursion.
def _sm_tuned_kf(y, steady_state=True):
    kfm = _import("statsmodels.tsa.statespace.kalman_filter")
    kw = dict(filter_method=kfm.FILTER_UNIVARIATE, stability_method=0)
    if not steady_state:
        kw["tolerance"] = 0.0
    return _sm_kf(y, **kw)


def _sm_filter_memory(kfm):
    return (kfm.MEMORY_NO_FORECAST | kfm.MEMORY_NO_PREDICTED | kfm.MEMORY_NO_GAIN
            | kfm.MEMORY_NO_SMOOTHING | kfm.MEMORY_NO_STD_FORECAST | kfm.MEMORY_NO_LIKELIHOOD)


def mk_sm_filter_tuned(y, steady_state=True):
    kfm, kf = _sm_tuned_kf(y, steady_state)
    mem = _sm_filter_memory(kfm)

    def run():
        k = kf._filter(conserve_memory=mem)
        # (n,T) / (n,n,T) Fortran-ordered arrays; transposed views are free.
        return np.asarray(k.filtered_state).T, np.asarray(k.filtered_state_cov).transpose(2, 0, 1)

    return run


def _sm_ks(y, **kw):
    """Same set-up as _sm_kf, on statsmodels' KalmanSmoother."""
    kss = _import("statsmodels.tsa.statespace.kalman_smoother")
    F, H, Q, R, x0, P0 = cv_model()
    ks = kss.KalmanSmoother(k_endog=2, k_states=4, k_posdef=4, **kw)
    ks.bind(y.copy())
    ks["design"] = H
    ks["obs_cov"] = R
    ks["transition"] = F
    ks["selection"] = np.eye(4)
    ks["state_cov"] = Q
    ks.initialize_known(x0, P0)
    return kss, ks


def mk_sm_smooth_default(y):
    # smooth() with defaults: the filter stores everything, the smoother
    # computes SMOOTHER_ALL (states, state covs, disturbances, disturbance
    # covs, state autocovariances) and a SmootherResults is built.
    _, ks = _sm_ks(y)

    def run():
        r = ks.smooth()
        return r.smoothed_state.T, r.smoothed_state_cov.transpose(2, 0, 1)

    return run


# "tuned" smoother (measured with benches/sm_options.py, see BENCHMARKS.md):
#  * smoother_output = states and state covariances only, and the Cython
#    filter/smoother called through ks._filter() / ks._smooth() (no
#    SmootherResults) -- about 2x against plain smooth();
#  * stability_method=0 -- a few %;
#  * filter_method=FILTER_UNIVARIATE kept for consistency with W1: for the
#    whole filter + smoother it ties with the conventional filter (the faster
#    univariate filter is paid back in the univariate smoother);
#  * smoothing method: the default (conventional) beats SMOOTH_ALTERNATIVE and
#    SMOOTH_CLASSICAL (the textbook RTS form);
#  * conserve_memory can only drop the likelihood and standardised forecast
#    errors (the smoother needs the rest); set, makes no measurable difference.
#  * The steady-state shortcut is on as by default; "no steady" = tolerance=0.
def mk_sm_smooth_tuned(y, steady_state=True):
    kfm = _import("statsmodels.tsa.statespace.kalman_filter")
    kw = dict(filter_method=kfm.FILTER_UNIVARIATE, stability_method=0,
              conserve_memory=kfm.MEMORY_NO_LIKELIHOOD | kfm.MEMORY_NO_STD_FORECAST)
    if not steady_state:
        kw["tolerance"] = 0.0
    kss, ks = _sm_ks(y, **kw)
    out = kss.SMOOTHER_STATE | kss.SMOOTHER_STATE_COV

    def run():
        ks._filter()
        k = ks._smooth(out)
        return np.asarray(k.smoothed_state).T, np.asarray(k.smoothed_state_cov).transpose(2, 0, 1)

    return run


def sm_lag1_reference(y):
    """statsmodels' smoothed_state_autocov with the full recursion (tolerance=0):
    autocov[t] = Cov(x[t+1], x[t] | all y), i.e. kfast's P_lag1[t+1]."""
    _, ks = _sm_ks(y, tolerance=0.0)
    r = ks.smooth()
    return np.asarray(r.smoothed_state_autocov).transpose(2, 0, 1)


def mk_sm_loglik_default(y):
    _, kf = _sm_kf(y)
    return lambda: kf.loglike()


def mk_sm_loglik_tuned(y, steady_state=True):
    kfm, kf = _sm_tuned_kf(y, steady_state)
    return lambda: kf.loglike(conserve_memory=kfm.MEMORY_CONSERVE)


def sm_steady_state_info(y, **kw):
    """Does statsmodels' steady-state shortcut kick in on this data?"""
    try:
        kfm, kf = _sm_kf(y, **kw)
        k = kf._filter(conserve_memory=kfm.MEMORY_CONSERVE)
        conv = bool(k.converged)
        per = int(k.period_converged) if conv else None
        return conv, per
    except Exception:  # noqa: BLE001
        return None, None


# ---- filterpy ---------------------------------------------------------------
def _fp_kf():
    fpk = _import("filterpy.kalman")
    F, H, Q, R, x0, P0 = cv_model()
    kf = fpk.KalmanFilter(dim_x=4, dim_z=2)
    kf.F, kf.H, kf.Q, kf.R = F.copy(), H.copy(), Q.copy(), R.copy()
    return kf, x0, P0


def _fp_reset(kf, x0, P0):
    # 1-D state: filterpy's batch_filter passes H explicitly to update(), which
    # then skips reshaping z, so a (4,1) state with (2,) rows broadcasts wrongly.
    kf.x = x0.copy()
    kf.P = P0.copy()


def mk_fp_filter(y):
    kf, x0, P0 = _fp_kf()

    def run():
        _fp_reset(kf, x0, P0)
        means, covs, _, _ = kf.batch_filter(y, update_first=True)
        return means, covs

    return run


def mk_fp_smooth(y):
    kf, x0, P0 = _fp_kf()

    def run():
        _fp_reset(kf, x0, P0)
        means, covs, _, _ = kf.batch_filter(y, update_first=True)
        xs, Ps, _, _ = kf.rts_smoother(means, covs)
        return xs, Ps

    return run


def mk_fp_loglik(y):
    kf, x0, P0 = _fp_kf()
    rows = list(y)

    def run():
        _fp_reset(kf, x0, P0)
        ll = 0.0
        for r in rows:
            kf.update(r)
            ll += kf.log_likelihood
            kf.predict()
        return ll

    return run


def mk_fp_stream(y):
    kf, x0, P0 = _fp_kf()
    rows = list(y)

    def run():
        _fp_reset(kf, x0, P0)
        upd, pred = kf.update, kf.predict
        for r in rows:
            upd(r)
            pred()
        return kf

    return run


# ---- pykalman ---------------------------------------------------------------
def _pk_kf():
    pk = _import("pykalman")
    F, H, Q, R, x0, P0 = cv_model()
    return pk.KalmanFilter(transition_matrices=F, observation_matrices=H,
                           transition_covariance=Q, observation_covariance=R,
                           initial_state_mean=x0, initial_state_covariance=P0)


def mk_pk_filter(y):
    kf = _pk_kf()
    return lambda: kf.filter(y)


def mk_pk_smooth(y):
    kf = _pk_kf()
    return lambda: kf.smooth(y)


def mk_pk_loglik(y):
    kf = _pk_kf()
    return lambda: kf.loglikelihood(y)


# ---- simdkalman -------------------------------------------------------------
def _sk_kf():
    sk = _import("simdkalman")
    F, H, Q, R, x0, P0 = cv_model()
    return sk.KalmanFilter(state_transition=F, process_noise=Q,
                           observation_model=H, observation_noise=R), x0, P0


def mk_sk_filter(y):
    kf, x0, P0 = _sk_kf()
    data = y[None]  # (1 series, T, m)

    def run():
        r = kf.compute(data, 0, initial_value=x0, initial_covariance=P0,
                       smoothed=False, filtered=True, observations=False)
        return r.filtered.states.mean, r.filtered.states.cov

    return run


def mk_sk_smooth(y):
    kf, x0, P0 = _sk_kf()
    data = y[None]

    def run():
        r = kf.compute(data, 0, initial_value=x0, initial_covariance=P0,
                       smoothed=True, filtered=False, observations=False)
        return r.smoothed.states.mean[0], r.smoothed.states.cov[0]

    return run


def mk_sk_loglik(y):
    kf, x0, P0 = _sk_kf()
    data = y[None]

    def run():
        r = kf.compute(data, 0, initial_value=x0, initial_covariance=P0,
                       smoothed=False, filtered=False, states=False,
                       covariances=False, observations=False, log_likelihood=True)
        # simdkalman leaves out the constant -T*m/2*log(2*pi); add it back
        return float(np.asarray(r.log_likelihood).ravel()[0]) + const

    const = -0.5 * y.shape[0] * y.shape[1] * np.log(2 * np.pi)

    return run


# ---- dynamax (JAX, CPU) -------------------------------------------------------
_DYNAMAX = None


def _dynamax():
    global _DYNAMAX
    if _DYNAMAX is None:
        jax = _import("jax")
        jax.config.update("jax_enable_x64", True)
        inf = _import("dynamax.linear_gaussian_ssm.inference")
        jnp = _import("jax.numpy")
        F, H, Q, R, x0, P0 = cv_model()
        params = inf.ParamsLGSSM(
            initial=inf.ParamsLGSSMInitial(mean=jnp.asarray(x0), cov=jnp.asarray(P0)),
            dynamics=inf.ParamsLGSSMDynamics(weights=jnp.asarray(F), bias=jnp.zeros(4),
                                              input_weights=jnp.zeros((4, 0)), cov=jnp.asarray(Q)),
            emissions=inf.ParamsLGSSMEmissions(weights=jnp.asarray(H), bias=jnp.zeros(2),
                                                input_weights=jnp.zeros((2, 0)), cov=jnp.asarray(R)),
        )
        f_filter = jax.jit(lambda p, e: (lambda r: (r.filtered_means, r.filtered_covariances,
                                                     r.marginal_loglik))(inf.lgssm_filter(p, e)))
        f_ll = jax.jit(lambda p, e: inf.lgssm_filter(p, e).marginal_loglik)
        _DYNAMAX = (jax, jnp, params, f_filter, f_ll)
    return _DYNAMAX


def mk_dx_filter(y):
    jax, jnp, params, f_filter, _ = _dynamax()
    e = jax.device_put(jnp.asarray(y))
    return lambda: jax.block_until_ready(f_filter(params, e))


def mk_dx_loglik(y):
    jax, jnp, params, _, f_ll = _dynamax()
    e = jax.device_put(jnp.asarray(y))
    return lambda: jax.block_until_ready(f_ll(params, e))


_DX_SMOOTH = None


def mk_dx_smooth(y):
    global _DX_SMOOTH
    jax, jnp, params, _, _ = _dynamax()
    if _DX_SMOOTH is None:
        inf = _import("dynamax.linear_gaussian_ssm.inference")
        # only means and covariances leave the jitted function (lgssm_smoother
        # also builds smoothed_cross_covariances; XLA may drop that work)
        _DX_SMOOTH = jax.jit(lambda p, e: (lambda r: (r.smoothed_means, r.smoothed_covariances))(
            inf.lgssm_smoother(p, e)))
    f = _DX_SMOOTH
    e = jax.device_put(jnp.asarray(y))
    return lambda: jax.block_until_ready(f(params, e))


# ---- C loop -------------------------------------------------------------------
# Two builds of the same kf_cv.c.  C_REF (gcc -O3 -march=native) is THE
# reference of issue #11 (kfast must beat it) and of the cross-checks.  C_128
# adds -mprefer-vector-width=128: on AVX-512 machines (Zen 4) -march=native lets
# gcc use wider vectors, which are slower here than 128-bit vectors with FMA, so
# that row shows what the same C gets with better flags.
from cloop import DEFAULT_FLAGS as C_REF  # noqa: E402
C_128 = (*C_REF, "-mprefer-vector-width=128")
_CLOOPS: dict = {}  # (n, m, flags) -> CLoop or the build's exception


def c_name(flags=C_REF):
    """Row label of a C-loop build: its optimisation flags, verbatim."""
    return "C loop " + " ".join(flags)


def c_loop(flags=C_REF, n=4, m=2):
    """The C loop compiled with `flags` for N=n, M=m; built once per process."""
    key = (n, m, tuple(flags))
    if key not in _CLOOPS:
        from cloop import CLoop
        try:
            _CLOOPS[key] = CLoop.build(n, m, flags=flags)
        except Exception as e:  # noqa: BLE001
            _CLOOPS[key] = e
    if isinstance(_CLOOPS[key], Exception):
        raise Unavailable("C build failed: " + _short_err(_CLOOPS[key]))
    return _CLOOPS[key]


def mk_c_filter(y, reuse=False, flags=C_REF):
    c = c_loop(flags)
    args = c.prepare(*cv_model()[:4], y, *cv_model()[4:])
    if reuse:
        out = (np.empty((len(y), 4)), np.empty((len(y), 4, 4)))
        return lambda: c.filter_prepared(args, out)
    return lambda: c.filter_prepared(args)


def mk_c_smooth(y, reuse=False, flags=C_REF):
    c = c_loop(flags)
    args = c.prepare(*cv_model()[:4], y, *cv_model()[4:])
    if reuse:
        out = c.smooth_out(len(y))
        return lambda: c.smooth_prepared(args, out)
    return lambda: c.smooth_prepared(args)


def mk_c_loglik(y, flags=C_REF):
    c = c_loop(flags)
    args = c.prepare(*cv_model()[:4], y, *cv_model()[4:])
    return lambda: c.loglik_prepared(args)


def c_rows(mk, T, notes):
    """Spec rows of the C loop for W1-W3: for each build (reference first, then
    the 128-bit one) one row per (suffix, mk keyword arguments, note) in `notes`.
    Group "c" is the reference only (plots' "C loop" bar); the other build is "c-alt"."""
    rows = []
    for flags, group in ((C_REF, "c"), (C_128, "c-alt")):
        for suffix, kw, note in notes:
            rows.append((c_name(flags) + suffix, lambda yy, kw=kw, flags=flags: mk(yy, flags=flags, **kw),
                         T, note, group))
    return rows


# --------------------------------------------------------------------------
# Correctness cross-checks (so the timing comparison is honest)
# --------------------------------------------------------------------------
def _extract_filter(name, out):
    """Normalise a contender's W1 output to (x_filt (T,n), P_filt (T,n,n))."""
    if hasattr(out, "x_filt"):
        return np.asarray(out.x_filt), np.asarray(out.P_filt)
    if name.startswith("filterpy"):
        xf = np.asarray(out[0])
        return (xf[..., 0] if xf.ndim == 3 else xf), np.asarray(out[1])
    if name.startswith("C loop"):
        return out[0], out[1]
    if name.startswith("dynamax"):
        return np.asarray(out[0]), np.asarray(out[1])
    if name.startswith("simdkalman"):
        return np.asarray(out[0])[0], np.asarray(out[1])[0]
    if name.startswith("statsmodels") and "default" in name:
        return np.asarray(out[0]).T, np.asarray(out[1]).transpose(2, 0, 1)
    return np.asarray(out[0]), np.asarray(out[1])


def _extract_smooth(name, out):
    """Normalise a W2 output to (x_smooth (T,n), P_smooth (T,n,n))."""
    if hasattr(out, "x_smooth"):
        return np.asarray(out.x_smooth), np.asarray(out.P_smooth)
    xs, Ps = out[0], out[1]
    return np.asarray(xs), np.asarray(Ps)


def check_smooth(contenders, y, log):
    """Max |diff| of every W2 contender's x_smooth / P_smooth against the C
    loop, plus kfast's lag-one covariances against statsmodels'
    smoothed_state_autocov (full recursion)."""
    try:
        c = c_loop()
    except Unavailable as e:
        log(f"  (no cross-check: {e})")
        return {}
    F, H, Q, R, x0, P0 = cv_model()
    res = {}
    refs = {}
    lag1_ref = None
    for k in contenders:
        if not k.ok or k.group == "c":  # the reference itself (other C builds are checked)
            continue
        T = k.steps
        if T not in refs:
            refs[T] = c.smooth(F, H, Q, R, y[:T], x0, P0)
        xr, Pr, _ = refs[T]
        try:
            out = k.fn()
            xs, Ps = _extract_smooth(k.name, out)
            dx = float(np.max(np.abs(xs - xr)))
            dP = float(np.max(np.abs(Ps - Pr)))
            res[k.name] = (dx, dP)
            log(f"  {k.name:<36s} max|dx_smooth| = {dx:.2e}   max|dP_smooth| = {dP:.2e}   (T={T})")
            if getattr(out, "P_lag1", None) is not None:
                if lag1_ref is None:
                    try:
                        lag1_ref = sm_lag1_reference(y[:T])
                    except Exception as e:  # noqa: BLE001
                        lag1_ref = e
                if isinstance(lag1_ref, Exception):
                    log(f"  {'':<36s} (no lag-one check: {_short_err(lag1_ref)})")
                elif len(lag1_ref) == T:
                    L = np.asarray(out.P_lag1)
                    d1 = float(np.max(np.abs(L[1:] - lag1_ref[:-1])))
                    res[k.name] = (dx, dP, d1)
                    log(f"  {'':<36s} max|dP_lag1| = {d1:.2e} vs statsmodels smoothed_state_autocov (tolerance=0)")
        except Exception as e:  # noqa: BLE001
            log(f"  {k.name:<36s} check failed: {_short_err(e)}")
    return res


def _loglik_of(name, out):
    if hasattr(out, "loglik"):
        return float(out.loglik)
    return float(out)


def check_filter(contenders, y, log):
    """Max |diff| of every W1 contender's x_filt / P_filt against the C loop."""
    try:
        c = c_loop()
    except Unavailable as e:
        log(f"  (no cross-check: {e})")
        return {}
    F, H, Q, R, x0, P0 = cv_model()
    res = {}
    refs = {}
    for k in contenders:
        if not k.ok or k.group == "c":  # the reference itself (other C builds are checked)
            continue
        T = k.steps
        if T not in refs:
            refs[T] = c.filter(F, H, Q, R, y[:T], x0, P0)
        xr, Pr, _ = refs[T]
        try:
            xf, Pf = _extract_filter(k.name, k.fn())
            dx = float(np.max(np.abs(xf - xr)))
            dP = float(np.max(np.abs(Pf - Pr)))
            res[k.name] = (dx, dP)
            log(f"  {k.name:<36s} max|dx_filt| = {dx:.2e}   max|dP_filt| = {dP:.2e}   (T={T})")
        except Exception as e:  # noqa: BLE001
            log(f"  {k.name:<36s} check failed: {_short_err(e)}")
    return res


def check_loglik(contenders, y, log):
    try:
        c = c_loop()
    except Unavailable as e:
        log(f"  (no cross-check: {e})")
        return {}
    F, H, Q, R, x0, P0 = cv_model()
    res = {}
    for k in contenders:
        if not k.ok:
            continue
        T = k.steps
        ref = c.loglik(F, H, Q, R, y[:T], x0, P0)
        if k.group == "c":
            log(f"  {k.name:<36s} loglik = {ref:.10f}   (T={T})")
            continue
        try:
            ll = _loglik_of(k.name, k.fn())
            d = abs(ll - ref)
            res[k.name] = d
            log(f"  {k.name:<36s} |loglik - C| = {d:.2e}   (rel {d / abs(ref):.1e}, T={T})")
        except Exception as e:  # noqa: BLE001
            log(f"  {k.name:<36s} check failed: {_short_err(e)}")
    return res


# --------------------------------------------------------------------------
# Reporting
# --------------------------------------------------------------------------
def fmt_ns(x):
    if x >= 1e4:
        return f"{x:,.0f}"
    if x >= 100:
        return f"{x:.0f}"
    return f"{x:.1f}"


def table(contenders, kfast_names, title, md=False):
    """Rows: contender, T, ns/step, IQR, and kfast/this for each kfast variant."""
    kref = {n: next((c for c in contenders if c.name == n and c.ok), None) for n in kfast_names}
    head = ["contender", "T", "ns/step", "IQR (ns/step)"] + [f"{n}/this" for n in kfast_names] + ["note"]
    rows = []
    for c in contenders:
        if c.ok:
            lo, hi = c.spread()
            r = [c.name, f"{c.steps:,}", fmt_ns(c.ns_per_step()), f"{fmt_ns(lo)}-{fmt_ns(hi)}"]
            for n in kfast_names:
                k = kref[n]
                r.append(f"{k.ns_per_step() / c.ns_per_step():.3g}" if k else "n/a")
        else:
            r = [c.name, f"{c.steps:,}", "-", "-"] + ["n/a"] * len(kfast_names)
        note = c.note
        if not c.ok:
            note = (c.error or "no samples") + ("; " + note if note else "")
        r.append(note)
        rows.append(r)
    if md:
        out = [f"#### {title}", "", "| " + " | ".join(head) + " |",
               "|" + "|".join(["---"] + ["---:"] * (len(head) - 2) + ["---"]) + "|"]
        out += ["| " + " | ".join(x.replace("|", "\\|") for x in r) + " |" for r in rows]
        return "\n".join(out) + "\n"
    w = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    w[-1] = 0
    line = lambda r: "  ".join(  # noqa: E731
        (s.ljust(w[i]) if i in (0, len(r) - 1) else s.rjust(w[i])) for i, s in enumerate(r)).rstrip()
    out = [title, line(head), line(["-" * x for x in w[:-1]] + [""])]
    out += [line(r) for r in rows]
    return "\n".join(out) + "\n"


# SIMD extensions that matter for the kernels, in /proc/cpuinfo's spelling.
SIMD_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512bw", "avx512vl",
              "avx512ifma", "avx512vbmi")


def cpu_simd():
    """The SIMD_FLAGS this CPU reports (first 'flags' line of /proc/cpuinfo), space-separated."""
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((line.split(":", 1)[1].split() for line in f if line.startswith("flags")), [])
    except OSError:
        return "? (no /proc/cpuinfo)"
    return " ".join(x for x in SIMD_FLAGS if x in flags) or "none of " + " ".join(SIMD_FLAGS)


def kfast_kernel():
    """Which kernel kfast dispatched to, from kfast._kfast.kernel_info() (older
    builds lack it: then says so instead of failing)."""
    try:
        fn = getattr(importlib.import_module("kfast._kfast"), "kernel_info", None)
        if fn is None:
            return "n/a (no kfast._kfast.kernel_info)"
        return ", ".join(f"{k}={v}" for k, v in dict(fn()).items())
    except Exception as e:  # noqa: BLE001
        return "n/a (" + _short_err(e) + ")"


def machine_info():
    info = {}
    try:
        txt = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=10).stdout
        m = re.search(r"^Model name:\s*(.+)$", txt, re.M)
        info["cpu"] = m.group(1).strip() if m else platform.processor() or "?"
    except Exception:  # noqa: BLE001
        info["cpu"] = platform.processor() or "?"
    info["cores"] = os.cpu_count()
    info["python"] = platform.python_version()
    info["numpy"] = np.__version__
    info["kfast"] = kfast_version() or "not installed"
    try:
        ext = importlib.import_module("kfast._kfast").__file__
        info["kfast"] += " (extension built " + _dt.datetime.fromtimestamp(
            os.path.getmtime(ext)).isoformat(timespec="minutes") + ")"
    except Exception:  # noqa: BLE001
        pass
    info["simd"] = cpu_simd()
    info["kernel"] = kfast_kernel()
    info["platform"] = platform.platform()
    try:
        info["load"] = "%.2f %.2f %.2f" % os.getloadavg()
    except OSError:
        info["load"] = "?"
    try:
        info["gcc"] = subprocess.run(["gcc", "-dumpfullversion"], capture_output=True,
                                     text=True, timeout=10).stdout.strip() or "?"
    except Exception:  # noqa: BLE001
        info["gcc"] = "not found"
    peers = {}
    for d in ["statsmodels", "filterpy", "pykalman", "simdkalman", "dynamax", "jax", "scipy"]:
        peers[d] = version_of(d) or "not installed"
    info["peers"] = peers
    return info


# --------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------
def contender(name, make, steps, note, group, log):
    """A Contender whose timed function is `make()`; a failure to make it is recorded as the
    contender's error (and logged), never raised."""
    c = Contender(name, None, steps, note, group)
    try:
        c.fn = make()
    except Unavailable as e:
        c.error = str(e)
    except Exception as e:  # noqa: BLE001
        c.error = "setup failed: " + _short_err(e)
    if c.error:
        log(f"    [{name}] {c.error}")
    return c


def build(spec, y_full, log):
    """spec: list of (name, factory, T, note, group)."""
    return [contender(name, lambda f=factory, T=T: f(y_full[:T]), T, note, group, log)
            for name, factory, T, note, group in spec]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="short smoke run")
    ap.add_argument("--write", action="store_true", help="rewrite the results block of BENCHMARKS.md")
    ap.add_argument("--rounds", type=int, default=None, help="interleaved rounds per workload")
    ap.add_argument("--only", default="W1,W2,W3,W4,W5,W6,W7,W8,MEM",
                    help="comma list of workloads (W1-W8, MEM)")
    ap.add_argument("--json", metavar="PATH", help="also dump the medians as JSON to PATH")
    args = ap.parse_args(argv)

    buf = io.StringIO()

    def log(s=""):
        print(s, flush=True)
        buf.write(s + "\n")

    quick = args.quick
    T = 20_000 if quick else 100_000
    T_slow = 1_000 if quick else 5_000      # filterpy, pykalman, simdkalman (pure Python/NumPy per step)
    T_stream_k = 5_000 if quick else 20_000  # kfast streaming, per sample
    T_stream_p = 500 if quick else 2_000     # filterpy streaming, per sample
    rounds = args.rounds or (3 if quick else 9)
    todo = {w.strip().upper() for w in args.only.split(",")}

    info = machine_info()
    info["memory"] = keep_freed_memory()
    t_start = time.time()
    log(f"kfast benchmark  {_dt.datetime.now().isoformat(timespec='seconds')}  "
        f"{'(quick)' if quick else ''}")
    log(f"machine: {info['cpu']}, {info['cores']} cores | python {info['python']} | "
        f"numpy {info['numpy']} | kfast {info['kfast']} | gcc {info['gcc']} | load {info['load']}")
    log(f"cpu SIMD: {info['simd']} | kfast kernel: {info['kernel']}"
        + (f" | {info['memory']}" if info["memory"] else ""))
    log("peers: " + ", ".join(f"{k} {v}" for k, v in info["peers"].items()))
    log(f"model CV (n=4, m=2, dt={DT}, q=1, R=I), float64, seed {SEED}; T={T:,}; "
        f"slow peers T={T_slow:,}; {rounds} interleaved rounds, medians")
    y = simulate(T)

    info["c_builds"] = []
    for flags, role in ((C_REF, "the reference"), (C_128, "extra rows in W1-W3")):
        try:
            info["c_builds"].append(f"`{c_loop(flags).cc_cmd}` ({role})")
            log(f"C loop ({role}): {c_loop(flags).cc_cmd} benches/c/kf_cv.c (N=4, M=2 compile-time)")
        except Unavailable as e:
            log(f"C loop ({role}, {' '.join(flags)}): {e}")

    if any(k in todo for k in ("W1", "W2", "W3")):
        # pre-compile the JAX functions so that failures show up here
        try:
            _dynamax()
        except Unavailable as e:
            log(f"dynamax: {e}")
        except Exception as e:  # noqa: BLE001
            log(f"dynamax: setup failed: {_short_err(e)}")

    ss_conv, ss_per = sm_steady_state_info(y)
    if ss_conv is None:
        sm_ss_note = ""
    elif ss_conv:
        sm_ss_note = f"steady-state shortcut ON (default), converged at t={ss_per}"
    else:
        sm_ss_note = "steady-state shortcut ON (default) but never triggered"
    conv0, _ = sm_steady_state_info(y, tolerance=0.0)
    ns_note = ("as tuned, tolerance=0 (full recursion like kfast's default; "
               + ("verified: never converges)" if conv0 is False else "WARNING: still converged)")
               if conv0 is not None else "as tuned, tolerance=0 (full recursion like kfast's default)")
    results = {}
    slow = f"T={T_slow:,} (slow peer)"

    # ---------------- W1: filter ----------------
    if "W1" in todo:
        log("\n== W1: filter -> x_filt (T,n) and P_filt (T,n,n) ==")
        spec = [
            ("kfast standard", lambda yy: mk_kfast_filter(yy, "standard"), T, "", "kfast"),
            ("kfast joseph", lambda yy: mk_kfast_filter(yy, "joseph"), T, "", "kfast"),
            ("kfast standard, x_filt+P_filt", lambda yy: mk_kfast_filter(yy, "standard", ("x_filt", "P_filt")), T,
             "outputs=(\"x_filt\", \"P_filt\"): the workload's outputs, like the C loop", "kfast"),
            ("kfast joseph, x_filt+P_filt", lambda yy: mk_kfast_filter(yy, "joseph", ("x_filt", "P_filt")), T,
             "outputs=(\"x_filt\", \"P_filt\")", "kfast"),
            ("kfast standard, x_filt+P_filt, no FMA",
             lambda yy: without_fma(mk_kfast_filter)(yy, "standard", ("x_filt", "P_filt")), T,
             "the loops of a CPU without FMA: run-time sizes, separate multiply-adds", "kfast"),
            ("kfast joseph, x_filt+P_filt, no FMA",
             lambda yy: without_fma(mk_kfast_filter)(yy, "joseph", ("x_filt", "P_filt")), T,
             "the loops of a CPU without FMA", "kfast"),
            *c_rows(mk_c_filter, T, [("", {}, "fresh output arrays each call"),
                                     (", reused out", {"reuse": True},
                                      "output buffers preallocated (no page faults)")]),
            ("statsmodels tuned", mk_sm_filter_tuned, T, "univariate, no symmetrisation, _filter(), conserve_memory; " + sm_ss_note, "peer"),
            ("statsmodels tuned, no steady", lambda yy: mk_sm_filter_tuned(yy, False), T,
             ns_note, "peer"),
            ("statsmodels default", mk_sm_filter_default, T, "KalmanFilter.filter(); " + sm_ss_note, "peer"),
            ("dynamax", mk_dx_filter, T, "jax.jit(lgssm_filter), CPU, x64", "peer"),
            ("simdkalman", mk_sk_filter, T_slow, slow, "peer"),
            ("filterpy", mk_fp_filter, T_slow, slow + "; batch_filter(update_first=True), Joseph", "peer"),
            ("pykalman", mk_pk_filter, T_slow, slow, "peer"),
        ]
        spec += [(f"kfast {f}, x_filt+P_filt", lambda yy, f=f: mk_kfast_filter(yy, f, W1_OUT), T,
                  f"form=\"{f}\" (docs/algorithms.md, \"Update forms\"), the workload's outputs", "kfast")
                 for f in ROBUST_FORMS]
        cs = build(spec, y, log)
        run_interleaved(cs, rounds, log=log)
        log("")
        log(table(cs, ["kfast standard", "kfast joseph", "kfast standard, x_filt+P_filt"], "W1 results"))
        log("cross-check vs C loop (same T):")
        chk = check_filter(cs, y, log)
        results["W1"] = (cs, ["kfast standard", "kfast joseph", "kfast standard, x_filt+P_filt"], chk)

    # ---------------- W2: RTS smoother ----------------
    if "W2" in todo:
        log("\n== W2: filter + RTS smoother -> x_smooth (T,n) and P_smooth (T,n,n) ==")
        lag = "; also returns P_lag1 and the full FilterResult"
        spec = [
            ("kfast smooth standard", lambda yy: mk_kfast_smooth(yy, "standard"), T,
             "LinearGaussian.smooth(form=\"standard\")" + lag, "kfast"),
            ("kfast smooth joseph", lambda yy: mk_kfast_smooth(yy, "joseph"), T,
             "LinearGaussian.smooth() (default form, joseph)" + lag, "kfast"),
            ("kfast standard, x_smooth+P_smooth", lambda yy: mk_kfast_smooth(yy, "standard", W2_OUT), T,
             "outputs=(\"x_smooth\", \"P_smooth\"): the workload's outputs, like the C loop", "kfast"),
            ("kfast joseph, x_smooth+P_smooth", lambda yy: mk_kfast_smooth(yy, "joseph", W2_OUT), T,
             "outputs=(\"x_smooth\", \"P_smooth\")", "kfast"),
            ("kfast standard, x_smooth+P_smooth, no FMA",
             lambda yy: without_fma(mk_kfast_smooth)(yy, "standard", W2_OUT), T,
             "the loops of a CPU without FMA: run-time sizes, separate multiply-adds", "kfast"),
            *c_rows(mk_c_smooth, T, [("", {}, "fresh outputs + prior buffers each call"),
                                     (", reused out", {"reuse": True},
                                      "output and prior buffers preallocated")]),
            ("statsmodels tuned", mk_sm_smooth_tuned, T,
             "univariate, no symmetrisation, _filter() + _smooth(STATE|STATE_COV); " + sm_ss_note, "peer"),
            ("statsmodels tuned, no steady", lambda yy: mk_sm_smooth_tuned(yy, False), T,
             ns_note, "peer"),
            ("statsmodels default", mk_sm_smooth_default, T,
             "KalmanSmoother.smooth() (SMOOTHER_ALL: also disturbances and autocovs); " + sm_ss_note, "peer"),
            ("dynamax", mk_dx_smooth, T, "jax.jit(lgssm_smoother) -> means, covs; CPU, x64", "peer"),
            ("simdkalman", mk_sk_smooth, T_slow, slow + "; compute(smoothed=True)", "peer"),
            ("filterpy", mk_fp_smooth, T_slow, slow + "; batch_filter(update_first=True) + rts_smoother", "peer"),
            ("pykalman", mk_pk_smooth, T_slow, slow + "; smooth()", "peer"),
        ]
        cs = build(spec, y, log)
        run_interleaved(cs, rounds, log=log)
        log("")
        log(table(cs, ["kfast smooth standard", "kfast smooth joseph", "kfast standard, x_smooth+P_smooth"], "W2 results"))
        log("cross-check vs C loop (same T):")
        chk = check_smooth(cs, y, log)
        results["W2"] = (cs, ["kfast smooth standard", "kfast smooth joseph", "kfast standard, x_smooth+P_smooth"], chk)

    # ---------------- W3: loglik ----------------
    if "W3" in todo:
        log("\n== W3: total log-likelihood only ==")
        spec = [
            ("kfast loglik", mk_kfast_loglik, T, "LinearGaussian.loglik() (default form, joseph)", "kfast"),
            ("kfast loglik standard", lambda yy: mk_kfast_loglik(yy, "standard"), T,
             "LinearGaussian.loglik(form=\"standard\")", "kfast"),
            ("kfast loglik, no FMA", lambda yy: without_fma(mk_kfast_loglik)(yy), T,
             "the loops of a CPU without FMA: run-time sizes, separate multiply-adds", "kfast"),
            ("kfast loglik standard, no FMA", lambda yy: without_fma(mk_kfast_loglik)(yy, "standard"), T,
             "the loops of a CPU without FMA", "kfast"),
            *[(f"kfast loglik {f}", lambda yy, f=f: mk_kfast_loglik(yy, f), T,
               f"LinearGaussian.loglik(form=\"{f}\")", "kfast") for f in ROBUST_FORMS],
            *c_rows(mk_c_loglik, T, [("", {}, "")]),
            ("statsmodels tuned", mk_sm_loglik_tuned, T, "univariate, no symmetrisation, loglike(conserve_memory=MEMORY_CONSERVE); " + sm_ss_note, "peer"),
            ("statsmodels tuned, no steady", lambda yy: mk_sm_loglik_tuned(yy, False), T,
             ns_note, "peer"),
            ("statsmodels default", mk_sm_loglik_default, T, "KalmanFilter.loglike(); " + sm_ss_note, "peer"),
            ("dynamax", mk_dx_loglik, T, "jax.jit(lgssm_filter(...).marginal_loglik)", "peer"),
            ("simdkalman", mk_sk_loglik, T_slow, slow + "; compute(log_likelihood=True); its loglik omits the -Tm/2 log 2pi constant (added back)", "peer"),
            ("filterpy", mk_fp_loglik, T_slow, slow + "; update/predict loop + log_likelihood", "peer"),
            ("pykalman", mk_pk_loglik, T_slow, slow + "; loglikelihood()", "peer"),
        ]
        cs = build(spec, y, log)
        run_interleaved(cs, rounds, log=log)
        log("")
        log(table(cs, ["kfast loglik", "kfast loglik standard"], "W3 results"))
        log("cross-check vs C loop (same T):")
        chk = check_loglik(cs, y, log)
        results["W3"] = (cs, ["kfast loglik", "kfast loglik standard"], chk)

    # ---------------- W7: streaming ----------------
    if "W7" in todo:
        log("\n== W7: streaming, one update + one predict call per step from Python ==")
        spec = [
            ("kfast stream", mk_kfast_stream, T_stream_k, "KalmanFilter.update(y_t); .predict()", "kfast"),
            ("kfast stream + read x", lambda yy: mk_kfast_stream(yy, True), T_stream_k,
             "same, plus reading kf.x every step", "kfast"),
            ("filterpy", mk_fp_stream, T_stream_p, f"T={T_stream_p:,}; update(z); predict()", "peer"),
        ]
        cs = build(spec, y, log)
        run_interleaved(cs, rounds, log=log)
        log("")
        log(table(cs, ["kfast stream"], "W7 results"))
        results["W7"] = (cs, ["kfast stream"], {})

    # ---------------- W4, W5, W8, MEM (benches/bench_more.py) ----------------
    more = None
    if todo & {"W4", "W5", "W8", "MEM"}:
        import bench_more as more
    if "W4" in todo:
        log(f"\n== W4: filter, random stable model n={more.W4_N}, m={more.W4_M} (rho 0.95) ==")
        results["W4"] = more.run_w4(rounds, quick, log)
    if "W5" in todo:
        log("\n== W5: many series, kfast.filter_batch (CV model) ==")
        results["W5"] = more.run_w5(rounds, quick, log)
    if "W8" in todo:
        log("\n== W8: scaling in n (random stable, m = n/2; then a grid n = 1..12, 16, 32, 64 x m = 1, 2, 3) ==")
        results["W8"] = ("md", more.run_w8(max(3, rounds // 2), quick, log))
        log("\n  -- W8 update forms: n = 4, 16, 64 (x_filt, P_filt) --")
        results["W8"][1]["forms"] = more.run_w8_forms(max(3, rounds // 2), quick, log)
    if "MEM" in todo:
        log("\n== MEM: peak RSS of a W1 run in a fresh interpreter ==")
        results["MEM"] = ("md", more.run_mem(quick, log))
    w6 = None
    if "W6" in todo:
        log("\n== W6: the DARE (benches/bench_riccati.py) ==")
        try:
            import bench_riccati
            w6 = bench_riccati.run(quick)
            log(bench_riccati.table(w6))
        except Exception as e:  # noqa: BLE001
            log(f"W6 failed: {_short_err(e)}")

    elapsed = time.time() - t_start
    try:
        info["load_end"] = "%.2f %.2f %.2f" % os.getloadavg()
    except OSError:
        info["load_end"] = "?"
    log(f"\ntotal wall time {elapsed:.0f} s; load average at start {info['load']}, at end {info['load_end']}")

    if args.json:
        try:
            import json
            dump = {"info": info, "quick": quick, "results": {
                w: [{"name": c.name, "steps": c.steps, "ok": c.ok, "error": c.error,
                     "ns_per_step": c.ns_per_step() if c.ok else None,
                     "iqr": list(c.spread()) if c.ok else None, "samples": len(c.samples)}
                    for c in r[0]] for w, r in results.items() if r[0] != "md"}}
            with open(args.json, "w") as f:
                json.dump(dump, f, indent=1)
            log(f"wrote {args.json}")
        except Exception as e:  # noqa: BLE001
            log(f"--json failed: {_short_err(e)}")

    if args.write:
        if more is not None:
            try:
                more.make_plots(results, log)
            except Exception as e:  # noqa: BLE001
                log(f"plots failed: {_short_err(e)}")
        write_md(info, results, quick, T, T_slow, T_stream_k, T_stream_p, rounds, sm_ss_note, log)
        if w6 is not None:
            try:
                import bench_riccati
                bench_riccati.write_block(w6)
                log("wrote the W6 block of BENCHMARKS.md")
            except Exception as e:  # noqa: BLE001
                log(f"W6 write failed: {_short_err(e)}")
    return 0


BEGIN = "<!-- BEGIN GENERATED RESULTS (benches/bench_filter.py --write) -->"
END = "<!-- END GENERATED RESULTS -->"


def write_md(info, results, quick, T, T_slow, T_sk, T_sp, rounds, sm_ss_note, log):
    path = os.path.join(ROOT, "BENCHMARKS.md")
    lines = [BEGIN, ""]
    lines.append(f"Run: {_dt.date.today().isoformat()}{' (--quick)' if quick else ''}  ")
    lines.append(f"Machine: {info['cpu']}, {info['cores']} cores, {info['platform']}  ")
    lines.append(f"CPU SIMD: {info['simd']}; kfast kernel: {info['kernel']}"
                 + (f"; {info['memory']}" if info.get("memory") else "") + "  ")
    lines.append(f"Load average (1/5/15 min) at start {info['load']}, at end {info['load_end']}  ")
    lines.append(f"Python {info['python']}, NumPy {info['numpy']}, kfast {info['kfast']}, gcc {info['gcc']}  ")
    lines.append("Peers: " + ", ".join(f"{k} {v}" for k, v in info["peers"].items()) + "  ")
    if info.get("c_builds"):
        lines.append("C loop builds: " + "; ".join(info["c_builds"]) + "  ")
    lines.append(f"T = {T:,} (slow peers T = {T_slow:,}; streaming: kfast {T_sk:,}, filterpy {T_sp:,} "
                 f"steps per sample); {rounds} interleaved rounds; medians; "
                 "`X/this` < 1 means X is faster.")
    lines.append("")
    titles = {"W1": "W1: filter (x_filt, P_filt for every step)",
              "W2": "W2: filter + RTS smoother (x_smooth, P_smooth for every step)",
              "W3": "W3: total log-likelihood",
              "W4": "W4: filter, random stable model n = 20, m = 5 (x_filt, P_filt for every step)",
              "W5": "W5: many series, B = 10,000 CV series of T = 500 (ns per series-step; the T column is B × T)",
              "W7": "W7: streaming predict + update from Python",
              "W8": "W8: scaling in n (x_filt, P_filt; random stable model, m = n/2, and a grid for m = 1, 2, 3)",
              "MEM": "Memory: peak RSS of a W1 run"}
    for w in ("W1", "W2", "W3", "W4", "W5", "W7", "W8", "MEM"):
        if w not in results:
            continue
        if results[w][0] == "md":
            import bench_more
            lines.append(f"#### {titles[w]}")
            lines.append("")
            if w == "W8":
                lines.append("GFLOP/s = flop/step ÷ ns/step with flop/step = 4n³ + 4n²m + 4nm² + m³/3 + 2n² + 4nm "
                             "(dense standard-form update and prediction, no symmetry used), for every "
                             "contender and form alike. statsmodels: tuned options, tolerance=0.")
                lines.append("")
                lines.append(bench_more.w8_markdown(results[w][1]["pow2"]))
                lines.append("")
                lines.append("![W8 scaling](benches/plots/w8_scaling.png)")
                lines.append("")
                lines.append("Dense grid, m = 1, 2, 3: kfast's default call (Joseph form, x_filt and P_filt), "
                             "ns/step (median over interleaved samples of all sizes); T = steps per call.")
                lines.append("")
                lines.append(bench_more.w8_grid_markdown(results[w][1]["grid"]))
                if "forms" in results[w][1]:
                    lines.append("")
                    lines.append("Update forms (`form=`; docs/algorithms.md, \"Update forms\"), x_filt and P_filt, "
                                 "same random models (m = n/2):")
                    lines.append("")
                    lines.append(bench_more.w8_forms_markdown(results[w][1]["forms"]))
            else:
                lines.append(bench_more.mem_markdown(results[w][1]))
            lines.append("")
            continue
        cs, knames, chk = results[w]
        lines.append(table(cs, knames, titles[w], md=True))
        if chk:
            lines.append("Cross-check against kfast.filter_batch on the same series:" if w == "W5"
                         else "Cross-check against the C loop (same data, same T):")
            lines.append("")
            for name, v in chk.items():
                if isinstance(v, tuple) and w == "W2":  # noqa: SIM114
                    extra = (f"; lag-one covariances vs statsmodels' smoothed_state_autocov "
                             f"(tolerance=0): max|dP_lag1| = {v[2]:.1e}" if len(v) > 2 else "")
                    lines.append(f"- {name}: max|dx_smooth| = {v[0]:.1e}, max|dP_smooth| = {v[1]:.1e}{extra}")
                elif isinstance(v, tuple):
                    lines.append(f"- {name}: max|dx_filt| = {v[0]:.1e}, max|dP_filt| = {v[1]:.1e}")
                else:
                    lines.append(f"- {name}: |loglik - C| = {v:.1e}")
            lines.append("")
    if any(w in results for w in ("W1", "W2", "W3", "W4", "W5")):
        lines.append("![W1-W5: kfast vs the C loop vs the fastest peer](benches/plots/w1_w5_bars.png)")
        lines.append("")
    lines.append(END)
    block = "\n".join(lines)
    try:
        with open(path) as f:
            old = f.read()
    except FileNotFoundError:
        old = "# Benchmarks\n\n"
    if BEGIN in old and END in old:
        new = old[: old.index(BEGIN)] + block + old[old.index(END) + len(END):]
    else:
        new = old.rstrip("\n") + "\n\n" + block + "\n"
    with open(path, "w") as f:
        f.write(new)
    log(f"wrote results into {path}")


if __name__ == "__main__":
    try:
        sys.exit(main())
    except SystemExit:
        raise
    except BaseException:  # noqa: BLE001  -- a benchmark never fails; it prints
        traceback.print_exc()
        sys.exit(0)
