"""The registry: every MATLAB solver name, suggestions that know the suite, honest mappings."""

import numpy as np
import pytest

import odelab
from odelab.solvers.registry import METHODS, get_method

SUITE = ("ode23", "ode45", "ode15s", "ode23s", "ode23t", "ode23tb", "ode113", "ode78", "ode89")


@pytest.mark.parametrize("name", SUITE)
def test_every_matlab_name_runs_as_method_and_function(name):
    decay = lambda t, y: -y  # noqa: E731
    by_function = getattr(odelab, name)(decay, [0, 1], 1.0, RelTol=1e-6, AbsTol=1e-9)
    by_name = odelab.solve(decay, [0, 1], 1.0, method=name, rtol=1e-6, atol=1e-9)
    assert by_function.success and by_function.method == name
    np.testing.assert_array_equal(by_function.y, by_name.y)
    # global error in units of rtol; the second-order ode23s, ode23t, ode23tb: about 22, 34, 22 units here
    units = {"ode23s": 30, "ode23t": 40, "ode23tb": 30}.get(name, 10)
    assert abs(by_function.y[-1, 0] - np.exp(-1)) < units * 1e-6 * np.exp(-1)
    m = METHODS[name]
    if m.kind == "implicit":
        assert by_function.stats.npds >= 1 and by_function.stats.nsolves >= by_function.stats.nsteps


@pytest.mark.parametrize("typed, meant", [
    ("ode15", "ode15s"), ("ODE15", "ode15s"), ("ode113s", "ode113"), ("ode23st", "ode23s"),
    ("ode46", "ode45"), ("trbdf2", "ode23tb"), ("rosenbrock", "ode23s"), ("ode87", "ode78"),
])
def test_did_you_mean_knows_the_suite(typed, meant):
    with pytest.raises(ValueError, match=rf"`method` is '{typed}', which is not a method odelab knows\. "
                                         rf"Did you mean '{meant}'\?"):
        get_method(typed)


def test_step_limit_on_a_stiff_problem_names_the_stiff_solvers():
    vdp = lambda t, y: [y[1], 1000 * (1 - y[0] ** 2) * y[1] - y[0]]  # noqa: E731
    for method in ("ode23", "ode45", "RK45"):
        sol = odelab.solve(vdp, [0, 3000], [2, 0], method=method, max_steps=300)
        assert sol.status == "failed"
        assert "the problem is probably stiff: use method 'ode15s' (or 'ode23s' at crude tolerances)" in sol.message
    stiff = odelab.ode15s(vdp, [0, 3000], [2, 0], max_steps=10)
    assert "ode15s" not in stiff.message.split("steps:")[1] and "raise max_steps" in stiff.message


def test_orders_are_honest():
    assert METHODS["LSODA"].order_label == "Adams 1-12 / BDF 1-5"
    assert METHODS["ode15s"].order_label == "1-5" and METHODS["ode45"].order_label == "5(4)"
    assert METHODS["ode15s"].kind_label == "stiff, DAE" and METHODS["ode113"].kind_label == "non-stiff"
