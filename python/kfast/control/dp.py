"""Stochastic dynamic programming on finite grids (Söderström Lemma 10.4, (10.53); Example 10.1),
with the state known at each step:

::

    V(x, t_f) = terminal_cost(x)
    J̄(x, u, t) = stage_cost(x, u, t) + sum_k p_k V(f(x, u, v_k, t), t + 1)
    u*(x, t) = argmin_u J̄(x, u, t),   V(x, t) = min_u J̄(x, u, t)

over the states reachable from the initial ones (computed forward first: the grid is exact, no
interpolation). The cost is O(t_f |X| |U| |V|) calls of the user's functions, which is the
method's own cost: it grows exponentially with the state dimension (the book's warning).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Hashable, Sequence, Union

import numpy as np

from kfast._args import index
from kfast._kfast import KfastError

__all__ = ["DPResult", "dynamic_programming"]


@dataclass(frozen=True, repr=False)
class DPResult:
    """Value and policy tables of :func:`dynamic_programming`, one entry per stage t = 0..t_f
    (the last stage has values only)."""

    states: list
    """states[t]: the reachable states at stage t (a list, in first-reached order)."""
    value: list
    """value[t]: V(x, t) for x in states[t], an array."""
    policy: list
    """policy[t]: the minimising control u*(x, t) for x in states[t] (t < t_f), a list."""
    costs: list
    """costs[t]: J̄(x, u, t), an array (len(states[t]), len(controls)) with NaN for a control not
    allowed at x (t < t_f): Example 10.1's tables."""
    ties: list
    """ties[t]: whether another control reached the same minimum (the first in the given order
    was chosen), a boolean array (t < t_f)."""
    controls: list
    """The controls in the order of the columns of costs."""

    def _row(self, x: Hashable, t: int) -> int:
        try:
            return [_key(s) for s in self.states[t]].index(_key(x))
        except (ValueError, KfastError):
            raise KfastError(f"x: {x!r} is not reachable at stage {t}") from None

    def value_at(self, x: Hashable, t: int) -> float:
        """V(x, t)."""
        return float(self.value[t][self._row(x, t)])

    def policy_at(self, x: Hashable, t: int) -> Any:
        """u*(x, t)."""
        return self.policy[t][self._row(x, t)]

    def expected_cost(self, prior: dict) -> float:
        """E V(x(0), 0) for a probability mass function {x: p} on x(0)."""
        return float(sum(p * self.value_at(x, 0) for x, p in prior.items()))

    def __repr__(self) -> str:
        sizes = [len(s) for s in self.states]
        return f"DPResult(horizon={len(self.states) - 1}, states per stage={sizes}, controls={len(self.controls)})"


def _key(x: Any) -> Hashable:
    """A state as a dictionary key: numbers as floats (so 1 and 1.0 are the same state, and
    -0.0 is 0.0), sequences as tuples of those."""
    if isinstance(x, (list, tuple, np.ndarray)):
        return tuple(_key(v) for v in np.asarray(x).ravel().tolist())
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
        raise KfastError(f"f: states must be numbers or sequences of numbers, got {x!r}")
    v = float(x)
    if not np.isfinite(v):
        raise KfastError(f"f: a state is not finite ({v})")
    return v + 0.0


def dynamic_programming(
    f: Callable[[Any, Any, Any, int], Any],
    stage_cost: Callable[[Any, Any, int], float],
    terminal_cost: Callable[[Any], float],
    states: Sequence,
    controls: Union[Sequence, Callable[[Any, int], Sequence]],
    noise: tuple,
    horizon: int,
) -> DPResult:
    """Optimal feedback u*(x, t) for x(t+1) = f(x, u, v, t) with a discrete noise v, minimising
    E[terminal_cost(x(t_f)) + sum_t stage_cost(x(t), u(t), t)] (Söderström Lemma 10.4, (10.53)).

    Parameters
    ----------
    f : callable
        ``f(x, u, v, t)`` -> the next state (a number or a sequence of numbers; states are matched
        exactly, so a grid must map onto itself, e.g. integers).
    stage_cost : callable
        ``stage_cost(x, u, t)`` -> float.
    terminal_cost : callable
        ``terminal_cost(x)`` -> float.
    states : sequence
        The initial states x(0) (the stages' grids are the states reachable from them).
    controls : sequence or callable
        The admissible controls (the same at every state), or ``controls(x, t)`` -> a
        subsequence of the controls allowed at x.
    noise : (values, probabilities)
        The noise's probability mass function (probabilities >= 0 summing to 1).
    horizon : int
        t_f >= 1 (the book's N).

    Returns
    -------
    DPResult
        Per stage: states, V, u*, J̄ for every control, ties.

    Examples
    --------
    Söderström Example 10.1: x(t+1) = x + u + w, u in {-1, 0, 1}, P(w = -1) = 0.3,
    P(w = 1) = 0.7, cost E[x(2)^2 + u(1)^2 + u(0)^2].

    >>> dp = kfast.control.dynamic_programming(
    ...     lambda x, u, w, t: x + u + w, lambda x, u, t: u**2, lambda x: x**2,
    ...     states=range(-2, 3), controls=[-1, 0, 1], noise=([-1, 1], [0.3, 0.7]), horizon=2)
    >>> print(dp.costs[1][dp.states[1].index(-3.0)].round(6))
    [14.8  7.6  4.4]
    >>> dp.policy_at(-3, 1), round(dp.value_at(-3, 1), 6)
    (1, 4.4)
    """
    t_f = index("horizon", horizon)
    if t_f < 1:
        raise KfastError(f"horizon: must be at least 1, got {t_f}")
    try:
        values, probs = noise
        values, probs = list(values), np.asarray(probs, dtype=float)
    except (TypeError, ValueError):
        raise KfastError("noise: expected (values, probabilities)") from None
    if probs.ndim != 1 or len(values) != len(probs) or len(values) == 0:
        raise KfastError(f"noise: values and probabilities must be non-empty and of the same length ({len(values)} and {probs.shape})")
    if not np.all(np.isfinite(probs)) or np.any(probs < 0) or abs(probs.sum() - 1.0) > 1e-9:
        raise KfastError(f"noise: probabilities must be >= 0 and sum to 1, got {probs.tolist()}")
    support = [(v, p) for v, p in zip(values, probs) if p > 0]
    all_controls = None if callable(controls) else list(controls)
    if all_controls is not None and not all_controls:
        raise KfastError("controls: no controls given")

    def allowed(x: Any, t: int) -> list:
        if all_controls is not None:
            return all_controls
        got = list(controls(x, t))  # type: ignore[operator]
        if not got:
            raise KfastError(f"controls: no control allowed at x = {x!r}, stage {t}")
        return got

    # Forward: the reachable states of every stage (first-reached order), and the control list.
    stage_states: list[list] = [list(dict.fromkeys(_key(x) for x in states))]
    if not stage_states[0]:
        raise KfastError("states: no initial state given")
    column: dict = {}
    order: list = []
    succ: list[dict] = []
    for t in range(t_f):
        nxt: dict = {}
        table: dict = {}
        for x in stage_states[t]:
            for u in allowed(_as_user(x), t):
                if _key_control(u) not in column:
                    column[_key_control(u)] = len(order)
                    order.append(u)
                table[(x, _key_control(u))] = [(_key(f(_as_user(x), u, v, t)), p) for v, p in support]
                for y, _ in table[(x, _key_control(u))]:
                    nxt.setdefault(y, None)
        succ.append(table)
        stage_states.append(list(nxt))

    # Backward: V, J̄, u*.
    value = [np.empty(0)] * (t_f + 1)
    value[t_f] = np.array([_cost("terminal_cost", terminal_cost(_as_user(x)), x, t_f) for x in stage_states[t_f]])
    costs: list = [None] * t_f
    policy: list = [None] * t_f
    ties: list = [None] * t_f
    for t in range(t_f - 1, -1, -1):
        row_of = {x: i for i, x in enumerate(stage_states[t + 1])}
        here = {x: i for i, x in enumerate(stage_states[t])}
        J = np.full((len(stage_states[t]), len(order)), np.nan)
        for (x, uk), nexts in succ[t].items():
            i, j = here[x], column[uk]
            expected = sum(p * value[t + 1][row_of[y]] for y, p in nexts)
            J[i, j] = _cost("stage_cost", stage_cost(_as_user(x), order[j], t), x, t) + expected
        best = np.nanargmin(J, axis=1)
        low = J[np.arange(len(J)), best]
        value[t] = low
        costs[t] = J
        policy[t] = [order[j] for j in best]
        ties[t] = np.sum(np.abs(J - low[:, None]) <= 1e-12 * np.maximum(1.0, np.abs(low[:, None])), axis=1) > 1
    return DPResult(
        states=[[_as_user(x) for x in s] for s in stage_states],
        value=value,
        policy=policy,
        costs=costs,
        ties=ties,
        controls=order,
    )


def _key_control(u: Any) -> Hashable:
    return tuple(np.asarray(u).ravel().tolist()) if isinstance(u, (list, tuple, np.ndarray)) else u


def _as_user(x: Hashable) -> Any:
    """A state key back as the user's functions see it: a float or a NumPy vector."""
    return np.array(x) if isinstance(x, tuple) else x


def _cost(name: str, value: Any, x: Any, t: int) -> float:
    try:
        c = float(value)
    except (TypeError, ValueError):
        raise KfastError(f"{name}: must return a number, got {value!r} at x = {x!r}, stage {t}") from None
    if not np.isfinite(c):
        raise KfastError(f"{name}: returned {c} at x = {x!r}, stage {t}")
    return c
