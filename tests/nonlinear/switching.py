"""Söderström's Example 9.2 (tests/data/imm_example_9_2.json) as a seeded simulation, shared by
the multiple-model tests."""

import json
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[1] / "data"


def example_9_2(seed, T=None):
    """The case, its modes as dicts (F, B, H, Q, R), u (T, 1), y (T, 1), the true x and the true
    mode (0 = M1)."""
    case = json.loads((DATA / "imm_example_9_2.json").read_text(encoding="utf-8"))
    rng = np.random.default_rng(seed)
    T, period, modes = T or case["T"], case["u_period"], case["modes"]
    u = np.where(np.arange(T) % period < period // 2, 1.0, -1.0)
    true_mode = np.zeros(T, dtype=int)
    for start, mode in case["switches"]:
        true_mode[start:] = mode
    x, xs = case["x_true_0"], np.zeros(T)
    for t in range(T):
        xs[t] = x
        mo = modes[true_mode[t]]
        x = mo["F"] * x + mo["B"] * u[t] + np.sqrt(mo["Q"]) * rng.standard_normal()
    y = xs + np.sqrt(case["R"]) * rng.standard_normal(T)
    dicts = [dict(F=mo["F"], B=mo["B"], H=mo["H"], Q=mo["Q"], R=case["R"]) for mo in modes]
    return case, dicts, u[:, None], y[:, None], xs, true_mode
