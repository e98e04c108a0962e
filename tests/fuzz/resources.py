"""Resource checks of the fuzz campaign, shared by test_fuzz_resources.py (small sizes) and
report.py (the published sizes): concurrency (8 threads), memory stability (soak) and leaks.

Each function returns a dict of figures and raises AssertionError with the figures when the
check fails.
"""

from __future__ import annotations

import sys
import threading
import time

import numpy as np

import kfast


def rss_mb() -> float:
    """The resident set size of this process, in MiB (Linux /proc)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS in /proc/self/status")


def _model_and_data(T: int, seed: int = 0):
    model = kfast.models.constant_velocity(2, dt=0.1)
    rng = np.random.default_rng(seed)
    y = rng.standard_normal((T, 2))
    return model, y, np.zeros(4), np.eye(4)


def _in_threads(fn, n_threads: int, timeout: float = 120.0) -> list:
    """Run fn(i) in n_threads threads started together; returns their results or exceptions."""
    results: list = [None] * n_threads
    barrier = threading.Barrier(n_threads)

    def body(i):
        barrier.wait()
        try:
            results[i] = fn(i)
        except BaseException as exc:  # noqa: B036 - a PanicException must be reported, not lost
            results[i] = exc

    threads = [threading.Thread(target=body, args=(i,), daemon=True) for i in range(n_threads)]
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as possible: interleave the calls
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout)
            assert not t.is_alive(), f"a thread did not finish within {timeout} s (deadlock?)"
    finally:
        sys.setswitchinterval(interval)
    return results


def threads_same_results(n_threads: int = 8, T: int = 2000, rounds: int = 3) -> dict:
    """filter, smooth and filter_batch from n_threads threads at once on one shared model give
    exactly the serial results."""
    model, y, x0, P0 = _model_and_data(T)
    Y = np.stack([np.roll(y, i, axis=0) for i in range(4)])
    serial = [model.filter(np.roll(y, i, axis=0), x0, P0).x_filt for i in range(n_threads)]
    serial_sm = model.smooth(y, x0, P0).x_smooth
    serial_b = kfast.filter_batch(model, Y, x0, P0, threads=2).loglik
    calls = 0
    for _ in range(rounds):
        out = _in_threads(lambda i: model.filter(np.roll(y, i, axis=0), x0, P0).x_filt, n_threads)
        out_sm = _in_threads(lambda i: model.smooth(y, x0, P0).x_smooth, n_threads)
        out_b = _in_threads(lambda i: kfast.filter_batch(model, Y, x0, P0, threads=2).loglik, n_threads)
        for i in range(n_threads):
            for got, want, what in ((out[i], serial[i], "filter"), (out_sm[i], serial_sm, "smooth"), (out_b[i], serial_b, "filter_batch")):
                assert not isinstance(got, BaseException), f"{what} in thread {i}: {type(got).__name__}: {got}"
                assert np.array_equal(got, want), f"{what} in thread {i} differs from the serial result"
        calls += 3 * n_threads
    return {"threads": n_threads, "calls": calls, "T": T}


def shared_streaming_filter(n_threads: int = 8, steps_per_thread: int = 500) -> dict:
    """One KalmanFilter shared by n_threads threads calling step() with the same y: each step is
    atomic (the same y makes the order irrelevant), so the final state must be that of
    n_threads * steps_per_thread serial steps, or every failing call must raise a clear error."""
    model, y, x0, P0 = _model_and_data(1)
    shared = kfast.KalmanFilter(model, x0, P0)
    serial = kfast.KalmanFilter(model, x0, P0)
    for _ in range(n_threads * steps_per_thread):
        serial.step(y[0])

    def work(i):
        errors = []
        for _ in range(steps_per_thread):
            try:
                shared.step(y[0])
            except (ValueError, RuntimeError) as exc:
                errors.append(f"{type(exc).__name__}: {exc}")
        return errors

    out = _in_threads(work, n_threads)
    bad = [r for r in out if isinstance(r, BaseException)]
    assert not bad, f"shared KalmanFilter.step from {n_threads} threads raised {type(bad[0]).__name__}: {bad[0]}"
    errors = [e for r in out for e in r]
    if not errors:
        assert shared.t == serial.t, f"t = {shared.t} after {serial.t} steps from {n_threads} threads"
        assert np.allclose(shared.x, serial.x, rtol=1e-12) and np.allclose(shared.P, serial.P, rtol=1e-12), (
            "shared KalmanFilter.step from threads differs from the serial steps"
        )
    return {"threads": n_threads, "steps": n_threads * steps_per_thread, "errors": len(errors), "first_error": errors[0] if errors else ""}


def shared_streaming_update_predict(n_threads: int = 8, pairs_per_thread: int = 300) -> dict:
    """One KalmanFilter shared by threads calling update() then predict() (issue #10: "update
    called twice" errors): memory-safe, and any failure is a clear error (a ValueError or
    RuntimeError, never a crash, a panic or another exception type)."""
    model, y, x0, P0 = _model_and_data(1)
    shared = kfast.KalmanFilter(model, x0, P0)

    def work(i):
        errors = []
        for _ in range(pairs_per_thread):
            for call in (lambda: shared.update(y[0]), shared.predict):
                try:
                    call()
                except (ValueError, RuntimeError) as exc:
                    errors.append(f"{type(exc).__name__}: {exc}")
        return errors

    out = _in_threads(work, n_threads)
    bad = [r for r in out if isinstance(r, BaseException)]
    assert not bad, f"shared KalmanFilter update/predict from {n_threads} threads raised {type(bad[0]).__name__}: {bad[0]}"
    errors = [e for r in out for e in r]
    assert np.isfinite(shared.x).all() and np.isfinite(shared.P).all(), "the shared filter's state is not finite"
    return {"threads": n_threads, "calls": 2 * n_threads * pairs_per_thread, "errors": len(errors), "first_error": errors[0] if errors else ""}


def leak(calls: int = 20000, T: int = 50, max_growth_mb: float = 20.0) -> dict:
    """RSS after many calls of filter, smooth, loglik, filter_batch, a failing call and the
    streaming filter: growth after a warm-up stays under max_growth_mb."""
    model, y, x0, P0 = _model_and_data(T)
    Y = np.stack([y, y])
    kf = kfast.KalmanFilter(model, x0, P0)

    def one(i):
        model.filter(y, x0, P0)
        model.loglik(y, x0, P0)
        if i % 4 == 0:
            model.smooth(y, x0, P0)
            kfast.filter_batch(model, Y, x0, P0, threads=1)
        try:
            model.filter(y, x0, -P0)
        except kfast.KfastError:
            pass
        kf.step(y[i % T])

    for i in range(calls // 10):
        one(i)
    start = rss_mb()
    t0 = time.perf_counter()
    for i in range(calls):
        one(i)
    growth = rss_mb() - start
    assert growth < max_growth_mb, f"RSS grew by {growth:.1f} MiB over {calls} rounds of calls"
    return {"rounds": calls, "rss_start_mb": round(start, 1), "rss_growth_mb": round(growth, 2), "seconds": round(time.perf_counter() - t0, 1)}


def soak(steps: int = 10**7, max_growth_mb: float = 50.0) -> dict:
    """steps filter steps through filter_batch (1000 series at a time, P(t|t) not returned) and
    steps // 10 through the streaming filter: RSS sampled along the way stays flat."""
    model, y, x0, P0 = _model_and_data(1000)
    B = 1000
    T = 1000
    Y = np.broadcast_to(y, (B, T, 2))
    samples = []
    done = 0
    t0 = time.perf_counter()
    while done < steps:
        res = kfast.filter_batch(model, Y, x0, P0, return_covs=False)
        assert np.isfinite(res.loglik).all()
        done += B * T
        samples.append(rss_mb())
    batch_seconds = time.perf_counter() - t0
    kf = kfast.KalmanFilter(model, x0, P0)
    stream_steps = steps // 10
    t0 = time.perf_counter()
    for i in range(stream_steps):
        kf.step(y[i % 1000])
        if i % 100000 == 0:
            samples.append(rss_mb())
    stream_seconds = time.perf_counter() - t0
    assert np.isfinite(kf.x).all() and np.isfinite(kf.loglik)
    warm = samples[min(2, len(samples) - 1)]
    growth = max(samples) - warm
    assert growth < max_growth_mb, f"RSS grew by {growth:.1f} MiB during the soak (samples {samples[:3]} ... {samples[-3:]})"
    return {
        "batch_steps": done,
        "batch_seconds": round(batch_seconds, 1),
        "stream_steps": stream_steps,
        "stream_seconds": round(stream_seconds, 1),
        "rss_min_mb": round(min(samples), 1),
        "rss_max_mb": round(max(samples), 1),
        "rss_growth_after_warmup_mb": round(growth, 2),
    }
