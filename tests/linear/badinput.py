"""Shared helpers of the bad-input tests of the linear model, the filter and the streaming
filter (test_model_errors.py, test_filter_errors.py, test_streaming_errors.py,
test_input_conversion.py).

Bad input is refused with a ``kfast.KfastError`` (a ValueError) whose message names the
argument, the time step when there is one, and the problem; good input in any array-like form
gives the same float64 answer and is never modified.

Every error case is checked with ``pytest.raises(ValueError, match=...)``, anchored at the start
of the message (``"Q at step 3: ..."``), and then required to be a ``kfast.KfastError`` (so that
e.g. a NumPy ValueError leaking out with no argument name fails). A Rust panic would surface as
``pyo3_runtime.PanicException``, a BaseException that ``pytest.raises(ValueError)`` does not
catch, so any panic fails the test that provoked it.

Models used: ``full_model`` has n = 2 states, m = 2 outputs, k = 1 input, with B, D and N;
data has T = 6 steps.
"""

from __future__ import annotations

import contextlib
import re

import numpy as np
import pytest

import kfast


T = 6
N_STATES, N_OBS, N_IN = 2, 2, 1


# --------------------------------------------------------------------------------------------
# helpers


def msg(arg, *problem, step=None):
    """Regex for ``"<arg>[ at step <step>]: ... <problem parts, in order> ..."``."""
    head = f"{arg}: " if step is None else f"{arg} at step {step}: "
    return "^" + re.escape(head) + ".*" + ".*".join(problem)


@contextlib.contextmanager
def fails(pattern, exc=kfast.KfastError):
    """``pytest.raises(ValueError, match=pattern)``, and the error must be exactly ``exc``."""
    with pytest.raises(ValueError, match=pattern) as info:
        yield info
    assert type(info.value) is exc, f"{type(info.value).__name__}: {info.value}"


def model_mats(**over):
    """Valid matrices of the full model (n = 2, m = 2, k = 1); ``over`` replaces/removes some."""
    mats = {
        "F": np.array([[0.9, 0.1], [0.0, 0.7]]),
        "H": np.array([[1.0, 0.0], [0.5, 1.0]]),
        "Q": np.array([[0.5, 0.1], [0.1, 0.3]]),
        "R": np.array([[1.0, 0.2], [0.2, 0.8]]),
        "B": np.array([[1.0], [0.5]]),
        "D": np.array([[0.1], [0.2]]),
        "N": np.array([[0.1, 0.0], [0.0, 0.05]]),
    }
    mats.update(over)
    return {k: v for k, v in mats.items() if v is not None}


def plain_mats(**over):
    """F, H, Q, R of the full model only (no B, D, N)."""
    return model_mats(B=None, D=None, N=None, **over)


def data(**over):
    rng = np.random.default_rng(1)
    d = {
        "y": rng.normal(size=(T, N_OBS)),
        "x0": np.array([0.5, -0.5]),
        "P0": np.array([[1.0, 0.3], [0.3, 2.0]]),
        "u": rng.normal(size=(T, N_IN)),
    }
    d.update(over)
    return {k: v for k, v in d.items() if v is not None}


def full_model():
    return kfast.LinearGaussian(**model_mats())


def plain_model():
    return kfast.LinearGaussian(**plain_mats())


def per_step_model(steps=T, **over):
    """The full model with F and Q given per step (``steps`` of them)."""
    mats = model_mats()
    mats["F"] = np.stack([mats["F"] * (1 - 0.05 * t) for t in range(steps)])
    mats["Q"] = np.stack([mats["Q"] * (1 + 0.1 * t) for t in range(steps)])
    mats.update(over)
    return kfast.LinearGaussian(**mats)


def batch(how, model, **d):
    """``model.filter(**d)`` or ``model.loglik(**d)``."""
    return getattr(model, how)(**d)


BATCH = ["filter", "loglik"]


def stack(a, steps=T):
    return np.stack([a] * steps)


# --------------------------------------------------------------------------------------------
# matrices that are not covariances

ASYM = np.array([[1.0, 0.5], [0.4, 1.0]])
NOT_PSD = np.array([[1.0, 2.0], [2.0, 1.0]])  # eigenvalues 3, -1


# --------------------------------------------------------------------------------------------
# models whose innovation covariance S = H P H' + R cannot be factorized at some step


def singular_model(**over):
    """R = 0, Q = 0: with P0 = 0, S = 0 at step 0."""
    mats = plain_mats(Q=np.zeros((2, 2)), R=np.zeros((2, 2)))
    mats.update(over)
    return kfast.LinearGaussian(**mats)


def later_singular_model():
    """n = m = 1, F = 0, Q = 0, R = 0, H = 1, P0 = 1: S = 1 at step 0, then P(1|0) = 0 and
    S = 0 at step 1 (constant matrices)."""
    return kfast.LinearGaussian(0.0, 1.0, 0.0, 0.0)
