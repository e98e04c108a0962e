"""Concurrency, leaks and memory stability (issue #10), at sizes for CI; report.py runs them at
the published sizes (10**7 soak steps) and the long profile here does too."""

from __future__ import annotations

import resources


def test_threads_give_the_serial_results():
    resources.threads_same_results(n_threads=8, T=500, rounds=2)


def test_shared_streaming_filter_step_from_threads():
    resources.shared_streaming_filter(n_threads=8, steps_per_thread=300)


def test_shared_streaming_filter_update_predict_from_threads():
    resources.shared_streaming_update_predict(n_threads=8, pairs_per_thread=200)


def test_no_leak(fuzz_profile):
    resources.leak(calls=100000 if fuzz_profile == "long" else 5000)


def test_soak(fuzz_profile):
    resources.soak(steps=10**7 if fuzz_profile == "long" else 10**6)
