"""Stochastic dynamic programming (kfast.control.dynamic_programming): Söderström Example 10.1's
table, optimality against every Markov policy of a small problem, vector states, controls that
depend on the state, and bad input."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

import kfast

CASES = json.loads((Path(__file__).parent.parent / "data" / "textbook_cases.json").read_text())


def example_10_1(horizon=2, states=range(-2, 3)):
    case = CASES["I1"]
    return kfast.control.dynamic_programming(
        lambda x, u, w, t: x + u + w,
        lambda x, u, t: u**2,
        lambda x: x**2,
        states=states,
        controls=case["controls"],
        noise=(case["noise_values"], case["noise_probabilities"]),
        horizon=horizon,
    )


def test_soderstrom_example_10_1_table():
    case = CASES["I1"]
    dp = example_10_1(case["horizon"])
    row = dp.states[1].index(float(case["x1"]))
    np.testing.assert_allclose(dp.costs[1][row], case["J_bar_at_x1"], rtol=1e-12)
    assert dp.policy_at(case["x1"], 1) == case["u_star"]
    assert dp.value_at(case["x1"], 1) == pytest.approx(case["V"], rel=1e-12)
    assert dp.controls == case["controls"]


def policy_cost(policy, x0, horizon, t=0):
    """E cost of a Markov policy {(t, x): u} by enumerating the noise paths (Example 10.1)."""
    if t == horizon:
        return x0**2
    u = policy[(t, x0)]
    return u**2 + sum(p * policy_cost(policy, x0 + u + w, horizon, t + 1) for w, p in ((-1, 0.3), (1, 0.7)))


@pytest.mark.parametrize("x0", [-1, 0, 2])
def test_optimal_among_all_markov_policies(x0):
    dp = example_10_1(2, states=[x0])
    stage1 = dp.states[1]
    best = np.inf
    for u0 in (-1, 0, 1):
        for us in itertools.product((-1, 0, 1), repeat=len(stage1)):
            policy = {(0, float(x0)): u0, **{(1, float(x)): u for x, u in zip(stage1, us)}}
            best = min(best, policy_cost(policy, float(x0), 2))
    assert dp.value_at(x0, 0) == pytest.approx(best, rel=1e-12)
    policy = {(0, float(x0)): dp.policy_at(x0, 0), **{(1, x): dp.policy_at(x, 1) for x in stage1}}
    assert policy_cost(policy, float(x0), 2) == pytest.approx(best, rel=1e-12)


def test_vector_states_state_dependent_controls_and_ties():
    """A 2-D state (position, velocity) on an integer grid, controls limited at the edges; the
    prior's expected cost; a symmetric problem has ties."""
    dp = kfast.control.dynamic_programming(
        lambda x, u, w, t: (x[0] + x[1], x[1] + u + w),
        lambda x, u, t: 0.5 * u**2 + x[0] ** 2,
        lambda x: 10.0 * (x[0] ** 2 + x[1] ** 2),
        states=[(0, 0), (1, 0), (-1, 1)],
        controls=lambda x, t: [u for u in (-1, 0, 1) if abs(x[1] + u) <= 2],
        noise=([-1, 0, 1], [0.25, 0.5, 0.25]),
        horizon=3,
    )
    assert all(isinstance(x, np.ndarray) and x.shape == (2,) for x in dp.states[2])
    assert dp.value_at((0, 0), 0) <= dp.value_at((1, 0), 0)
    prior = {(0, 0): 0.5, (1, 0): 0.25, (-1, 1): 0.25}
    assert dp.expected_cost(prior) == pytest.approx(sum(p * dp.value_at(x, 0) for x, p in prior.items()))
    # u = -1 and u = +1 are mirror images at the origin of a symmetric problem: a tie, the first wins.
    sym = kfast.control.dynamic_programming(lambda x, u, w, t: x + u + w, lambda x, u, t: 0.0, lambda x: x**2, [0, 3], [-1, 1], ([-1, 1], [0.5, 0.5]), 1)
    assert sym.ties[0].tolist() == [True, False] and sym.policy_at(0, 0) == -1 and sym.policy_at(3, 0) == -1
    for t in range(3):
        J = dp.costs[t]
        np.testing.assert_array_equal(dp.value[t], np.nanmin(J, axis=1))


def test_bad_input():
    f, c, term = (lambda x, u, w, t: x + u + w), (lambda x, u, t: u**2), (lambda x: x**2)
    dp = kfast.control.dynamic_programming
    with pytest.raises(ValueError, match="noise: probabilities must be >= 0 and sum to 1"):
        dp(f, c, term, [0], [-1, 1], ([-1, 1], [0.5, 0.6]), 2)
    with pytest.raises(ValueError, match="noise: values and probabilities"):
        dp(f, c, term, [0], [-1, 1], ([-1, 1], [1.0]), 2)
    with pytest.raises(ValueError, match="horizon: must be at least 1"):
        dp(f, c, term, [0], [-1, 1], ([0], [1.0]), 0)
    with pytest.raises(ValueError, match="controls: no controls given"):
        dp(f, c, term, [0], [], ([0], [1.0]), 2)
    with pytest.raises(ValueError, match="controls: no control allowed at x = 0.0, stage 0"):
        dp(f, c, term, [0], lambda x, t: [], ([0], [1.0]), 2)
    with pytest.raises(ValueError, match="stage_cost: returned nan at x = 0.0, stage 1"):
        dp(f, lambda x, u, t: np.nan if t == 1 else 0.0, term, [0], [0], ([0], [1.0]), 2)
    with pytest.raises(ValueError, match="f: a state is not finite"):
        dp(lambda x, u, w, t: np.inf, c, term, [0], [0], ([0], [1.0]), 2)
    with pytest.raises(ValueError, match="x: 99 is not reachable at stage 1"):
        example_10_1().value_at(99, 1)
