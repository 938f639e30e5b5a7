"""The step-limit message tells a stiff problem from a long one (odelab.solvers.stiffness)."""

import math
import re

import numpy as np
import pytest

import odelab
from odelab.solvers.registry import get_method
from odelab.solvers.stiffness import diagnose_step_limit, stability_boundary, step_limit_advice

VDP = lambda t, y: [y[1], 1000 * (1 - y[0] ** 2) * y[1] - y[0]]  # noqa: E731
OSCILLATOR = lambda t, y: [y[1], -y[0]]  # noqa: E731


@pytest.mark.parametrize("method, boundary", [("euler", 2.0), ("heun", 2.0), ("midpoint", 2.0), ("rk3", 2.5127),
                                              ("ode23", 2.5127), ("rk4", 2.7853), ("ode45", 3.3066)])
def test_stability_boundaries_on_the_negative_real_axis(method, boundary):
    tab = get_method(method).tableau
    assert stability_boundary(tab.A, tab.b) == pytest.approx(boundary, abs=2e-3)


@pytest.mark.parametrize("method", ["ode23", "ode45", "RK45", "RK23", "DOP853"])
def test_a_long_non_stiff_run_is_called_long_with_the_budget_it_needs(method):
    sol = odelab.solve(OSCILLATOR, [0, 1e5], [1, 0], method=method, max_steps=2000)
    assert sol.status == "failed" and "probably stiff" not in sol.message and "ode15s" not in sol.message
    assert "after max_steps = 2000 steps: the run is long, not stiff: its steps are set by accuracy" in sol.message
    reached = float(re.search(r"stopped at t = (\S+) of", sol.message).group(1))
    needed = int(re.search(r"needs about ([\d,]+) steps", sol.message).group(1).replace(",", ""))
    assert needed == round(2000 * 1e5 / reached)
    budget = int(re.search(r"--max-steps (\d+)", sol.message).group(1))
    assert 1.2 * needed <= budget <= 1.3 * needed and f"raise max_steps to {budget:,} " in sol.message


def test_a_crude_tolerance_on_an_oscillator_is_at_the_stability_edge_but_not_stiff():
    sol = odelab.solve(OSCILLATOR, [0, 1e5], [1, 0], method="ode45", rtol=1e-1, max_steps=2000)
    assert "the run is long, not stiff" in sol.message
    assert "is no faster than the solution itself moves" in sol.message


@pytest.mark.parametrize("method", ["ode23", "ode45", "RK45"])
def test_van_der_pol_is_stiff_with_the_evidence(method):
    sol = odelab.solve(VDP, [0, 3000], [2, 0], method=method, max_steps=300)
    assert "the problem is probably stiff: use method 'ode15s'" in sol.message
    h_rho, limit = map(float, re.search(r"is (\S+), at \S+ stability limit (\S+)\.$", sol.message).groups())
    assert 0.5 * limit <= h_rho <= 1.3 * limit  # held at the edge of the stability region


def test_decay_below_the_tolerance_is_stiff():
    sol = odelab.solve(lambda t, y: [-1000 * y[0]], [0, 1e3], [1], method="ode45", max_steps=2000)
    assert "the problem is probably stiff" in sol.message


def test_the_diagnosis_itself():
    tab = get_method("ode45").tableau
    d = diagnose_step_limit(lambda t, y: np.array([y[1], -1e4 * y[1] - y[0]]), 0.0, [1.0, 0.0], 3e-4, tab.A, tab.b)
    assert d.rho == pytest.approx(1e4, rel=1e-4) and d.stiff and d.h_rho == pytest.approx(3.0, rel=1e-4)
    assert diagnose_step_limit(lambda t, y: 1 / 0, 0.0, [1.0], 0.1, tab.A, tab.b) is None
    assert diagnose_step_limit(OSCILLATOR, 0.0, [1.0, 0.0], math.nan, tab.A, tab.b) is None
    big = diagnose_step_limit(lambda t, y: -np.arange(1, 201) * y, 0.0, np.ones(200), 1e-3, tab.A, tab.b)
    assert big.rho == pytest.approx(200, rel=0.05)  # power iteration past 64 states


def test_without_an_indicator_the_message_offers_both_readings():
    text = step_limit_advice("ode45", None, 1000, 0.0, 1.0, 10.0)
    assert text == ("the problem may be stiff (then use method 'ode15s' (or 'ode23s' at crude tolerances), which "
                    "take a few hundred steps where explicit methods need millions; or raise max_steps), or the run "
                    "is just long (then raise max_steps: odelab run --max-steps N).")
