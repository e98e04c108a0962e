"""Workload N3: a bootstrap particle filter on UNGM, systematic resampling at every step ->
filtered means, variances and the log-likelihood; 100,000 particles, T = 200.

    python benches/bench_particle.py [--quick]

Contenders, timed in one run (rounds interleaved, medians; ns per particle-step):

- kfast with the built-in UNGM (`kfast.models.ungm`), on all cores and on one;
- kfast with the model as numba `@cfunc`s (the C signature of kfast.NonlinearModel) and as
  vectorized Python callables (one call of f and one of h per step for all particles);
- a plain vectorized NumPy bootstrap filter (the same algorithm, NumPy's generator);
- kfast's built-in with the Student-t likelihood, with the measurements quantized (step 0.5) and
  the quantized likelihood, and with regularization (their cost beside the Gaussian default);
- kfast's built-in with the Gaussian likelihood given by the user, as a vectorized Python
  function and as a numba `@cfunc` (what a user-given p(y | x) costs), and with the book's
  r = 10 copies of each resampled particle;
- Chopin's `particles` (SMC with a Bootstrap Feynman-Kac model, ESSrmin = 1 so that it resamples
  at every step), which needs numpy < 2 and runs in its own venv (benches/peers_particle.py;
  set KFAST_PARTICLES_PYTHON or create /work/venv-particles as that file says);
- Stone Soup's ParticlePredictor / ParticleUpdater / SystematicResampler with UNGM as custom
  Stone Soup models (benches/peer_stonesoup.py; `pip install stonesoup`, in the bench extras).

Different generators: the filters agree only within Monte-Carlo error, which the run prints (the
largest |difference of means| to kfast's, over the posterior standard deviation, and each
log-likelihood).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, os.path.dirname(__file__))

import numpy as np  # noqa: E402

from bench_filter import Contender, run_interleaved  # noqa: E402

import kfast  # noqa: E402

Q, R, P0 = 10.0, 1.0, 5.0
PARTICLES_PYTHON = os.environ.get("KFAST_PARTICLES_PYTHON", "/work/venv-particles/bin/python")


def ungm_f(X, t, u):
    return X / 2 + 25 * X / (1 + X**2) + 8 * np.cos(1.2 * t)


def ungm_h(X, t, u):
    return X**2 / 20


def simulate(T, seed=1):
    rng = np.random.default_rng(seed)
    x, y = rng.normal(0, np.sqrt(P0)), np.zeros(T)
    for t in range(T):
        y[t] = x**2 / 20 + rng.normal(0, np.sqrt(R))
        x = ungm_f(x, t, None) + rng.normal(0, np.sqrt(Q))
    return y


def numpy_bootstrap(y, N, seed=0):
    """The bootstrap filter in vectorized NumPy: weights in logs, systematic resampling every step."""
    rng = np.random.default_rng(seed)
    x = rng.normal(0, np.sqrt(P0), N)
    means, variances, loglik = np.zeros(len(y)), np.zeros(len(y)), 0.0
    for t in range(len(y)):
        lw = -0.5 * (np.log(2 * np.pi * R) + (y[t] - x**2 / 20) ** 2 / R)
        top = lw.max()
        w = np.exp(lw - top)
        total = w.sum()
        loglik += top + np.log(total / N)
        w /= total
        means[t] = w @ x
        variances[t] = w @ (x - means[t]) ** 2
        if t + 1 < len(y):
            cumulative = np.cumsum(w)
            u = (np.arange(N) + rng.uniform()) / N
            x = x[np.minimum(np.searchsorted(cumulative, u * cumulative[-1]), N - 1)]
            x = ungm_f(x, t, None) + rng.normal(0, np.sqrt(Q), N)
    return means, variances, loglik


def numba_model():
    try:
        import numba
        from numba import types
    except ImportError:
        return None
    sig = types.void(types.CPointer(types.float64), types.intp, types.intp, types.int64, types.CPointer(types.float64), types.CPointer(types.float64))

    @numba.cfunc(sig, fastmath=False)
    def f(X, k, n, t, u, out):
        c = 8 * np.cos(1.2 * t)
        for i in range(k):
            x = X[i]
            out[i] = x / 2 + 25 * x / (1 + x * x) + c

    @numba.cfunc(sig, fastmath=False)
    def h(X, k, n, t, u, out):
        for i in range(k):
            out[i] = X[i] * X[i] / 20

    return kfast.NonlinearModel(f, h, [[Q]], [[R]], n=1)


def gaussian_loglik(X, y, t, u):
    """log N(y; x^2/20, R): the default likelihood, written as a user's."""
    return -0.5 * (np.log(2 * np.pi * R) + (y[0] - X[:, 0] ** 2 / 20) ** 2 / R)


def numba_loglik():
    """``gaussian_loglik`` as a numba @cfunc of kfast's PARTICLE_C_SIGNATURE (None without numba)."""
    try:
        import numba
        from numba import types
    except ImportError:
        return None
    p = types.CPointer(types.float64)
    sig = types.void(p, types.intp, types.intp, p, types.intp, types.int64, p, p)
    constant = -0.5 * np.log(2 * np.pi * R)

    @numba.cfunc(sig, fastmath=False)
    def loglik(X, k, n, y, m, t, u, out):
        for i in range(k):
            e = y[0] - X[i] * X[i] / 20
            out[i] = constant - 0.5 * e * e / R

    return loglik


def stonesoup_contender(y, N, steps):
    """Stone Soup's bootstrap filter (benches/peer_stonesoup.py), or a row saying why not."""
    try:
        import stonesoup
        from peer_stonesoup import stonesoup_bootstrap
    except ImportError:
        row = Contender("Stone Soup", None, steps)
        row.error = "stonesoup not installed (pip install stonesoup)"
        return row, None
    return Contender("Stone Soup", lambda: stonesoup_bootstrap(y, N, Q, R, P0), steps), stonesoup.__version__


def run_particles(y, N, rounds):
    """`particles` in its venv: (samples, means, variances, loglik, version) or an error string."""
    if not os.path.exists(PARTICLES_PYTHON):
        return f"particles venv missing: see benches/peers_particle.py (or set KFAST_PARTICLES_PYTHON)"
    with tempfile.TemporaryDirectory() as d:
        np.save(os.path.join(d, "y.npy"), y)
        with open(os.path.join(d, "job.json"), "w") as f:
            json.dump({"rounds": rounds, "particles": N}, f)
        script = os.path.join(os.path.dirname(__file__), "peers_particle.py")
        done = subprocess.run([PARTICLES_PYTHON, script, d], capture_output=True, text=True)
        if done.returncode:
            return "particles failed: " + (done.stderr.strip().splitlines() or ["?"])[-1][:100]
        with open(os.path.join(d, "timings.json")) as f:
            return json.load(f)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)
    rounds = 3 if args.quick else 5
    N, T = (20_000, 50) if args.quick else (100_000, 200)
    y = simulate(T)
    y_quantized = kfast.quantize(y, 0.5)
    builtin = kfast.models.ungm(q=Q, r=R)
    python = kfast.NonlinearModel(ungm_f, ungm_h, [[Q]], [[R]], n=1)
    jitted = numba_model()
    loglik_c = numba_loglik()
    pf = dict(resample="systematic", seed=0)
    steps = N * T
    stone_soup, stone_soup_version = stonesoup_contender(y, N, steps)
    contenders = [
        Contender("kfast built-in, all cores", lambda: builtin.particle_filter(y, [0.0], [[P0]], N, **pf), steps),
        Contender("kfast built-in, 1 thread", lambda: builtin.particle_filter(y, [0.0], [[P0]], N, threads=1, **pf), steps),
        Contender("kfast numba cfunc, all cores", lambda: jitted.particle_filter(y, [0.0], [[P0]], N, **pf), steps),
        Contender("kfast Python callable", lambda: python.particle_filter(y, [0.0], [[P0]], N, **pf), steps),
        Contender("NumPy bootstrap filter", lambda: numpy_bootstrap(y, N), steps),
        # kfast's other likelihoods and the regularization, beside its Gaussian default
        Contender("kfast built-in, Student-t(4) likelihood",
                  lambda: builtin.particle_filter(y, [0.0], [[P0]], N, likelihood=kfast.StudentT(4.0), **pf), steps),
        Contender("kfast built-in, quantized y (delta 0.5)",
                  lambda: builtin.particle_filter(y_quantized, [0.0], [[P0]], N, likelihood=kfast.Quantized(0.5), **pf), steps),
        Contender("kfast built-in, regularized", lambda: builtin.particle_filter(y, [0.0], [[P0]], N, regularize=True, **pf), steps),
        Contender("kfast built-in, likelihood a Python function",
                  lambda: builtin.particle_filter(y, [0.0], [[P0]], N, likelihood=gaussian_loglik, **pf), steps),
        Contender("kfast built-in, likelihood a numba cfunc",
                  lambda: builtin.particle_filter(y, [0.0], [[P0]], N, likelihood=loglik_c, **pf), steps),
        Contender("kfast built-in, r = 10 copies", lambda: builtin.particle_filter(y, [0.0], [[P0]], N, copies=10, **pf), steps),
        stone_soup,
    ]
    if jitted is None:
        contenders[2].error = "numba not installed"
    if loglik_c is None:
        contenders[10].error = "numba not installed"
    peer = run_particles(y, N, rounds)
    run_interleaved([c for c in contenders if c.fn is not None], rounds)
    chopin = Contender("particles (Chopin)", None, steps)
    if isinstance(peer, str):
        chopin.error = peer
    else:
        chopin.samples = peer["samples"]
    contenders.insert(5, chopin)
    cores = os.cpu_count()
    print(f"kfast {kfast.__version__}; UNGM, N = {N:,} particles, T = {T}; {rounds} rounds, medians; {cores} cores")
    if not isinstance(peer, str):
        print(f"peers: particles {peer['version']}, numpy (theirs) in their venv")
    if stone_soup_version:
        print(f"peers: Stone Soup {stone_soup_version}")
    base = contenders[0]
    print("\n| contender | ns/particle-step | IQR | /kfast built-in |\n|---|---:|---:|---:|")
    for c in contenders:
        if not c.ok:
            print(f"| {c.name} | - | - | {c.error} |")
            continue
        lo, hi = c.spread()
        print(f"| {c.name} | {c.ns_per_step():.1f} | {lo:.1f}-{hi:.1f} | {c.ns_per_step() / base.ns_per_step():.3g} |")
    # the filters agree within Monte-Carlo error
    reference = builtin.particle_filter(y, [0.0], [[P0]], N, **pf)
    sd = np.sqrt(reference.P_filt[:, 0, 0])
    others = [("kfast Python callable", python.particle_filter(y, [0.0], [[P0]], N, **pf))]
    if jitted is not None:
        others.insert(0, ("kfast numba cfunc", jitted.particle_filter(y, [0.0], [[P0]], N, **pf)))
    print(f"  kfast built-in: loglik {reference.loglik:.3f}")
    for name, res in others:
        print(f"  check {name}: max|dmean| = {np.max(np.abs(res.x_filt[:, 0] - reference.x_filt[:, 0])):.1e}, loglik {res.loglik:.3f}")
    means, _, loglik = numpy_bootstrap(y, N)
    print(f"  check NumPy bootstrap: max|dmean|/sd = {np.max(np.abs(means - reference.x_filt[:, 0]) / sd):.2f}, loglik {loglik:.3f}")
    if not isinstance(peer, str):
        d = np.max(np.abs(np.array(peer["mean"]) - reference.x_filt[:, 0]) / sd)
        print(f"  check particles: max|dmean|/sd = {d:.2f}, loglik {peer['loglik']:.3f}")
    if stone_soup.ok:
        means, _, loglik = stone_soup.fn()
        print(f"  check Stone Soup: max|dmean|/sd = {np.max(np.abs(means - reference.x_filt[:, 0]) / sd):.2f}, loglik {loglik:.3f}")
    if loglik_c is not None:
        user = builtin.particle_filter(y, [0.0], [[P0]], N, likelihood=loglik_c, **pf)
        print(f"  check numba likelihood: max|dmean| = {np.max(np.abs(user.x_filt[:, 0] - reference.x_filt[:, 0])):.1e}")


if __name__ == "__main__":
    main()
