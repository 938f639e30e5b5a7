"""kind = "implicit": [system.residuals] with der(x), decic at load time, ode15i, and every refusal's message."""

import math

import numpy as np
import pytest

from odelab.exceptions import InputError
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_experiment
from odelab.store.results import read_run, write_case

# The prescribed syntax, MATLAB's ode15i example (Weissinger's equation)
WEISSINGER = """
[system]
kind = "implicit"
states = ["y"]
[system.residuals]              # each residual = 0; der(y) is y'
r = "t*y^2*der(y)^3 - y^3*der(y)^2 + t*(t^2 + 1)*der(y) - t^2*y"
[initial]
y = "sqrt(3/2)"
"der(y)" = 0                    # a guess; decic makes it consistent
[initial.fixed]                 # what decic may not change (default: the states)
y = true
[time]
start = 1
stop = 10
[solver]
method = "ode15i"
"""

ROBERTSON = """
title = "Robertson as an implicit DAE (MATLAB's ihb1dae)"
[system]
kind = "implicit"
states = ["y1", "y2", "y3"]
[system.residuals]
r1 = "der(y1) + 0.04*y1 - 1e4*y2*y3"
r2 = "der(y2) - 0.04*y1 + 1e4*y2*y3 + 3e7*y2^2"
r3 = "y1 + y2 + y3 - 1"
[initial]
y1 = 1
y2 = 0
y3 = 1e-3
[initial.fixed]
y3 = false
[time]
stop = 1e11
"""
ROBER_1E11 = np.array([0.2083340149701255e-7, 0.8333360770334713e-13, 0.9999999791665050])


def write(tmp_path, text, name="implicit.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("rtol", [1e-3, 1e-5, 1e-8])
def test_weissinger_file_within_the_tolerance_of_the_exact_solution(tmp_path, rtol):
    text = WEISSINGER + f'rtol = {rtol}\natol = {rtol * 1e-3}\n[exact]\ny = "sqrt(t^2 + 1/2)"\n'
    (r,) = run_experiment(write(tmp_path, text))
    assert r.status == "success" and r.case.problem.method == "ode15i" and r.reference_kind == "exact"
    exact = np.sqrt(r.t**2 + 0.5)
    units = np.abs(r.x[:, 0] - exact) / (rtol * exact + rtol * 1e-3)
    assert units.max() < 10, units.max()  # measured 0.68, 3.0, 2.8 (the exact partials by complex step)
    assert r.x[0, 0] == math.sqrt(1.5)


def test_decic_runs_at_load_time_and_resolved_toml_reproduces_the_run(tmp_path):
    exp = load_experiment(write(tmp_path, WEISSINGER))
    case = exp.cases[0]
    initial = case.config["initial"]  # the guesses, from which decic gives the same start again
    assert initial == {"y": math.sqrt(1.5), "der(y)": 0.0, "fixed": {"y": True, "der(y)": False}}
    (r,) = run_experiment(exp)
    slope = (r.x[1, 0] - r.x[0, 0]) / (r.t[1] - r.t[0])  # the first step is BDF1 from the consistent slope
    assert abs(slope - 1 / math.sqrt(1.5)) < 0.05
    folder = write_case(r, tmp_path / "runs")
    again = load_experiment(folder / "resolved.toml")
    (r2,) = run_experiment(again)
    np.testing.assert_array_equal(r2.x, r.x)
    assert read_run(folder)["method"] == "ode15i"


def test_ode15i_is_the_default_method_of_an_implicit_system(tmp_path):
    (r,) = run_experiment(write(tmp_path, WEISSINGER.replace('[solver]\nmethod = "ode15i"\n', "")))
    assert r.case.problem.method == "ode15i" and r.status == "success"


def test_robertson_file_against_the_bari_reference(tmp_path):
    # decic frees y3 (the guess 1e-3 goes to 0), the partials are exact (complex step), AbsTol 1e-12
    text = ROBERTSON + "[solver]\nrtol = 1e-6\natol = 1e-12\n"
    (r,) = run_experiment(write(tmp_path, text))
    assert r.status == "success" and r.t[-1] == 1e11
    assert r.case.config["initial"]["y3"] == 1e-3 and abs(r.x[0, 2]) < 1e-15  # the guess kept, decic's start used
    err = np.abs(r.x[-1] - ROBER_1E11) / (1e-6 * ROBER_1E11 + 1e-12)
    assert err.max() < 1, err  # measured 0.12 units, 5.2 digits
    assert np.abs(r.x.sum(axis=1) - 1).max() < 1e-12


def test_events_with_a_reset_restart_from_a_consistent_slope(tmp_path):
    # A ball written implicitly: at each bounce the reset turns v around and decic makes der(h) = v
    # consistent again (the slope carried from before the bounce would be -v).
    text = """
[parameters]
e = 0.8
[system]
kind = "implicit"
states = ["h", "v"]
[system.residuals]
kinematics = "der(h) - v"
gravity = "der(v) + 9.81"
[initial]
h = 10
v = 0
[time]
stop = 6
[solver]
rtol = 1e-8
atol = 1e-10
[events.floor]
when = "h"
direction = "falling"
reset = { v = "-e*v" }
"""
    (r,) = run_experiment(write(tmp_path, text))
    t1 = math.sqrt(2 * 10 / 9.81)
    exact = [t1 * (1 + 2 * 0.8 * (1 - 0.8**k) / (1 - 0.8)) for k in range(3)]
    assert r.status == "success" and len(r.events) == 3
    np.testing.assert_allclose([e["t"] for e in r.events], exact, rtol=0, atol=1e-6)


@pytest.mark.parametrize("text, key, message", [
    (WEISSINGER.replace('r = "t*y^2*der(y)^3 - y^3*der(y)^2 + t*(t^2 + 1)*der(y) - t^2*y"', 'r = "y^2 - t"'),
     "system.residuals", "[system.residuals] uses no der(): nothing is differentiated, so this is an algebraic system"),
    (WEISSINGER.replace("der(y)^3 -", "der(k)^3 -") + "[parameters]\nk = 2\n", "system.residuals.r",
     "`der(k)`: k is a parameter, not a state; der() takes a state (y)"),
    (WEISSINGER.replace("der(y)^3 -", "der(z)^3 -"), "system.residuals.r",
     "`der(z)`: z is not a name this system knows, not a state"),
    (WEISSINGER.replace("der(y)^3 -", "der(der(y))^3 -"), "system.residuals.r",
     "`der(der(x))` is a second derivative; write the system in first order"),
    (WEISSINGER.replace('states = ["y"]', 'states = ["y", "w"]').replace('y = true', 'y = true\n[initial.w]'),
     None, None),
    (WEISSINGER.replace('states = ["y"]', 'states = ["y", "w"]') + "", "system.residuals",
     "[system.residuals] has 1 residual for 2 states (y, w): an implicit system needs exactly one residual"),
    (WEISSINGER.replace('method = "ode15i"', 'method = "ode45"'), "solver.method",
     "`solver.method` is 'ode45', which solves x' = f(t, x); an implicit system (kind = \"implicit\", der() in its "
     "residuals) is solved by \"ode15i\""),
    (WEISSINGER.replace('kind = "implicit"\n', ""), "system.residuals",
     "[system.residuals] (F = 0 with der(x) for x') is given but the system is not implicit: add kind = \"implicit\""),
    (WEISSINGER.replace('"der(y)" = 0', '"der(y)" = 0\n[initial.fixed]\n"der(y)" = true').replace(
        '[initial.fixed]                 # what decic may not change (default: the states)\ny = true\n', ""),
     "initial.fixed", "decic can hold at most 1 of the 2 components of y0 and yp0 fixed"),
    (WEISSINGER.replace('"der(y)" = 0', '"der(w)" = 0'), "initial.der(w)", "`initial.\"der(w)\"`: 'w' is not a state"),
    (WEISSINGER.replace("y = true", "y = 1"), "initial.fixed.y", "`initial.fixed.y` must be true or false; got 1"),
    (WEISSINGER.replace("[solver]", '[linearize]\nstart = "initial"\n[solver]'), "linearize",
     "[linearize] is not available for an implicit system yet"),
    (WEISSINGER + '[reference]\nmethod = "high-accuracy"\n', "reference.method",
     "`reference.method` is 'high-accuracy', which odelab computes for x' = f(t, x)"),
])
def test_bad_implicit_files(tmp_path, text, key, message):
    if message is None:
        return
    with pytest.raises(InputError) as info:
        load_experiment(write(tmp_path, text))
    assert message in str(info.value), str(info.value)
    if key is not None:
        assert info.value.key == key


def test_an_index_2_file_is_refused_with_the_reason(tmp_path):
    text = """
[system]
kind = "implicit"
states = ["x", "z"]
[system.residuals]
a = "der(x) - z"
b = "x - sin(t)"
[initial]
x = 0
z = 1
[initial.fixed]
z = false
[time]
stop = 1
"""
    with pytest.raises(InputError) as info:
        load_experiment(write(tmp_path, text))
    assert info.value.key == "system.residuals"
    assert "ode15i solves ODEs and DAEs of index 1" in str(info.value) and "index 2 or higher" in str(info.value)


def test_initial_conditions_decic_cannot_make_consistent(tmp_path):
    text = """
[system]
kind = "implicit"
states = ["y"]
[system.residuals]
r = "der(y)^2 + y^2 + 1"
[initial]
y = 1
"der(y)" = 0.5
[time]
stop = 1
"""
    with pytest.raises(InputError) as info:
        load_experiment(write(tmp_path, text))
    assert "cannot be made consistent" in str(info.value) and "did not find consistent initial conditions" in \
        str(info.value)


def test_der_and_fixed_outside_an_implicit_system_are_refused(tmp_path):
    base = '[system]\nstates = ["y"]\n[system.equations]\ny = "-y"\n[initial]\ny = 1\n[time]\nstop = 1\n'
    with pytest.raises(InputError, match="`initial.\"der\\(y\\)\"` guesses an initial slope"):
        load_experiment(write(tmp_path, base.replace("y = 1\n", 'y = 1\n"der(y)" = 2\n')))
    with pytest.raises(InputError, match="\\[initial.fixed\\] says what decic may not change"):
        load_experiment(write(tmp_path, base + "[initial.fixed]\ny = true\n"))
    with pytest.raises(InputError, match="`der\\(x\\)` \\(a state's derivative\\) is allowed in \\[system.residuals\\]"):
        load_experiment(write(tmp_path, base.replace('y = "-y"', 'y = "-der(y)"')))
    with pytest.raises(InputError, match="`solver.method` is 'ode15i', which solves fully implicit systems"):
        load_experiment(write(tmp_path, base + '[solver]\nmethod = "ode15i"\n'))
