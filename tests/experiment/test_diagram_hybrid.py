"""Diagrams with switching and discrete blocks in experiment files: the keys, the notes, the errors."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.exceptions import InputError
from odelab.experiment.loader import load_experiment
from odelab.experiment.runner import run_case

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
