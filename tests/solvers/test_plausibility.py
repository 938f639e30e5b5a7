"""Results that cannot be right are said, not reported as plain success (solvers/plausibility.py)."""

import warnings

import numpy as np
import pytest

import odelab
from odelab.exceptions import SolverWarning
from odelab.solvers.plausibility import PREFIX, implausible


def rober(t, y):
    return [-0.04 * y[0] + 1e4 * y[1] * y[2], 0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2, 3e7 * y[1] ** 2]


def test_robertson_lost_at_a_crude_tolerance_is_flagged():
    # ode15s at RelTol 0.1 on Robertson: "success" with y1 = -1.9e7 (the true y1 is 5.2e-8)
    with pytest.warns(SolverWarning, match=PREFIX):
        sol = odelab.solve(rober, [0, 4e10], [1, 0, 0], method="ode15s", rtol=0.1, atol=1e-3)
    assert sol.status == "success" and sol.y[:, 0].min() < -1e6
    assert any(w.startswith(PREFIX) and "times the initial scale" in w for w in sol.warnings)


def test_a_negative_amount_in_a_closed_system_is_flagged():
    # the ode23t result the issue reported: y2 on a spurious branch below zero, y1 + y2 + y3 = 1 kept
    t = np.array([0.0, 1.0, 2.0])
    y = np.array([[1.0, 0.0, 0.0], [0.5, 3e-5, 0.49997], [0.6, -4e-6, 0.400004]])
    note = implausible(t, y, y[0], [1e-8, 1e-12, 1e-8], "ode23t")
    assert note.startswith(PREFIX) and "y2 = -4e-06 at t = 2" in note and "conserves the sum" in note
    # the same undershoot within the tolerances is the error control at work: nothing to say
    y[2, 1] = -5e-11
    y[2, 2] = 0.4 + 5e-11
    assert implausible(t, y, y[0], [1e-8, 1e-12, 1e-8], "ode23t") is None


@pytest.mark.parametrize("method", ["ode15s", "ode23s", "ode23t", "ode23tb", "Radau"])
def test_correct_runs_are_not_flagged(method):
    with warnings.catch_warnings():
        warnings.simplefilter("error", SolverWarning)
        vdp = odelab.solve(lambda t, y: [y[1], 1000 * (1 - y[0] ** 2) * y[1] - y[0]], [0, 3000], [2, 0],
                           method=method)
        # a decaying oscillation crossing zero, whose components' sum happens to start at zero slope
        osc = odelab.solve(lambda t, y: [y[1], -y[0] - 0.1 * y[1]], [0, 60], [1, 1], method=method)
        rob = odelab.solve(rober, [0, 4e10], [1, 0, 0], method=method, rtol=1e-4, atol=1e-10)
    assert not vdp.warnings and not osc.warnings and not rob.warnings
    assert osc.y[:, 0].min() < -0.5  # it does go negative: the sign check is off for it
