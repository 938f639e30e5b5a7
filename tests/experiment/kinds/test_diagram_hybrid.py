"""Diagrams with switching and discrete blocks in experiment files: the keys, the notes, the errors."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.exceptions import InputError
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case

EPS = np.finfo(float).eps

RAMP_SAT = """
title = "a ramp into a saturation"
[system]
kind = "diagram"
outputs = { y = "sat", q = "acc" }
[blocks]
r = { type = "ramp", slope = 1 }
sat = { type = "saturation", upper = 0.5, lower = -0.5, input = "r"SAT_EXTRA }
acc = { type = "integrator", input = "sat" }
[time]
stop = 2
[solver]
rtol = 1e-3
SOLVER_EXTRA
[exact]
q = "min(t, 0.5)^2/2 + 0.5*max(t - 0.5, 0)"
"""


def write(tmp_path, sat="", solver=""):
    path = tmp_path / "sat.toml"
    path.write_text(RAMP_SAT.replace("SAT_EXTRA", sat).replace("SOLVER_EXTRA", solver))
    return path


def test_the_crossing_is_located_and_the_run_says_how_many_per_block(tmp_path):
    result = run_case(load_experiment(write(tmp_path)).cases[0])
    assert result.status == "success"
    assert "zero crossings located: sat (saturation) 1" in result.warnings
    assert result.errors["q"].max_abs <= 16 * EPS  # exact on each piece: the corner is not stepped over
    runner = CliRunner()
    out = runner.invoke(app, ["run", str(write(tmp_path)), "--runs", str(tmp_path / "runs")])
    assert out.exit_code == 0 and "zero crossings located: sat (saturation) 1" in out.output


@pytest.mark.parametrize("sat, solver", [(", zero_crossing = false", ""), ("", "zero_crossing = false")])
def test_zero_crossing_false_on_the_block_or_under_solver_steps_over_the_corner(tmp_path, sat, solver):
    result = run_case(load_experiment(write(tmp_path, sat, solver)).cases[0])
    assert result.status == "success" and not any("zero crossings" in w for w in result.warnings)
    assert result.errors["q"].max_abs > 1e3 * EPS


def test_a_bad_zero_crossing_value_names_the_key(tmp_path):
    with pytest.raises(InputError) as info:
        load_experiment(write(tmp_path, ', zero_crossing = "no"'))
    assert info.value.key == "blocks.sat.zero_crossing" and "true or false" in info.value.message
    out = CliRunner().invoke(app, ["run", str(write(tmp_path, ', zero_crossing = "no"'))])
    assert out.exit_code == 2 and "Traceback" not in out.output


def test_a_relay_thermostat_in_a_file_and_its_json(tmp_path):
    path = tmp_path / "relay.toml"
    path.write_text("""
[system]
kind = "diagram"
outputs = { x = "x" }
[blocks]
x = { type = "integrator", input = "r" }
r = { type = "relay", on_point = 1, off_point = -1, on_value = -2, off_value = 1, input = "x" }
[time]
stop = 6
""")
    out = CliRunner().invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs"), "--json"])
    assert out.exit_code == 0, out.output
    case = json.loads(out.output)["experiments"][0]["cases"][0]
    assert "zero crossings located: r (relay) 4" in case["warnings"]


ROOT = __import__("pathlib").Path(__file__).resolve().parents[3]


def test_the_shipped_speed_controller_is_c2ds_closed_loop_at_the_samples():
    import control as ct

    case = load_experiment(ROOT / "experiments" / "speed_control.toml").cases[0]
    result = run_case(case)
    assert result.status == "success"
    p = case.problem.parameters
    Ts = p["Ts"]
    plant = ct.tf([p["K"]], [p["J"] * p["L"], p["J"] * p["R"] + p["b"] * p["L"], p["b"] * p["R"] + p["K"] ** 2])
    z = ct.tf([1, 0], [1], Ts)
    P, I, D, N = 100, 200, 10, 20
    C = P + I * Ts / (z - 1) + D * N * (z - 1) / (z - 1 + N * Ts)
    n = 31
    expect = np.squeeze(ct.step_response(ct.feedback(C * ct.c2d(plant, Ts, "zoh"), 1), T=np.arange(n) * Ts).outputs)
    speed = result.series()["speed"]
    got = np.array([speed[np.flatnonzero(result.t == k * Ts)[-1]] for k in range(n)])
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-7)  # the solver's rtol 1e-8 on a peak of 1.3
    assert any(w.startswith("sample hits: 31") for w in result.warnings)


def test_the_shipped_thermostat_switches_at_the_closed_form_times():
    case = load_experiment(ROOT / "experiments" / "thermostat.toml").cases[0]
    result = run_case(case)
    heater = result.series()["heater"]
    jumps = result.t[1:][np.diff(heater) != 0]
    tau = 10.0
    heat, cool = tau * np.log(10.5 / 9.5), tau * np.log(15.5 / 14.5)
    expect = [tau * np.log(15 / 9.5)]
    while len(expect) < jumps.size:
        expect.append(expect[-1] + (cool if len(expect) % 2 else heat))
    assert jumps.size == 10
    # located on ode45's interpolant of a solution computed at rtol 1e-6
    np.testing.assert_allclose(jumps, expect, rtol=0, atol=1e-5)


LOOP = """
[system]
kind = "diagram"
outputs = { y = "y", q = "q" }
POLICY
[parameters]
a = 3
[blocks]
u  = { type = "step", time = 0, final = 2 }
y  = { type = "sum", signs = "+-", inputs = ["u", "ay"] }
ay = { type = "gain", gain = "a", input = "y" }
q  = { type = "integrator", input = "y" }
[time]
stop = 1
"""


def test_an_algebraic_loop_in_a_file_is_solved_and_named_once_or_refused(tmp_path):
    path = tmp_path / "loop.toml"
    path.write_text(LOOP.replace("POLICY", ""))
    result = run_case(load_experiment(path).cases[0])
    notes = [w for w in result.warnings if w.startswith("algebraic loop y -> ay -> y solved by Newton")]
    assert result.status == "success" and len(notes) == 1
    np.testing.assert_allclose(result.series()["y"], 2 / (1 + 3), rtol=8 * EPS)
    assert result.reference_kind == "lti" and result.errors["q"].max_abs <= 1e-14
    path.write_text(LOOP.replace("POLICY", 'algebraic_loops = "error"'))
    with pytest.raises(InputError) as info:
        load_experiment(path)
    assert info.value.key == "blocks.y" and "algebraic loop: y -> ay -> y" in info.value.message
    path.write_text(LOOP.replace("POLICY", 'algebraic_loops = "loud"'))
    out = CliRunner().invoke(app, ["run", str(path)])
    assert out.exit_code == 2 and "algebraic_loops" in out.output


def test_a_lookup_table_from_a_csv_file_and_a_table_input_with_its_interpolation(tmp_path):
    (tmp_path / "curve.csv").write_text("u, y\n0, 1\n0.5, -0.5\n1.2, 2\n2, 0.3\n3, 0.8\n")
    path = tmp_path / "lut.toml"
    path.write_text("""
[system]
kind = "diagram"
outputs = { y = "lut", i = "acc" }
[blocks]
r   = { type = "ramp", slope = 1 }
lut = { type = "lookup-table", file = "curve.csv", interpolation = "flat", input = "r" }
acc = { type = "integrator", input = "lut" }
[time]
stop = 4
""")
    result = run_case(load_experiment(path).cases[0])
    assert result.status == "success"
    assert abs(result.series()["i"][-1] - (0.5 * 1 - 0.5 * 0.7 + 2 * 0.8 + 0.3 * 1 + 0.8 * 1)) <= 1e-13
    (tmp_path / "u.csv").write_text("t, u\n0, 0\n1, 1\n2, 0\n")
    path = tmp_path / "held.toml"
    path.write_text("""
[system]
states = ["x"]
inputs = ["u"]
equations = { x = "u" }
[inputs.u]
type = "table"
file = "u.csv"
interpolation = "flat"
[initial]
x = 0
[time]
stop = 3
""")
    result = run_case(load_experiment(path).cases[0])
    assert abs(result.series()["x"][-1] - 1.0) <= 1e-12  # u = 0 on [0, 1), 1 on [1, 2), 0 after
    path.write_text(path.read_text().replace('interpolation = "flat"', 'interpolation = "spline"'))
    with pytest.raises(InputError) as info:
        load_experiment(path)
    assert info.value.key == "inputs.u.interpolation" and "cubic-spline" in info.value.message


def test_linearising_a_diagram_with_discrete_blocks_is_refused_with_the_reason(tmp_path):
    path = tmp_path / "dl.toml"
    text = (ROOT / "experiments" / "speed_control.toml").read_text() + "\n[analysis]\nstep_info = true\n"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        load_experiment(path)
    assert info.value.key == "analysis" and "`sampler` (zero-order-hold) is discrete" in info.value.message


def test_events_of_a_diagram_with_a_saturation_are_located_with_its_crossings(tmp_path):
    # x'' = -sat(x), |sat| <= 0.5, from x = 2 at rest: x = 2 - t^2/4 until x = 0.5 at t1 = sqrt(6),
    # then x = 0.5 cos(s) - v1 sin(s) with v1 = sqrt(6)/2, zero at s = atan(0.5 / v1): the event
    path = tmp_path / "ev.toml"
    path.write_text("""
[system]
kind = "diagram"
outputs = { x = "x" }
[blocks]
x    = { type = "integrator", input = "v", initial = 2 }
v    = { type = "integrator", input = "push" }
sat  = { type = "saturation", lower = -0.5, upper = 0.5, input = "x" }
push = { type = "gain", gain = -1, input = "sat" }
[time]
stop = 10
[solver]
rtol = 1e-10
atol = 1e-12
[events.zero]
when = "x"
direction = "falling"
terminal = true
""")
    result = run_case(load_experiment(path).cases[0])
    assert result.status == "success", result.message
    t1 = np.sqrt(6.0)
    expect = t1 + np.arctan(0.5 / (t1 / 2))
    assert len(result.events) == 1 and abs(result.events[0]["t"] - expect) <= 1e-8
    assert abs(result.t[-1] - expect) <= 1e-8
    assert "zero crossings located: sat (saturation) 1" in result.warnings


RATE_LIMITED = """
title = "a step through a rate limiter into an integrator"
[system]
kind = "diagram"
outputs = { y = "rl", q = "acc" }
[blocks]
u   = { type = "step", time = 1, final = 3 }
rl  = { type = "rate-limiter", input = "u", rising = 2, falling = -1 }
acc = { type = "integrator", input = "rl" }
[time]
stop = 4
[solver]
rtol = 1e-3
EXTRA
[exact]
y = "min(max(2*(t - 1), 0), 3)"
q = "(t > 1)*(min(t - 1, 1.5)^2 + 3*max(t - 2.5, 0))"
"""


def test_a_rate_limiter_in_a_file_is_exact_and_named_when_it_keeps_the_run_on_python(tmp_path, monkeypatch):
    path = tmp_path / "rl.toml"
    path.write_text(RATE_LIMITED.replace("EXTRA", 'backend = "auto"'))
    result = run_case(load_experiment(path).cases[0])
    assert result.status == "success", result.message
    assert "zero crossings located: rl (rate-limiter) 1" in result.warnings
    assert result.errors["y"].max_abs <= 64 * EPS and result.errors["q"].max_abs <= 64 * EPS
    # backend = "auto" on a run long enough to compile says which block kept it on Python
    monkeypatch.setattr("odelab.solvers.compiled.AUTO_STEPS", 5)
    result = run_case(load_experiment(path).cases[0])
    assert "ran on the Python engine, not the compiled one: its block `rl` (rate-limiter) switches with memory" \
        in " ".join(result.warnings)
    path.write_text(RATE_LIMITED.replace("EXTRA", 'backend = "compiled"'))
    out = CliRunner().invoke(app, ["run", str(path), "--no-store"])
    assert out.exit_code == 2 and "`rl` (rate-limiter)" in out.output and "Traceback" not in out.output


def test_a_bad_slew_rate_or_an_analysis_of_a_rate_limiter_is_refused_with_the_fix(tmp_path):
    path = tmp_path / "rl.toml"
    path.write_text(RATE_LIMITED.replace("EXTRA", "").replace("falling = -1", "falling = 1"))
    with pytest.raises(InputError) as info:
        load_experiment(path)
    assert info.value.key == "blocks.rl.falling" and "must be negative" in info.value.message
    path.write_text(RATE_LIMITED.replace("EXTRA", "") + "\n[analysis]\npoles = true\n")
    with pytest.raises(InputError) as info:
        load_experiment(path)
    assert info.value.key == "analysis" and "replace it by a gain of 1" in info.value.message
