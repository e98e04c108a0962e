"""W4 (n = 20 filter), W5 (many series), W8 (scaling in n, and a dense small-n grid), MEM
(peak RSS) and the plots.

Driven from bench_filter.py (``--only W4,W5,W8,MEM``; ``--write`` puts them in
BENCHMARKS.md and draws benches/plots/*.png).  Uses bench_filter's timing
machinery (interleaved rounds, medians, GC off during a timed call) and its C
loop (benches/c/kf_cv.c, recompiled for each (N, M)).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

import numpy as np

_main = sys.modules.get("__main__")
if _main is not None and os.path.basename(getattr(_main, "__file__", "") or "") == "bench_filter.py":
    bf = _main
else:  # pragma: no cover - imported on its own
    import bench_filter as bf  # noqa: E402

Unavailable, _import, _short_err = bf.Unavailable, bf._import, bf._short_err

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
PLOTS = os.path.join(HERE, "plots")


# --------------------------------------------------------------------------
# Models
# --------------------------------------------------------------------------
def random_model(n, m, seed=None, rho=0.95):
    """Seeded random stable model: F scaled to spectral radius rho, H Gaussian,
    Q = C C'/n + 0.1 I, R = I; prior x0 = 0, P0 = I."""
    rng = np.random.default_rng(1000 + n if seed is None else seed)
    F = rng.standard_normal((n, n))
    F *= rho / max(abs(np.linalg.eigvals(F)))
    H = rng.standard_normal((m, n))
    C = rng.standard_normal((n, n))
    Q = C @ C.T / n + 0.1 * np.eye(n)
    R = np.eye(m)
    return F, H, Q, R, np.zeros(n), np.eye(n)


def simulate_model(F, H, Q, R, T, seed=bf.SEED):
    n, m = F.shape[0], H.shape[0]
    rng = np.random.default_rng(seed)
    w = rng.standard_normal((T, n)) @ np.linalg.cholesky(Q).T
    v = rng.standard_normal((T, m)) @ np.linalg.cholesky(R).T
    x = rng.standard_normal(n)
    y = np.empty((T, m))
    for t in range(T):
        y[t] = H @ x + v[t]
        x = F @ x + w[t]
    return np.ascontiguousarray(y)


def flops_per_step(n, m):
    """Flop count used for GFLOP/s (dense, standard form, no symmetry used):
    FPF' 4n^3, PH' 2n^2m, H(PH') 2nm^2, Cholesky of S m^3/3, K = PH'S^-1 2nm^2,
    P - K(PH')' 2n^2m, plus the O(n^2) mean updates (Fx 2n^2, Hx and Kv 4nm)."""
    return 4 * n**3 + 4 * n * n * m + 4 * n * m * m + m**3 / 3 + 2 * n * n + 4 * n * m


# --------------------------------------------------------------------------
# Generic contender factories (any model)
# --------------------------------------------------------------------------
def mk_kfast(model, y, **kw):
    kf = bf.kfast_module()
    F, H, Q, R, x0, P0 = model
    m = kf.LinearGaussian(F, H, Q, R)
    if kw.get("steady_state"):
        return lambda: m.filter(y, x0, None, **kw)
    return lambda: m.filter(y, x0, P0, **kw)


def cloop_for(n, m, flags=None):
    """The C loop for (N, M) = (n, m); bench_filter's cache, so every (n, m, flags) builds once."""
    return bf.c_loop(flags or bf.C_REF, n, m)


def mk_c(model, y):
    F, H, Q, R, x0, P0 = model
    c = cloop_for(F.shape[0], H.shape[0])
    args = c.prepare(F, H, Q, R, y, x0, P0)
    return lambda: c.filter_prepared(args)


def _sm_generic(model, y, **kw):
    kfm = _import("statsmodels.tsa.statespace.kalman_filter")
    F, H, Q, R, x0, P0 = model
    n, m = F.shape[0], H.shape[0]
    kf = kfm.KalmanFilter(k_endog=m, k_states=n, k_posdef=n, **kw)
    kf.bind(y.copy())
    kf["design"] = H
    kf["obs_cov"] = R
    kf["transition"] = F
    kf["selection"] = np.eye(n)
    kf["state_cov"] = Q
    kf.initialize_known(x0, P0)
    return kfm, kf


def mk_sm_tuned(model, y, steady_state=True):
    kfm = _import("statsmodels.tsa.statespace.kalman_filter")
    kw = dict(filter_method=kfm.FILTER_UNIVARIATE, stability_method=0)
    if not steady_state:
        kw["tolerance"] = 0.0  # constructor only: see the pitfall in bench_filter._sm_kf
    kfm, kf = _sm_generic(model, y, **kw)
    mem = bf._sm_filter_memory(kfm)

    def run():
        k = kf._filter(conserve_memory=mem)
        return np.asarray(k.filtered_state).T, np.asarray(k.filtered_state_cov).transpose(2, 0, 1)

    return run


def mk_sm_default(model, y):
    _, kf = _sm_generic(model, y)

    def run():
        r = kf.filter()
        return np.asarray(r.filtered_state).T, np.asarray(r.filtered_state_cov).transpose(2, 0, 1)

    return run


def sm_converged(model, y, **kw):
    try:
        kfm, kf = _sm_generic(model, y, **kw)
        k = kf._filter(conserve_memory=kfm.MEMORY_CONSERVE)
        return (int(k.period_converged) if bool(k.converged) else None), True
    except Exception:  # noqa: BLE001
        return None, False


def mk_fp(model, y):
    fpk = _import("filterpy.kalman")
    F, H, Q, R, x0, P0 = model
    kf = fpk.KalmanFilter(dim_x=F.shape[0], dim_z=H.shape[0])
    kf.F, kf.H, kf.Q, kf.R = F.copy(), H.copy(), Q.copy(), R.copy()

    def run():
        kf.x, kf.P = x0.copy(), P0.copy()
        means, covs, _, _ = kf.batch_filter(y, update_first=True)
        return means, covs

    return run


def mk_pk(model, y):
    pk = _import("pykalman")
    F, H, Q, R, x0, P0 = model
    kf = pk.KalmanFilter(transition_matrices=F, observation_matrices=H, transition_covariance=Q,
                         observation_covariance=R, initial_state_mean=x0, initial_state_covariance=P0)
    return lambda: kf.filter(y)


def _sk(model):
    sk = _import("simdkalman")
    F, H, Q, R, x0, P0 = model
    return sk.KalmanFilter(state_transition=F, process_noise=Q, observation_model=H, observation_noise=R)


def mk_sk(model, y):
    kf = _sk(model)
    x0, P0 = model[4], model[5]
    data = y[None]

    def run():
        r = kf.compute(data, 0, initial_value=x0, initial_covariance=P0,
                       smoothed=False, filtered=True, observations=False)
        return r.filtered.states.mean[0], r.filtered.states.cov[0]

    return run


def _dx_params(model):
    jax = _import("jax")
    jax.config.update("jax_enable_x64", True)
    inf = _import("dynamax.linear_gaussian_ssm.inference")
    jnp = _import("jax.numpy")
    F, H, Q, R, x0, P0 = model
    n, m = F.shape[0], H.shape[0]
    params = inf.ParamsLGSSM(
        initial=inf.ParamsLGSSMInitial(mean=jnp.asarray(x0), cov=jnp.asarray(P0)),
        dynamics=inf.ParamsLGSSMDynamics(weights=jnp.asarray(F), bias=jnp.zeros(n),
                                          input_weights=jnp.zeros((n, 0)), cov=jnp.asarray(Q)),
        emissions=inf.ParamsLGSSMEmissions(weights=jnp.asarray(H), bias=jnp.zeros(m),
                                            input_weights=jnp.zeros((m, 0)), cov=jnp.asarray(R)),
    )
    return jax, jnp, inf, params


def mk_dx(model, y):
    jax, jnp, inf, params = _dx_params(model)
    f = jax.jit(lambda p, e: (lambda r: (r.filtered_means, r.filtered_covariances))(inf.lgssm_filter(p, e)))
    e = jax.device_put(jnp.asarray(y))
    f(params, e)  # compile outside the timing
    return lambda: jax.block_until_ready(f(params, e))


def _as_filter_out(out):
    if hasattr(out, "x_filt"):
        return np.asarray(out.x_filt), np.asarray(out.P_filt)
    return np.asarray(out[0]), np.asarray(out[1])


def _frozen_at(P):
    """First t from which P_filt stays bit-for-bit constant (None if never)."""
    d = np.any(P[1:] != P[:-1], axis=(1, 2))
    idx = np.nonzero(d)[0]
    if len(idx) == 0:
        return 0
    t = int(idx[-1]) + 1
    return t if t < len(P) - 1 else None


def check_vs_c(cs, model, y, log):
    F, H, Q, R, x0, P0 = model
    try:
        c = cloop_for(F.shape[0], H.shape[0])
    except Unavailable as e:
        log(f"  (no cross-check: {e})")
        return {}
    res, refs = {}, {}
    for k in cs:
        if not k.ok or k.group == "c":  # the reference itself
            continue
        T = k.steps
        if T not in refs:
            refs[T] = c.filter(F, H, Q, R, y[:T], x0, P0)
        xr, Pr, _ = refs[T]
        try:
            xf, Pf = _as_filter_out(k.fn())
            dx, dP = float(np.max(np.abs(xf - xr))), float(np.max(np.abs(Pf - Pr)))
            res[k.name] = (dx, dP)
            log(f"  {k.name:<36s} max|dx_filt| = {dx:.2e}   max|dP_filt| = {dP:.2e}   (T={T})")
        except Exception as e:  # noqa: BLE001
            log(f"  {k.name:<36s} check failed: {_short_err(e)}")
    return res


# --------------------------------------------------------------------------
# W4: n = 20, m = 5
# --------------------------------------------------------------------------
W4_N, W4_M = 20, 5


def run_w4(rounds, quick, log):
    T = 2_000 if quick else 10_000
    T_slow = 200 if quick else 1_000
    model = random_model(W4_N, W4_M, seed=4)
    y = simulate_model(*model[:4], T)
    sm_per, kfm_ok = sm_converged(model, y)
    sm_note = ("steady-state shortcut ON (default), converged at t=%d" % sm_per if sm_per is not None
               else "steady-state shortcut ON (default) but never triggered") if kfm_ok else ""
    # where kfast's converge_tol freezes the gains
    kf_note = "converge_tol=1e-9 (freezes the gains like statsmodels' shortcut)"
    try:
        F, H, Q, R, x0, P0 = model
        r = bf.kfast_module().LinearGaussian(F, H, Q, R).filter(y, x0, P0, converge_tol=1e-9,
                                                                 outputs=("P_filt",))
        t = _frozen_at(np.asarray(r.P_filt))
        kf_note += f"; gains frozen from t={t}" if t is not None else "; never froze"
    except Exception:  # noqa: BLE001
        pass
    outs = ("x_filt", "P_filt")
    slow = f"T={T_slow:,} (slow peer)"
    spec = [
        ("kfast exact", lambda yy: mk_kfast(model, yy, outputs=outs), T,
         'filter(outputs=("x_filt","P_filt")), default form (joseph), full recursion', "kfast"),
        ("kfast exact standard", lambda yy: mk_kfast(model, yy, outputs=outs, form="standard"), T,
         'as above, form="standard"', "kfast"),
        ("kfast converge_tol", lambda yy: mk_kfast(model, yy, outputs=outs, converge_tol=1e-9), T,
         kf_note, "kfast"),
        ("kfast steady_state", lambda yy: mk_kfast(model, yy, outputs=outs, steady_state=True), T,
         "steady_state=True: stationary gains from t=0 (differs from the exact filter early on by design)",
         "kfast"),
        (bf.c_name(), lambda yy: mk_c(model, yy), T, f"kf_cv.c with N={W4_N}, M={W4_M}, Cholesky path", "c"),
        ("statsmodels tuned", lambda yy: mk_sm_tuned(model, yy), T,
         "univariate, no symmetrisation, _filter(), conserve_memory; " + sm_note, "peer"),
        ("statsmodels tuned, no steady", lambda yy: mk_sm_tuned(model, yy, False), T,
         "as tuned, tolerance=0 (full recursion)", "peer"),
        ("statsmodels default", lambda yy: mk_sm_default(model, yy), T, "KalmanFilter.filter(); " + sm_note, "peer"),
        ("dynamax", lambda yy: mk_dx(model, yy), T, "jax.jit(lgssm_filter), CPU, x64", "peer"),
        ("simdkalman", lambda yy: mk_sk(model, yy), T_slow, slow + "; one series", "peer"),
        ("filterpy", lambda yy: mk_fp(model, yy), T_slow, slow + "; batch_filter(update_first=True)", "peer"),
        ("pykalman", lambda yy: mk_pk(model, yy), T_slow, slow, "peer"),
    ]
    cs = bf.build(spec, y, log)
    bf.run_interleaved(cs, rounds, log=log)
    log("")
    knames = ["kfast exact", "kfast converge_tol"]
    log(bf.table(cs, knames, "W4 results"))
    log("cross-check vs C loop (same T):")
    chk = check_vs_c(cs, model, y, log)
    return (cs, knames, chk)


# --------------------------------------------------------------------------
# W5: many series (CV model)
# --------------------------------------------------------------------------
def simulate_batch(B, T, seed=bf.SEED + 5):
    F, H, Q, R, x0, P0 = bf.cv_model()
    rng = np.random.default_rng(seed)
    LQ, LP = np.linalg.cholesky(Q), np.linalg.cholesky(P0)
    x = x0 + rng.standard_normal((B, 4)) @ LP.T
    Y = np.empty((B, T, 2))
    for t in range(T):
        Y[:, t] = x @ H.T + rng.standard_normal((B, 2))
        x = x @ F.T + rng.standard_normal((B, 4)) @ LQ.T
    return Y


def np_batch_filter(F, H, Q, R, Y, x0, P0):
    """NumPy reference batched filter, vectorised over series: every series
    carries its own covariance (B, n, n), standard form, same recursion."""
    B, T, m = Y.shape
    n = F.shape[0]
    x = np.broadcast_to(x0, (B, n)).copy()
    P = np.broadcast_to(P0, (B, n, n)).copy()
    xs = np.empty((B, T, n))
    Ps = np.empty((B, T, n, n))
    for t in range(T):
        v = Y[:, t] - x @ H.T                                   # (B, m)
        PHt = np.einsum("bij,kj->bik", P, H)                    # (B, n, m)
        S = np.einsum("ki,bim->bkm", H, PHt) + R                # (B, m, m)
        K = np.linalg.solve(S, PHt.transpose(0, 2, 1)).transpose(0, 2, 1)  # PH' S^-1 (S symmetric)
        xf = x + np.einsum("bim,bm->bi", K, v)
        Pf = P - np.einsum("bim,bjm->bij", K, PHt)
        Pf = 0.5 * (Pf + Pf.transpose(0, 2, 1))
        xs[:, t] = xf
        Ps[:, t] = Pf
        x = xf @ F.T
        P = np.einsum("ij,bjk,lk->bil", F, Pf, F) + Q
    return xs, Ps


def np_batch_filter_shared(F, H, Q, R, Y, x0, P0):
    """NumPy batched filter using the same shortcut as kfast.filter_batch: with a
    shared prior covariance and no missing values, P and K do not depend on the
    data, so they are computed once (T small n x n steps) and each step only
    moves the (B, n) means with two matrix products."""
    B, T, m = Y.shape
    n = F.shape[0]
    P = P0.copy()
    Ks = np.empty((T, n, m))
    Ps = np.empty((T, n, n))
    for t in range(T):
        PHt = P @ H.T
        S = H @ PHt + R
        K = np.linalg.solve(S, PHt.T).T
        Pf = P - K @ PHt.T
        Pf = 0.5 * (Pf + Pf.T)
        Ks[t], Ps[t] = K, Pf
        P = F @ Pf @ F.T + Q
    x = np.broadcast_to(x0, (B, n)).copy()
    xs = np.empty((B, T, n))
    Ht, Ft = H.T, F.T
    for t in range(T):
        xf = x + (Y[:, t] - x @ Ht) @ Ks[t].T
        xs[:, t] = xf
        x = xf @ Ft
    return xs, np.broadcast_to(Ps, (B, T, n, n))


def run_w5(rounds, quick, log):
    B, T = (2_000, 200) if quick else (10_000, 500)
    Bp = 400 if quick else 2_000  # peers that store a per-series covariance (B, T, 4, 4)
    F, H, Q, R, x0, P0 = bf.cv_model()
    Y = simulate_batch(B, T)
    Yp = np.ascontiguousarray(Y[:Bp])
    ncores = os.cpu_count()
    spec = []

    def kf_batch(threads):
        def mk(_):
            kf = bf.kfast_module()
            m = kf.LinearGaussian(F, H, Q, R)
            return lambda: kf.filter_batch(m, Y, x0, P0, return_covs=True, threads=threads)
        return mk

    spec.append(("kfast batch", kf_batch(None), B * T,
                 f"filter_batch(return_covs=True), all {ncores} cores; B={B:,}, T={T}", "kfast"))
    spec.append(("kfast batch threads=1", kf_batch(1), B * T, f"threads=1; B={B:,}, T={T}", "kfast"))

    def mk_c_batch(fresh):
        def mk(_):
            c = cloop_for(4, 2)
            import ctypes
            dp = ctypes.POINTER(ctypes.c_double)
            args = c.prepare(F, H, Q, R, Y[0], x0, P0)
            Fp, Hp, Qp, Rp, _, x0p, P0p = [a.ctypes.data_as(dp) for a in args]
            keep = args
            Yc = np.ascontiguousarray(Y)
            ys = [ctypes.cast(Yc.ctypes.data + b * T * 2 * 8, dp) for b in range(B)]
            fn = c.lib.kf_cv_filter

            def run_fresh():
                # kfast's outputs: x per series, one (T, 4, 4) P (every series writes the
                # same covariances into it), allocated by the call
                _ = keep
                xs = np.empty((B, T, 4))
                Ps = np.empty((T, 4, 4))
                pp = Ps.ctypes.data_as(dp)
                for b, yp in enumerate(ys):
                    fn(Fp, Hp, Qp, Rp, yp, T, x0p, P0p, ctypes.cast(xs.ctypes.data + b * T * 4 * 8, dp), pp)
                return xs, np.broadcast_to(Ps, (B, T, 4, 4))

            xs = np.empty((B, T, 4))
            Ps = np.empty((B, T, 4, 4))
            ptrs = [(yp, ctypes.cast(xs.ctypes.data + b * T * 4 * 8, dp),
                     ctypes.cast(Ps.ctypes.data + b * T * 16 * 8, dp)) for b, yp in enumerate(ys)]

            def run_preallocated():
                _ = keep
                for yp, xp, pp in ptrs:
                    fn(Fp, Hp, Qp, Rp, yp, T, x0p, P0p, xp, pp)
                return xs, Ps

            return run_fresh if fresh else run_preallocated
        return mk

    spec.append((bf.c_name() + ", per series", mk_c_batch(True), B * T,
                 "kf_cv_filter called once per series (ctypes), one core, P recomputed per series; "
                 "kfast's outputs ((B, T, 4) means and one (T, 4, 4) P), allocated per call", "c"))
    spec.append((bf.c_name() + ", per series, preallocated", mk_c_batch(False), B * T,
                 "the same, into preallocated (B, T, 4) and (B, T, 4, 4) outputs (own P per series)", "c"))

    def mk_np(shared):
        fn = np_batch_filter_shared if shared else np_batch_filter
        data = Y if shared else Yp
        return lambda _: (lambda: fn(F, H, Q, R, data, x0, P0))

    spec.append(("numpy batched, shared P", mk_np(True), B * T,
                 f"this bench's NumPy filter, P and K computed once (as kfast does); B={B:,}", "peer"))
    spec.append(("numpy batched", mk_np(False), Bp * T,
                 f"this bench's NumPy filter, einsum over series, own P per series; B={Bp:,}", "peer"))

    def mk_skb(_):
        kf = _sk(bf.cv_model())

        def run():
            r = kf.compute(Yp, 0, initial_value=x0, initial_covariance=P0,
                           smoothed=False, filtered=True, observations=False)
            return r.filtered.states.mean, r.filtered.states.cov

        return run

    spec.append(("simdkalman", mk_skb, Bp * T, f"compute(filtered=True) on all series at once; B={Bp:,}", "peer"))

    def mk_dxb(_):
        model = bf.cv_model()
        jax, jnp, inf, params = _dx_params(model)
        f = jax.jit(jax.vmap(lambda e: (lambda r: (r.filtered_means, r.filtered_covariances))(
            inf.lgssm_filter(params, e))))
        e = jax.device_put(jnp.asarray(Yp))
        f(e)
        return lambda: jax.block_until_ready(f(e))

    spec.append(("dynamax vmap", mk_dxb, Bp * T, f"jax.jit(jax.vmap(lgssm_filter)), CPU, x64; B={Bp:,}", "peer"))

    cs = [bf.contender(name, lambda f=factory: f(None), steps, note, group, log)
          for name, factory, steps, note, group in spec]
    bf.run_interleaved(cs, rounds, log=log)
    log("")
    knames = ["kfast batch", "kfast batch threads=1"]
    log(bf.table(cs, knames, "W5 results (ns per series-step; the T column is B x T)"))
    # cross-check: every contender against kfast's per-series results
    chk = {}
    ref = next((c for c in cs if c.name == "kfast batch" and c.ok), None)
    if ref is not None:
        r = ref.fn()
        xr, Pr = np.asarray(r.x_filt), np.asarray(r.P_filt)
        kf = bf.kfast_module()
        one = kf.LinearGaussian(F, H, Q, R).filter(Y[7], x0, P0)
        d1 = float(np.max(np.abs(one.x_filt - xr[7])))
        log(f"  kfast batch vs model.filter on series 7: max|dx| = {d1:.1e}")
        for c in cs:
            if not c.ok or c is ref:
                continue
            try:
                out = c.fn()
                if hasattr(out, "x_filt"):
                    xs, Ps = out.x_filt, out.P_filt
                else:
                    xs, Ps = out
                xs, Ps = np.asarray(xs), np.asarray(Ps)
                b = xs.shape[0]
                dx = float(np.max(np.abs(xs - xr[:b])))
                dP = float(np.max(np.abs(Ps - Pr[:b])))
                chk[c.name] = (dx, dP)
                log(f"  {c.name:<36s} max|dx_filt| = {dx:.2e}   max|dP_filt| = {dP:.2e}   (B={b:,})")
            except Exception as e:  # noqa: BLE001
                log(f"  {c.name:<36s} check failed: {_short_err(e)}")
    return (cs, knames, chk)


# --------------------------------------------------------------------------
# W8: scaling in n
# --------------------------------------------------------------------------
W8_NS = (2, 4, 8, 16, 32, 64, 128)


def w8_T(n, quick):
    T = 10_000 if n <= 8 else int(round(10_000 / (n / 8) ** 2))
    return max(20, T // 4) if quick else T


W8_C = bf.c_name()  # the reference C build's row label
W8_COLS = ("kfast", "kfast standard", W8_C, "statsmodels tuned, no steady")

# The dense grid: every small n (where fixed-size kernels and their dispatch
# matter most) for m = 1, 2, 3, plus three larger n for the trend.
W8_GRID_NS = tuple(range(1, 13)) + (16, 32, 64)
W8_GRID_MS = (1, 2, 3)
W8_MONO_MAX_N = 12   # the monotonicity check covers n <= this
W8_MONO_DROP = 0.10  # flag n when ns/step falls more than this below n - 1


def run_w8(rounds, quick, log):
    """Powers of two with m = n/2 (the rows compared with earlier runs), then the dense grid."""
    rows = run_w8_pow2(rounds, quick, log)
    log("\n  -- W8 grid: kfast default call (joseph; x_filt, P_filt), random stable models --")
    grid = run_w8_grid(rounds if quick else 2 * rounds, quick, log)
    return {"pow2": rows, "grid": grid}


def run_w8_pow2(rounds, quick, log):
    rows = []
    outs = ("x_filt", "P_filt")
    for n in W8_NS:
        m = max(1, n // 2)
        T = w8_T(n, quick)
        model = random_model(n, m)
        y = simulate_model(*model[:4], T)
        spec = [
            ("kfast", lambda yy: mk_kfast(model, yy, outputs=outs), T, "default form (joseph)", "kfast"),
            ("kfast standard", lambda yy: mk_kfast(model, yy, outputs=outs, form="standard"), T, "", "kfast"),
            (W8_C, lambda yy: mk_c(model, yy), T, "", "c"),
            ("statsmodels tuned, no steady", lambda yy: mk_sm_tuned(model, yy, False), T, "", "peer"),
        ]
        cs = bf.build(spec, y, lambda s: log(f"  n={n}: {s.strip()}"))
        bf.run_interleaved(cs, rounds, log=log)
        chk = check_vs_c([c for c in cs], model, y, lambda s: None)
        fl = flops_per_step(n, m)
        row = {"n": n, "m": m, "T": T, "flops": fl}
        for c in cs:
            if c.ok:
                ns = c.ns_per_step()
                row[c.name] = {"ns": ns, "gflops": fl / ns, "iqr": c.spread(),
                               "dx": chk.get(c.name, (None, None))[0], "dP": chk.get(c.name, (None, None))[1]}
            else:
                row[c.name] = {"error": c.error}
        rows.append(row)
        log(f"  n={n:3d} m={m:2d} T={T:6,d}  " + "  ".join(
            f"{k}: {row[k]['ns']:,.0f} ns ({row[k]['gflops']:.2f} GF/s)" if "ns" in row[k] else f"{k}: {row[k]['error']}"
            for k in W8_COLS))
    return rows


def w8_grid_T(n, quick):
    """Steps per call in the grid, from n alone (one T per column): 5 ms at an
    assumed 30 ns + flop/4 ns per step (pessimistic: real calls are shorter),
    between 200 and 20,000 steps (the data are simulated by a Python loop),
    rounded to 2 digits; --quick: a quarter.  Calls stay well under the 40 ms a
    round gives each contender, so every size gets many samples per round."""
    est_ns = 30 + flops_per_step(n, 2) / 4
    T = int(min(20_000, max(200, 5e6 / est_ns)))
    T = int(float(f"{T:.2g}"))
    return max(50, T // 4) if quick else T


def run_w8_grid(rounds, quick, log):
    """kfast's default call on every (n, m) of the grid, all sizes interleaved in
    one round-robin, so load drifts hit every size alike (the monotonicity check
    compares neighbours).  Returns {"T": {n: T}, "ns": {(m, n): ns/step},
    "iqr": {(m, n): (q25, q75)}, "err": {(m, n): message}}."""
    outs = ("x_filt", "P_filt")
    keys = [(m, n) for m in W8_GRID_MS for n in W8_GRID_NS if n >= m]
    cs = []
    for m, n in keys:
        T = w8_grid_T(n, quick)
        model = random_model(n, m)
        make = lambda model=model, T=T: mk_kfast(model, simulate_model(*model[:4], T), outputs=outs)  # noqa: E731
        cs.append(bf.contender(f"kfast n={n} m={m}", make, T, "default form (joseph)", "kfast", log))
    bf.run_interleaved(cs, rounds, target_s=0.01 if quick else 0.04, log=log)
    grid = {"T": {n: w8_grid_T(n, quick) for n in W8_GRID_NS}, "ns": {}, "iqr": {}, "err": {}}
    for key, c in zip(keys, cs):
        if c.ok:
            grid["ns"][key], grid["iqr"][key] = c.ns_per_step(), c.spread()
        else:
            grid["err"][key] = c.error or "no samples"
    log(w8_grid_text(grid))
    return grid


def w8_drops(grid):
    """(m, n, change) for every n <= W8_MONO_MAX_N whose ns/step is more than
    W8_MONO_DROP below that at n - 1: a bigger problem should never be cheaper,
    so a drop means size n - 1 takes a slower path than it should."""
    ns = grid["ns"]
    out = []
    for m in W8_GRID_MS:
        for n in range(m + 1, W8_MONO_MAX_N + 1):
            a, b = ns.get((m, n - 1)), ns.get((m, n))
            if a and b and b < (1 - W8_MONO_DROP) * a:
                out.append((m, n, b / a - 1))
    return out


def w8_mono_line(grid):
    drops = w8_drops(grid)
    if not drops:
        return f"monotone in n for n <= {W8_MONO_MAX_N}"
    return (f"NOT monotone in n for n <= {W8_MONO_MAX_N} (ns/step more than {W8_MONO_DROP:.0%} below n-1): "
            + "; ".join(f"m={m}: n={n} ({d:+.0%} vs n={n - 1})" for m, n, d in drops))


def _grid_cells(grid):
    """Header and rows (T first, then one per m) of the grid table, as strings."""
    head = ["m \\ n"] + [str(n) for n in W8_GRID_NS]
    rows = [["T"] + [f"{grid['T'][n]:,}" for n in W8_GRID_NS]]
    for m in W8_GRID_MS:
        cells = [str(m)]
        for n in W8_GRID_NS:
            if n < m:
                cells.append("")
            elif (m, n) in grid["ns"]:
                cells.append(bf.fmt_ns(grid["ns"][(m, n)]))
            else:
                cells.append("err")
        rows.append(cells)
    return head, rows


def w8_grid_text(grid):
    head, rows = _grid_cells(grid)
    w = [max(len(head[i]), *(len(r[i]) for r in rows)) for i in range(len(head))]
    out = ["  ns/step (median), rows m, columns n:"]
    out += ["  " + "  ".join(s.rjust(w[i]) for i, s in enumerate(r)) for r in [head] + rows]
    out += [f"  {m=} {n=}: {e}" for (m, n), e in grid["err"].items()]
    out.append("  " + w8_mono_line(grid))
    return "\n".join(out)


def w8_grid_markdown(grid):
    head, rows = _grid_cells(grid)
    out = ["| " + " | ".join(head) + " |", "|" + "---:|" * len(head)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    out += ["", w8_mono_line(grid) + "."]
    out += [f"- m = {m}, n = {n}: {e}" for (m, n), e in grid["err"].items()]
    return "\n".join(out)




W8_FORM_NS = (4, 16, 64)
W8_FORMS = ("joseph", "standard", "sqrt", "ud", "information", "sequential")


def run_w8_forms(rounds, quick, log):
    """Each update form at n = 4, 16, 64 (m = n/2; x_filt, P_filt), with the C loop."""
    rows = []
    outs = ("x_filt", "P_filt")
    for n in W8_FORM_NS:
        m = n // 2
        T = w8_T(n, quick)
        model = random_model(n, m)
        y = simulate_model(*model[:4], T)
        spec = [(f"kfast {f}", lambda yy, f=f: mk_kfast(model, yy, outputs=outs, form=f), T, "", "kfast")
                for f in W8_FORMS]
        spec.append((W8_C, lambda yy: mk_c(model, yy), T, "", "c"))
        cs = bf.build(spec, y, lambda s: log(f"  n={n}: {s.strip()}"))
        bf.run_interleaved(cs, rounds, log=log)
        chk = check_vs_c(cs, model, y, lambda s: None)
        row = {"n": n, "m": m, "T": T}
        for c in cs:
            row[c.name] = {"ns": c.ns_per_step(), "dP": chk.get(c.name, (None, None))[1]} if c.ok else {"error": c.error}
        rows.append(row)
        log(f"  n={n:3d} m={m:2d} T={T:6,d}  " + "  ".join(
            f"{c.name}: {row[c.name]['ns']:,.0f} ns" if "ns" in row[c.name] else f"{c.name}: {row[c.name]['error']}"
            for c in cs))
    return rows


def w8_forms_markdown(rows):
    cols = [f"kfast {f}" for f in W8_FORMS] + [W8_C]
    out = ["| n | m | T | " + " | ".join(f"{c} ns/step" for c in cols) + " | max\\|dP\\| of each form vs C |",
           "|" + "---:|" * (3 + len(cols) + 1)]
    for r in rows:
        cells = [str(r["n"]), str(r["m"]), f"{r['T']:,}"]
        cells += [bf.fmt_ns(r[c]["ns"]) if "ns" in r[c] else (r[c].get("error") or "-") for c in cols]
        dps = [r[c]["dP"] for c in cols[:-1] if "ns" in r[c] and r[c].get("dP") is not None]
        cells.append(f"{max(dps):.1e}" if dps else "n/a")
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


def w8_markdown(rows):
    head = ("| n | m | T | flop/step | " + " | ".join(f"{c} ns/step (GFLOP/s)" for c in W8_COLS)
            + " | statsmodels / kfast | max\\|dP\\| kfast vs C |")
    out = [head, "|" + "---:|" * (4 + len(W8_COLS) + 2)]
    for r in rows:
        cells = [str(r["n"]), str(r["m"]), f"{r['T']:,}", f"{r['flops']:,.0f}"]
        for c in W8_COLS:
            d = r[c]
            cells.append(f"{bf.fmt_ns(d['ns'])} ({d['gflops']:.2f})" if "ns" in d else (d.get("error") or "-"))
        k, s = r["kfast"], r["statsmodels tuned, no steady"]
        cells.append(f"{s['ns'] / k['ns']:.2f}" if "ns" in k and "ns" in s else "n/a")
        cells.append(f"{k['dP']:.1e}" if "ns" in k and k.get("dP") is not None else "n/a")
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


# --------------------------------------------------------------------------
# MEM: peak RSS of a W1 run in a fresh interpreter
# --------------------------------------------------------------------------
_MEM_CHILD = r"""
import json, resource, sys
import numpy as np
import kfast
d = np.load(sys.argv[1])
y = np.ascontiguousarray(d["y"])
F, H, Q, R, x0, P0 = (d[k] for k in ("F", "H", "Q", "R", "x0", "P0"))
m = kfast.LinearGaussian(F, H, Q, R)
def hwm():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM"):
            return int(line.split()[1]) * 1024
    return -1
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
base_hwm = hwm()
outputs = json.loads(sys.argv[2])
r = m.filter(y, x0, P0, outputs=tuple(outputs)) if outputs else m.filter(y, x0, P0)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
peak_hwm = hwm()
nbytes = sum(getattr(r, f).nbytes for f in ("x_pred", "P_pred", "x_filt", "P_filt", "innov", "S", "K",
                                               "K_pred", "loglik_t") if isinstance(getattr(r, f, None), np.ndarray))
print(json.dumps({"base": base, "peak": peak, "out": nbytes, "base_hwm": base_hwm, "peak_hwm": peak_hwm}))
"""


def run_mem(quick, log):
    T = 20_000 if quick else 100_000
    y = bf.simulate(T)
    F, H, Q, R, x0, P0 = bf.cv_model()
    res = {"T": T}
    with tempfile.TemporaryDirectory() as td:
        p = os.path.join(td, "w1.npz")
        np.savez(p, y=y, F=F, H=H, Q=Q, R=R, x0=x0, P0=P0)
        for label, outs in (("x_filt, P_filt", ["x_filt", "P_filt"]), ("all outputs (default)", None)):
            samples = []
            for _ in range(3):
                try:
                    # Through sh, which forks the interpreter: Linux keeps ru_maxrss across
                    # execve, so a child exec'd straight from this (large) process would
                    # report this process's peak.  sh's own fork starts from sh's small RSS.
                    pr = subprocess.run(["/bin/sh", "-c", '"$@"; status=$?; exit $status', "sh",
                                         sys.executable, "-c", _MEM_CHILD, p, json.dumps(outs)],
                                        capture_output=True, text=True, timeout=120, env=os.environ.copy())
                    samples.append(json.loads(pr.stdout.strip().splitlines()[-1]))
                except Exception as e:  # noqa: BLE001
                    res[label] = {"error": _short_err(e) + " " + (pr.stderr[-200:] if "pr" in dir() else "")}
                    break
            if samples:
                s = sorted(samples, key=lambda d: d["peak"] - d["base"])[len(samples) // 2]
                res[label] = s
                over = s["peak"] - s["base"]
                log(f"  MEM {label}: baseline {s['base'] / 1e6:.1f} MB, peak {s['peak'] / 1e6:.1f} MB, "
                    f"outputs {s['out'] / 1e6:.1f} MB, peak - baseline = {over / 1e6:.1f} MB "
                    f"= {over / s['out']:.3f} x outputs (VmHWM: {s['base_hwm'] / 1e6:.1f} -> "
                    f"{s['peak_hwm'] / 1e6:.1f} MB)")
    return res


def mem_markdown(res):
    T = res["T"]
    out = [f"Fresh interpreter per measurement (median of 3), CV model, T = {T:,}. Baseline = "
           "`ru_maxrss` after importing numpy and kfast, loading y and building the model; peak = "
           "`ru_maxrss` after the call. Target: peak ≤ baseline + 1.10 × outputs.", "",
           "| outputs | baseline MB | peak MB | outputs MB | peak − baseline MB | (peak − baseline) / outputs "
           "| target met |",
           "|---|---:|---:|---:|---:|---:|---|"]
    for label in ("x_filt, P_filt", "all outputs (default)"):
        s = res.get(label)
        if not s or "error" in s:
            out.append(f"| {label} | {(s or {}).get('error', 'not run')} | | | | | |")
            continue
        over = s["peak"] - s["base"]
        ok = s["peak"] <= s["base"] + 1.10 * s["out"]
        out.append(f"| {label} | {s['base'] / 1e6:.1f} | {s['peak'] / 1e6:.1f} | {s['out'] / 1e6:.1f} | "
                   f"{over / 1e6:.1f} | {over / s['out']:.3f} | {'yes' if ok else 'no'} |")
    return "\n".join(out)


# --------------------------------------------------------------------------
# Plots
# --------------------------------------------------------------------------
def _best(cs, group, exclude=()):
    ok = [c for c in cs if c.ok and c.group == group and c.name not in exclude]
    return min(ok, key=lambda c: c.ns_per_step()) if ok else None


def _save(plt, fig, name):
    """Writes `fig` to benches/plots/`name` and closes it; returns the path."""
    fig.tight_layout()
    p = os.path.join(PLOTS, name)
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def make_plots(results, log):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except Exception as e:  # noqa: BLE001
        log(f"plots skipped: matplotlib: {_short_err(e)}")
        return []
    os.makedirs(PLOTS, exist_ok=True)
    made = []
    if "W8" in results:
        rows = results["W8"][1]["pow2"]
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
        styles = {"kfast": "o-", "kfast standard": "s--", W8_C: "^:", "statsmodels tuned, no steady": "d-"}
        for c in W8_COLS:
            pts = [(r["n"], r[c]["ns"]) for r in rows if "ns" in r[c]]
            if pts:
                ax.loglog(*zip(*pts), styles[c], label=c if c != "kfast" else "kfast (joseph)")
        k = [(r["n"], r["kfast"]["ns"]) for r in rows if "ns" in r["kfast"]]
        if k:
            n0, t0 = next(((n, t) for n, t in k if n == 32), k[-1])
            ns = np.array([r["n"] for r in rows], float)
            ax.loglog(ns, t0 * (ns / n0) ** 3, color="grey", lw=0.8, label="∝ n³ (through kfast at n=32)")
        ax.set_xlabel("n (states), m = n/2")
        ax.set_ylabel("ns / step")
        ax.set_title("W8: filter cost vs state dimension")
        ax.set_xticks([r["n"] for r in rows])
        ax.set_xticklabels([str(r["n"]) for r in rows])
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        made.append(_save(plt, fig, "w8_scaling.png"))
    # bar chart: W1-W5, kfast vs C loop vs best peer
    kname = {"W1": "kfast joseph", "W2": "kfast smooth joseph", "W3": "kfast loglik",
             "W4": "kfast exact", "W5": "kfast batch"}
    labels, vals = [], {"kfast": [], "kfast fastest": [], W8_C: [], "best peer": []}
    peer_names = []
    for w in ("W1", "W2", "W3", "W4", "W5"):
        if w not in results or results[w][0] == "md":
            continue
        cs = results[w][0]
        k = next((c for c in cs if c.name == kname[w] and c.ok), None)
        cl = _best(cs, "c")
        pr = _best(cs, "peer", exclude=("numpy batched, shared P",))
        labels.append(w)
        vals["kfast"].append(k.ns_per_step() if k else np.nan)
        kb = _best(cs, "kfast", exclude=("kfast steady_state",))
        vals["kfast fastest"].append(kb.ns_per_step() if kb else np.nan)
        vals[W8_C].append(cl.ns_per_step() if cl else np.nan)  # group "c": the reference build
        vals["best peer"].append(pr.ns_per_step() if pr else np.nan)
        peer_names.append(pr.name if pr else "")
    if labels:
        fig, ax = plt.subplots(figsize=(7.5, 4.6))
        x = np.arange(len(labels))
        wd = 0.21
        bars = (("kfast", "C0"), ("kfast fastest", "C9"), (W8_C, "C2"), ("best peer", "C1"))
        for i, (lab, col) in enumerate(bars):
            b = ax.bar(x + (i - 1.5) * wd, vals[lab], wd, label=lab, color=col)
            if lab == "best peer":
                for rect, nm in zip(b, peer_names):
                    if nm:
                        ax.annotate(nm, (rect.get_x() + rect.get_width() / 2, rect.get_height()),
                                    ha="center", va="bottom", fontsize=6, rotation=90, xytext=(0, 2),
                                    textcoords="offset points")
        ax.set_yscale("log")
        ax.set_xticks(x)
        names = {"W1": "W1 filter", "W2": "W2 smoother", "W3": "W3 loglik", "W4": "W4 n=20",
                 "W5": "W5 batch\n(per series-step)"}
        ax.set_xticklabels([names[w] for w in labels])
        ax.set_ylabel("ns / step (log)")
        ax.set_title("kfast (default options, and fastest options) vs C loop vs fastest peer (any options)",
                     fontsize=9)
        ax.grid(True, axis="y", which="both", alpha=0.3)
        ax.legend(fontsize=8)
        made.append(_save(plt, fig, "w1_w5_bars.png"))
    for p in made:
        log(f"wrote {p}")
    return made
