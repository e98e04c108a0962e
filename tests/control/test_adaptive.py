"""The one-step controllers of Söderström Sec. 10.2: the cautious law (10.74) is the
certainty-equivalence law (10.70) when the parameters are known exactly (ex. 10.3), reduces to
-a β/(β² + p) x (10.37) when only the gain is uncertain (ex. 10.2), minimises the expected cost
(10.69) (checked against a grid of inputs), and bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest

import kfast


def expected_cost(u, theta, P, y_past, u_past, r):
    phi = np.r_[-np.asarray(y_past, float), u, np.asarray(u_past, float)]
    return (phi @ theta - r) ** 2 + phi @ P @ phi  # (10.69) without λ²


@pytest.mark.parametrize("seed", range(8))
def test_cautious_minimises_the_expected_cost_and_is_ce_without_uncertainty(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 4))
    theta = rng.standard_normal(2 * n)
    theta[n] = rng.uniform(0.3, 2.0)
    A = rng.standard_normal((2 * n, 2 * n))
    P = 0.2 * A @ A.T
    y_past, u_past, r = rng.standard_normal(n), rng.standard_normal(n - 1), rng.standard_normal()
    u = kfast.control.cautious_control(theta, P, y_past, u_past, r)
    grid = u + np.linspace(-1, 1, 201)
    costs = [expected_cost(v, theta, P, y_past, u_past, r) for v in grid]
    assert expected_cost(u, theta, P, y_past, u_past, r) <= min(costs) + 1e-12
    ce = kfast.control.certainty_equivalence_control(theta, y_past, u_past, r)
    assert kfast.control.cautious_control(theta, np.zeros_like(P), y_past, u_past, r) == pytest.approx(ce, rel=1e-12)
    assert expected_cost(ce, theta, np.zeros_like(P), y_past, u_past, r) == pytest.approx(0.0, abs=1e-12)


def test_only_the_gain_uncertain_gives_equation_10_37():
    a, beta, p, x = 0.8, 0.5, 0.3, 1.7  # x(t+1) = a x + b u, b ~ (beta, p): y(t+1) = -a1 y + b1 u
    u = kfast.control.cautious_control([-a, beta], np.diag([0.0, p]), [x], [], r=0.0)
    assert u == pytest.approx(-a * beta / (beta**2 + p) * x, rel=1e-12)
    # The certainty-equivalence law is -(a / beta) x (10.35): larger in size.
    ce = kfast.control.certainty_equivalence_control([-a, beta], [x], [], r=0.0)
    assert ce == pytest.approx(-a / beta * x, rel=1e-12) and abs(ce) > abs(u)


def test_bad_input():
    with pytest.raises(ValueError, match="theta: the estimated gain b_1 is zero"):
        kfast.control.certainty_equivalence_control([0.5, 0.0], [1.0], [])
    with pytest.raises(ValueError, match="theta: expected 2n entries"):
        kfast.control.certainty_equivalence_control([0.5, 1.0, 2.0], [1.0], [])
    with pytest.raises(ValueError, match="u_past: expected n - 1 = 1 values"):
        kfast.control.certainty_equivalence_control([0.5, 0.1, 1.0, 0.2], [1.0, 2.0], [])
    with pytest.raises(ValueError, match="P: must be positive semidefinite"):
        kfast.control.cautious_control([0.5, 1.0], -np.eye(2), [1.0], [])
    with pytest.raises(ValueError, match="theta, P: b_1 is estimated as exactly zero"):
        kfast.control.cautious_control([0.5, 0.0], np.zeros((2, 2)), [1.0], [])
    with pytest.raises(ValueError, match="y_past: must be finite"):
        kfast.control.cautious_control([0.5, 1.0], np.eye(2), [np.nan], [])
