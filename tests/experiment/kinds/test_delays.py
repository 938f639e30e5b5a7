"""Delay equations in experiment files: lag(x, tau) in [system.equations], [history], dde23."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.exceptions import ExperimentError, InputError
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_experiment

ROOT = Path(__file__).resolve().parents[3]
EXAMPLE = ROOT / "experiments" / "delayed_feedback.toml"
EPS = np.finfo(float).eps

BASE = """
[parameters]
tau = 1
[system]
states = ["y"]
[system.equations]
y = "-lag(y, tau)"
[initial]
y = 1
[time]
stop = 5
points = 51
"""


def write(tmp_path, text, name="delay.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_shipped_example_against_its_exact_solution():
    (r,) = run_experiment(EXAMPLE)
    assert r.status == "success" and r.case.problem.method == "dde23"
    assert r.reference_kind == "exact"
    # dde23 at rtol 1e-3: the error is a fraction of the tolerance (measured 6.0e-5, |y| <= 1)
    assert r.errors["y"].max_abs <= 0.2 * 1e-3
    # the [exact] text in the file is the exact solution (the test suite's fractions): y(5) = 19/120
    assert abs(r.reference["y"][-1] - 19 / 120) <= 100 * EPS
    assert r.t.size == 101 and r.t[-1] == 5.0


@pytest.mark.parametrize("method_line", ["", 'method = "auto"', 'method = "dde23"', 'method = "DDE23"'])
def test_auto_and_the_default_pick_dde23(tmp_path, method_line):
    path = write(tmp_path, BASE + f"[solver]\n{method_line}\nrtol = 1e-6\natol = 1e-9\n")
    (r,) = run_experiment(path)
    assert r.status == "success" and r.case.problem.method == "dde23"
    y5 = float(r.x[-1, 0])
    assert abs(y5 - 19 / 120) <= 0.5e-6


@pytest.mark.parametrize("method", ["ode45", "ode23", "ode15s", "rk4"])
def test_other_methods_are_refused_naming_dde23(tmp_path, method):
    path = write(tmp_path, BASE + f'[solver]\nmethod = "{method}"\n')
    with pytest.raises(ExperimentError, match="dde23") as info:
        load_experiment(path)
    assert info.value.key == "solver.method" and method in str(info.value)
    out = CliRunner().invoke(app, ["validate", str(path)])
    assert out.exit_code == 2 and "solver.method" in out.output and "Traceback" not in out.output


def test_history_expression_of_t(tmp_path):
    # history 1 - t: on [0, 1] y' = -(1 - (t - 1)) = t - 2, so y = 1 - 2t + t^2/2 (a quadratic: exact)
    text = BASE.replace("stop = 5", "stop = 1") + '[history]\ny = "1 - t"\n'
    (r,) = run_experiment(write(tmp_path, text))
    t = r.t
    assert np.max(np.abs(r.x[:, 0] - (1 - 2 * t + t**2 / 2))) <= 50 * EPS


def test_history_that_differs_from_the_initial_value(tmp_path):
    # y(0) = 2 with the history 1: y = 2 - t on [0, 1] (the solution jumps at t0, as MATLAB's InitialY)
    text = BASE.replace("stop = 5", "stop = 1").replace("[initial]\ny = 1", "[initial]\ny = 2") + "[history]\ny = 1\n"
    (r,) = run_experiment(write(tmp_path, text))
    assert np.max(np.abs(r.x[:, 0] - (2 - r.t))) <= 50 * EPS


def test_two_states_and_a_lag_from_parameters(tmp_path):
    # x' = -lag(x, 2a) with a = 0.5, and v' = x: v = t - t^2/2 on [0, 1], exact
    text = """
[parameters]
a = 0.5
[system]
states = ["x", "v"]
[system.equations]
x = "-lag(x, 2*a)"
v = "x"
[initial]
x = 1
v = 0
[time]
stop = 1
points = 11
"""
    (r,) = run_experiment(write(tmp_path, text))
    t = r.t
    assert np.max(np.abs(r.x[:, 1] - (t - t**2 / 2))) <= 50 * EPS


@pytest.mark.parametrize("equation, key, fragment", [
    ("-lag(y, -1)", "system.equations.y", "positive constant"),
    ("-lag(y, 0)", "system.equations.y", "positive constant"),
    ("-lag(y, t)", "system.equations.y", "constant lags only"),
    ("-lag(y, y)", "system.equations.y", "constant lags only"),
    ("-lag(y)", "system.equations.y", "takes 2 arguments"),
    ("-lag(2*y, 1)", "system.equations.y", "first argument of `lag` is a state"),
    ("-lag(y, taau)", "system.equations.y", "did you mean `tau`"),
])
def test_bad_lags_name_the_key_and_the_fix(tmp_path, equation, key, fragment):
    path = write(tmp_path, BASE.replace('y = "-lag(y, tau)"', f'y = "{equation}"'))
    with pytest.raises(InputError) as info:
        load_experiment(path)
    assert info.value.key == key and fragment in str(info.value)
    out = CliRunner().invoke(app, ["validate", str(path)])
    assert out.exit_code == 2 and path.name in out.output and "Traceback" not in out.output


def test_history_mistakes(tmp_path):
    with pytest.raises(InputError, match="Did you mean 'y'") as info:
        load_experiment(write(tmp_path, BASE + '[history]\nyy = 1\n'))
    assert info.value.key == "history.yy"
    with pytest.raises(ExperimentError, match="no equation uses") as info:
        load_experiment(write(tmp_path, BASE.replace("-lag(y, tau)", "-y") + "[history]\ny = 1\n"))
    assert info.value.key == "history"
    with pytest.raises(ExperimentError, match="no delayed states"):
        load_experiment(write(tmp_path, BASE.replace("-lag(y, tau)", "-y") + '[solver]\nmethod = "dde23"\n'))


def test_lag_elsewhere_is_refused(tmp_path):
    with pytest.raises(InputError, match=r"allowed in \[system.equations\] only") as info:
        load_experiment(write(tmp_path, BASE + '[exact]\ny = "lag(y, 1)"\n'))
    assert info.value.key == "exact.y"


def test_what_delay_systems_cannot_do_yet_is_said(tmp_path):
    with pytest.raises(ExperimentError, match="high-accuracy"):
        load_experiment(write(tmp_path, BASE + '[reference]\nmethod = "high-accuracy"\n'))
    with pytest.raises(ExperimentError, match="restarting delay equations") as info:
        load_experiment(write(tmp_path, BASE + '[events.zero]\nwhen = "y"\nterminal = true\nreset = { y = 1 }\n'))
    assert info.value.key == "events.zero.reset"


def test_events_on_delay_equations(tmp_path):
    # y = 1 - t on [0, 1]: y = 0.5 at t = 0.5 exactly; y rises through 0 where the quartic of [3, 4]
    # (t^4 - 16 t^3 + 90 t^2 - 204 t + 149)/24 vanishes, t = 3.3459398..., which stops the run
    root = min(r.real for r in np.roots([1, -16, 90, -204, 149]) if abs(r.imag) < 1e-12 and 3 < r.real < 4)
    text = BASE + """[solver]
rtol = 1e-8
atol = 1e-11
[events.half]
when = "y - 0.5"
direction = "falling"
[events.zero]
when = "y"
direction = "rising"
terminal = true
"""
    (r,) = run_experiment(write(tmp_path, text))
    assert r.status == "success" and [e["name"] for e in r.events] == ["half", "zero"]
    assert abs(r.events[0]["t"] - 0.5) <= 1e-12
    assert abs(r.events[1]["t"] - root) <= 1e-6  # the solution's error at rtol 1e-8 over its slope 0.16
    assert r.t[-1] == r.events[1]["t"]


def test_a_parameter_named_lag_still_works(tmp_path):
    text = BASE.replace("tau = 1", "tau = 1\nlag = 2").replace('"-lag(y, tau)"', '"-lag*y"')
    (r,) = run_experiment(write(tmp_path, text))
    assert r.case.problem.method == "ode45" and abs(r.x[-1, 0] - np.exp(-10)) < 1e-5


def test_explain_history():
    out = CliRunner().invoke(app, ["explain", "history"])
    assert out.exit_code == 0 and "t <= t0" in out.output and "dde23" in out.output
