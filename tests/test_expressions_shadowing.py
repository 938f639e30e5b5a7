"""A parameter named like a constant (`e`, `pi`) shadows it, as a MATLAB variable does; a
parameter named like a function is still refused. The rule lives in
`odelab.expressions.functions.shadowed_constants`; every place that binds names asks it."""

import math
from pathlib import Path

import numpy as np
import pytest

from odelab.exceptions import InputError
from odelab.expressions import (
    check_identifier,
    compile_expression,
    compile_vector,
    evaluate_parameters,
    parse_expression,
)
from odelab.expressions.functions import shadowed_constants, shadowing_note
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case, run_experiment
from odelab.store.results import write_case

ROOT = Path(__file__).resolve().parents[1]
BALL = ROOT / "experiments" / "bouncing_ball.toml"
G, H0 = 9.81, 10.0


def bounce_times(e, count):
    """The ball's exact bounce times: t_k = t1 (1 + 2 e (1 - e^k) / (1 - e)), t1 = sqrt(2 h0 / g)."""
    t1 = math.sqrt(2 * H0 / G)
    return [t1 * (1 + 2 * e * (1 - e**k) / (1 - e)) for k in range(count)]


def test_the_rule_lives_in_one_function():
    assert shadowed_constants(["g", "e", "h0"]) == {"e"}
    assert shadowed_constants(["pi", "e", "x"]) == {"pi", "e"}
    assert shadowed_constants(["x", "sin", "t"]) == frozenset()
    assert shadowing_note(["e", "g"]) == ["parameter e shadows the constant e (2.718281828459045)"]


def test_parameters_shadow_constants_in_dependency_order():
    # k is listed before e and uses it: the dependency order sees e as a parameter, not Euler's number
    values = evaluate_parameters({"k": "2*e", "e": 0.8, "w": "2*pi"})
    assert values == {"k": 1.6, "e": 0.8, "w": 2 * math.pi}
    assert evaluate_parameters({"k": "2*e"}) == {"k": 2 * math.e}  # no parameter e: the constant
    assert evaluate_parameters({"pi": 3, "c": "pi*e"}) == {"pi": 3.0, "c": 3 * math.e}
    assert check_identifier("e", what="parameter") == "e"


def test_a_function_name_is_still_refused():
    with pytest.raises(InputError) as info:
        evaluate_parameters({"sin": 1.0}, source="f.toml")
    assert info.value.message == ("`parameters.sin`: `sin` is a function of the expression language; choose "
                                  "another name for this parameter")
    with pytest.raises(InputError, match="`e` is a constant"):  # a state is not a MATLAB variable here
        check_identifier("e", key="system.states[0]", what="state")


def test_the_python_compilers_read_the_shadowing_name():
    assert compile_expression("e*x", names=["x"])(x=2.0) == 2 * math.e
    assert compile_expression("e*x", names=["x", "e"])(x=2.0, e=0.8) == 1.6
    F = compile_vector(["-e*v", "pi + e"], args=["t", "v"], constants={"e": 0.8})
    np.testing.assert_array_equal(F(0.0, 10.0), [-8.0, math.pi + 0.8])
    Fc = compile_vector(["-e*v"], args=["t", "v"], constants={"e": 0.8}, complex_step=True)
    assert Fc(0.0, 10.0 + 1e-20j)[0].imag == pytest.approx(-0.8e-20, rel=1e-15)
    parsed = parse_expression("e*x + pi", names=["x", "e"])
    assert parsed.names == {"x", "e"} and parsed.constants == {"pi"}
    assert parse_expression("e*x + pi").names == {"x"}  # unbound: both are constants


def test_the_bouncing_ball_as_issue_10_wrote_it(tmp_path):
    text = BALL.read_text()
    assert 'e = 0.8 ' in text and 'reset = { v = "-e*v" }' in text
    (r,) = run_experiment(BALL)
    assert r.status == "success" and len(r.events) == 7
    # the bounce times of the closed form with e = 0.8 (with Euler's number e would be > 1: no bounces pile up)
    np.testing.assert_allclose([ev["t"] for ev in r.events], bounce_times(0.8, 7), rtol=0, atol=1e-12)
    assert all(ev["reset"]["v"] == -0.8 * ev["state"]["v"] for ev in r.events)
    assert "parameter e shadows the constant e (2.718281828459045)" in r.warnings
    folder = write_case(r, tmp_path / "runs")
    resolved = (folder / "resolved.toml").read_text()
    assert "# parameter e shadows the constant e (2.718281828459045); in this file's expressions it is the " \
           "parameter.\n" in resolved


def test_the_compiled_backend_reads_e_as_the_parameter():
    case = load_experiment(BALL).cases[0]
    python, compiled = run_case(case, backend="python"), run_case(case, backend="compiled")
    assert compiled.backend == "compiled" and compiled.stats == python.stats
    # the same steps; event times from the two engines agree to a few ulp of the times (~10)
    np.testing.assert_allclose([ev["t"] for ev in compiled.events], bounce_times(0.8, 7), rtol=0, atol=1e-12)
    for a, b in zip(compiled.events, python.events):
        assert abs(a["t"] - b["t"]) <= 64 * np.finfo(float).eps * 10


def test_a_sweep_over_e(tmp_path):
    path = tmp_path / "ball.toml"
    path.write_text(BALL.read_text() + '\n[sweep]\n"parameters.e" = [0.5, 0.7, 0.8]\n')
    results = run_experiment(path)
    assert len(results) == 3
    for r, e, count in zip(results, (0.5, 0.7, 0.8), (None, None, 7)):
        assert r.status == "success"
        assert r.case.problem.parameters["e"] == e
        times = [ev["t"] for ev in r.events]
        # with e = 0.5 the bounces pile up at t1 (1 + e) / (1 - e) = 4.28 s: a Zeno cascade, stopped at max_events
        expected = bounce_times(e, len(times))
        np.testing.assert_allclose(times[:12], expected[:12], rtol=0, atol=1e-11)
        if count is not None:
            assert len(times) == count


def test_a_sweep_says_the_shadowing_once_not_once_a_case(tmp_path):
    from typer.testing import CliRunner

    from odelab.cli import app

    path = tmp_path / "ball.toml"
    path.write_text(BALL.read_text() + '\n[sweep]\n"parameters.e" = [0.5, 0.7, 0.8]\n')
    out = CliRunner().invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs")]).output
    assert out.count("parameter e shadows the constant e") == 1
    assert "every case: note: parameter e shadows the constant e (2.718281828459045)" in out
    assert "e=0.5: note: the case stopped at t = 4.28351" in out  # a case's own note keeps its case


def test_pi_shadowed_in_an_experiment(tmp_path):
    path = tmp_path / "pi.toml"
    path.write_text("""
[parameters]
pi = 3                       # a MATLAB user's variable pi
[system]
states = ["x"]
equations = { x = "-pi*x" }
[initial]
x = 1
[time]
stop = 1
[exact]
x = "exp(-pi*t)"
""")
    (r,) = run_experiment(path)
    assert r.status == "success"
    assert r.x[-1, 0] == pytest.approx(math.exp(-3.0), rel=1e-5)  # ode45's default rtol 1e-3 on exp(-3 t)
    assert r.errors["x"].max_rel < 1e-3
    assert "parameter pi shadows the constant pi (3.141592653589793)" in r.warnings


def test_fit_of_a_parameter_named_e(tmp_path):
    from odelab.experiment.fit import fit_experiment

    t = np.arange(0, 61, 2.0)
    T = 21 + (88 - 21) * np.exp(-0.045 * t)  # exact data: the fit finds e = 0.045 to its tolerance
    (tmp_path / "cooling.csv").write_text("minutes,temperature\n" + "".join(f"{a:g},{b:.12g}\n" for a, b in zip(t, T)))
    path = tmp_path / "exp.toml"
    path.write_text("""
[parameters]
e = 0.1                     # the cooling rate, named e on purpose
T0 = 88
T_room = 21
[system]
states = ["T"]
equations = { T = "-e*(T - T_room)" }
[initial]
T = "T0"
[time]
stop = 60
[data]
file = "cooling.csv"
time = "minutes"
columns = { T = "temperature" }
[fit]
parameters = { e = { lower = 0 } }
[solver]
rtol = 1e-10
atol = 1e-10
""")
    fit = fit_experiment(load_experiment(path)).cases[0].problem.fit
    assert fit["status"] == "converged"
    assert fit["parameters"]["e"]["estimate"] == pytest.approx(0.045, rel=1e-6)


def test_networks_symbolic_layer_reads_e_as_a_symbol():
    sp = pytest.importorskip("sympy")
    from odelab.systems.network.symbolic import to_sympy

    x, e = sp.Symbol("x"), sp.Symbol("e")
    assert to_sympy(parse_expression("e*x"), {"x": x}) == sp.E * x
    assert to_sympy(parse_expression("e*x"), {"x": x, "e": e}) == e * x
    assert to_sympy(parse_expression("pi*x"), {"x": x}) == sp.pi * x
