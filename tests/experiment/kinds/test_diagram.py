"""kind = "diagram" in experiment files: the lab's Figure 1 is Exercise 2's plant."""

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.exceptions import ExperimentError, InputError
from odelab.experiment.loader import load_experiment, merge
from odelab.run.runner import run_case

ROOT = Path(__file__).resolve().parents[3]
FIGURE1 = ROOT / "experiments" / "figure1.toml"
EXERCISE2 = ROOT / "experiments" / "exercise2.toml"


def test_figure1_matrices_equal_exercise2_exactly():
    fig = load_experiment(FIGURE1).cases[0].problem
    ex2 = load_experiment(EXERCISE2).cases[0].problem
    assert fig.states == ("position", "velocity") and fig.inputs == ("force",) and fig.outputs == ("y", "x")
    assert type(fig.system.model).__name__ == "StateSpace" and fig.reference == "lti"
    for name in "AB":
        np.testing.assert_array_equal(getattr(fig.system.model, name), getattr(ex2.system.model, name))
    np.testing.assert_array_equal(fig.system.model.C[:1], ex2.system.model.C)  # y = q x; the second row is x itself
    np.testing.assert_array_equal(fig.system.model.D[:1], ex2.system.model.D)
    assert fig.system.model.C[1].tolist() == [1.0, 0.0]


@pytest.mark.parametrize("kind", ["step", "sine", "ramp"])
def test_figure1_responses_match_exercise2_to_round_off(kind):
    fig = {c.name: c for c in load_experiment(FIGURE1).cases}[f"{kind}-ode45"]
    ex2 = {c.name: c for c in load_experiment(EXERCISE2).cases}[f"{kind}-ode45"]
    a, b = run_case(fig), run_case(ex2)
    assert a.stats == b.stats and np.array_equal(a.t, b.t)
    scale = np.max(np.abs(b.y))
    assert np.max(np.abs(a.y[:, 0] - b.y[:, 0])) <= 4 * np.finfo(float).eps * scale
    assert np.max(np.abs(a.x - b.x)) <= 4 * np.finfo(float).eps * np.max(np.abs(b.x))
    assert a.errors["y"].max_abs == pytest.approx(b.errors["y"].max_abs, rel=1e-9)


def test_a_case_that_changes_a_tables_type_replaces_it():
    base = {"blocks": {"force": {"type": "step", "time": 0, "final": 1}}}
    out = merge(base, {"blocks": {"force": {"type": "sine", "frequency": 0.2}}})
    assert out["blocks"]["force"] == {"type": "sine", "frequency": 0.2}
    assert merge(base, {"blocks": {"force": {"final": 2}}})["blocks"]["force"]["time"] == 0


def test_initial_overrides_block_initial_values_and_expressions_everywhere(tmp_path):
    text = FIGURE1.read_text().replace("[time]", "[initial]\nposition = \"1/k\"\n[time]")
    text = text.replace('final = 1 }', 'final = "k/k" }')
    path = tmp_path / "fig.toml"
    path.write_text(text)
    case = load_experiment(path).cases[0]
    assert case.problem.x0.tolist() == [1 / 3, 0.0]
    assert case.config["initial"] == {"position": 1 / 3, "velocity": 0.0}
    r = run_case(case)
    np.testing.assert_allclose(r.x[:, 0], 1 / 3, atol=1e-9)  # starts at rest at the step's equilibrium


def test_nonlinear_diagram_runs_with_a_high_accuracy_reference_and_its_resolved_file_reproduces(tmp_path):
    text = FIGURE1.read_text().replace('spring   = { type = "gain", gain = "k", input = "position" }',
                                       'spring   = { type = "fcn", expression = "k*u + 2*u^3", input = "position" }')
    path = tmp_path / "hard.toml"
    path.write_text(text)
    runner = CliRunner()
    result = runner.invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs"), "--json"])
    assert result.exit_code == 0, result.output
    first = json.loads(result.output)["experiments"][0]["cases"][0]
    resolved = tmp_path / "runs" / "hard" / first["name"] / "resolved.toml"
    again = runner.invoke(app, ["run", str(resolved), "--runs", str(tmp_path / "b"), "--json"])
    assert again.exit_code == 0, again.output
    second = json.loads(again.output)["experiments"][0]["cases"][0]
    assert second["stats"] == first["stats"] and second["max_abs_error"] == first["max_abs_error"]
    case = load_experiment(path).cases[0]
    assert case.problem.reference == "none"  # no closed form: "high-accuracy" must be asked for
    assert type(case.problem.system.model).__name__ == "NonlinearSystem"


def test_nonlinear_diagram_linearises_exactly(tmp_path):
    from odelab.analysis.linearize import linearize

    text = FIGURE1.read_text().replace('spring   = { type = "gain", gain = "k", input = "position" }',
                                       'spring   = { type = "fcn", expression = "k*u + 2*u^3", input = "position" }')
    path = tmp_path / "hard.toml"
    path.write_text(text)
    system = load_experiment(path).cases[0].problem.system.model
    lin = linearize(system, u0=[1.0])
    xbar = lin.operating_point.x[0]
    assert 3 * xbar + 2 * xbar**3 == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(lin.A, [[0, 1], [-(3 + 6 * xbar**2), -4]], rtol=1e-15, atol=0)


def test_diagram_errors_name_the_key():
    with pytest.raises(InputError) as info:
        load_experiment(ROOT / "tests" / "assets" / "bad" / "diagram_algebraic_loop.toml")
    assert info.value.key == "blocks.net" and info.value.source.endswith("diagram_algebraic_loop.toml")
    with pytest.raises(InputError) as info:
        load_experiment(ROOT / "tests" / "assets" / "bad" / "diagram_sum_signs.toml")
    assert info.value.key == "blocks.net.signs"


def test_every_source_type_in_a_file_is_the_signal_of_inputs(tmp_path):
    (tmp_path / "u.csv").write_text("t,u\n0,0\n1,2\n2,2\n")
    text = '''
[parameters]
a = 2
[system]
kind = "diagram"
outputs = { step = "s1", ramp = "s2", sine = "s3", pulse = "s4", table = "s5", expr = "s6", const = "s7", t = "s8", xo = "x" }
[blocks]
s1 = { type = "step", time = "a/2", final = "a" }
s2 = { type = "ramp", slope = "a", start = 0.5 }
s3 = { type = "sine", amplitude = "a", frequency = 3, phase = 0.1 }
s4 = { type = "pulse", amplitude = 1, period = "a", width = 0.5 }
s5 = { type = "table", file = "u.csv" }
s6 = { type = "expression", expression = "a*t^2" }
s7 = { type = "constant", value = "-a" }
s8 = { type = "clock" }
m  = { type = "mux", inputs = ["s1", "s2", "s3", "s4", "s5", "s6", "s7", "s8"] }
k  = { type = "gain", gain = [[1, 1, 1, 1, 1, 1, 1, 1]], input = "m" }
x  = { type = "integrator", input = "k" }
[time]
stop = 2
points = 41
'''
    path = tmp_path / "sources.toml"
    path.write_text(text)
    case = load_experiment(path).cases[0]
    assert case.problem.inputs == ("s1", "s2", "s3", "s4", "s5", "s6", "s7", "s8")
    # linear, but an expression source has no exact form: no automatic reference, as for [inputs]
    assert type(case.problem.system.model).__name__ == "StateSpace" and case.problem.reference == "none"
    r = run_case(case)
    t = r.t
    expected = {
        "step": np.where(t >= 1, 2.0, 0.0),
        "ramp": np.where(t >= 0.5, 2 * (t - 0.5), 0.0),
        "sine": 2 * np.sin(3 * t + 0.1),
        "pulse": np.where(np.mod(t, 2) < 1, 1.0, 0.0),  # width is a fraction of the period, as Simulink
        "table": np.minimum(2 * t, 2.0),
        "expr": 2 * t**2,
        "const": -2.0 * np.ones_like(t),
        "t": t,
    }
    series = r.series()
    for name, values in expected.items():
        np.testing.assert_allclose(series[name], values, rtol=0, atol=1e-12, err_msg=name)
    assert r.status == "success" and series["xo"][-1] > 0
