"""Fused multiply-adds or the same bits on every CPU (docs/conventions.md, "Arithmetic").

kfast's filter and smoother loops *fuse* their multiply-adds: ``c + a * b`` rounds once
(IEEE ``fma``), on x86-64 CPUs with AVX2 and FMA and on every other target (aarch64), so the
same operations give the same bits on each of them. Products of run-time sizes above 12 go to
faer by default, whose kernels (and so last bits) depend on the CPU; *deterministic* mode
keeps them in kfast's loops, and then every CPU computes the same bits (an x86-64 CPU without
FMA fuses in software then: slow). Either way every path (``filter``, ``filter_batch``,
``KalmanFilter``, the smoothers) computes the same recursion the same way, so they agree with
each other to the bit.

Deterministic mode is off by default; ``KFAST_DETERMINISTIC=1`` in the environment turns it
on for the process (read at the first filter call), :func:`set_deterministic` at any time.
Its cost is measured in BENCHMARKS.md.

>>> import kfast
>>> previous = kfast.set_deterministic(True)
>>> kfast.deterministic()
True
>>> _ = kfast.set_deterministic(previous)
"""

from __future__ import annotations

from kfast import _kfast
from kfast._args import flag


def set_deterministic(on: bool) -> bool:
    """Turn deterministic mode on or off for the whole process; returns the previous setting.

    It changes results only with more than 12 states, by rounding. Calls already running keep
    their loops (one with more than 12 states may compute some products each way); a
    ``KalmanFilter`` or ``FixedLagSmoother`` keeps the loops it was created with. The matrix equation
    solvers (``solve_discrete_are`` and the like) are not affected: their large products run
    in faer, which picks its own kernels per CPU.
    """
    return _kfast.set_deterministic(flag("on", on))


def deterministic() -> bool:
    """Whether deterministic mode is on (see :func:`set_deterministic`)."""
    return _kfast.deterministic()


def kernel_info() -> dict[str, object]:
    """How the loops run on this machine: ``instruction_set`` (``"avx2+fma"``,
    ``"baseline+fma"``, or on an x86-64 CPU without FMA ``"avx2"`` or ``"baseline"``), ``deterministic``, ``cpu_features``, the compiled ``fixed_sizes``, the
    extension's ``build`` profile (``"release"`` or ``"debug"``) and ``target``, and
    ``threads``: the cores the batch functions use by default (``threads=None``)."""
    return dict(_kfast.kernel_info())
