"""Solver faults through the CLI: status "failed" or a warning that explains, partial results kept, exit 1."""

import json

import pytest
from typer.testing import CliRunner

from odelab.cli import app

runner = CliRunner()

HEADER = '[system]\nstates = ["y"]\nfunction = "rhs.py:rhs"\n[initial]\ny = 1\n[time]\nstop = 2\n'


def run_function(tmp_path, body, extra=""):
    (tmp_path / "rhs.py").write_text("import math\n\ndef rhs(t, y):\n" + body)
    (tmp_path / "exp.toml").write_text(HEADER + extra)
    result = runner.invoke(app, ["run", str(tmp_path / "exp.toml"), "--runs", str(tmp_path / "runs")])
    record_path = tmp_path / "runs" / "exp" / "ode45" / "result.json"
    record = json.loads(record_path.read_text()) if record_path.exists() else None
    return result, record


@pytest.mark.parametrize(
    "body, message, min_points",
    [
        ("    return [float('nan') if t > 1 else -y[0]]\n", "the derivative became NaN or infinite", 10),
        ("    return [math.inf if t > 1 else -y[0]]\n", "the derivative became NaN or infinite", 10),
        ("    if t > 1:\n        raise RuntimeError('sensor table ends at t = 1')\n    return [-y[0]]\n",
         "raised RuntimeError: sensor table ends at t = 1", 10),
        ("    return [-y[0], 1.0]\n", "the system function returned 2 values (shape (2,)) but the state has 1", 1),
        ("    return [y[0] ** 2]\n", "step size fell below 1.8e-15", 20),
    ],
    ids=["nan", "inf", "raises", "wrong-shape", "blow-up"],
)
def test_faults_fail_with_a_message_and_keep_the_partial_result(tmp_path, body, message, min_points):
    result, record = run_function(tmp_path, body)
    assert result.exit_code == 1, result.output
    assert "FAILED" in result.output and message in result.output
    assert "Traceback" not in result.output
    assert record["status"] == "failed" and message in record["message"]
    assert record["points"] >= min_points


def test_blow_up_says_where_and_why(tmp_path):
    result, record = run_function(tmp_path, "    return [y[0] ** 2]\n")
    assert "at t = 0.9999" in record["message"]  # y = 1/(1 - t) blows up at t = 1
    assert "unbounded" in record["message"]


def test_impossible_tolerance_is_raised_with_a_warning(tmp_path):
    result, record = run_function(tmp_path, "    return [-y[0]]\n", '[solver]\nrtol = 1e-18\n')
    assert result.exit_code == 0
    assert "RelTol has been increased to 2.22045e-14" in result.output
    assert record["warnings"] and record["status"] == "success"


def test_stiff_problem_given_to_ode45_is_stopped_by_max_steps(tmp_path):
    (tmp_path / "vdp.toml").write_text(
        '[parameters]\nmu = 1000\n[system]\nstates = ["x", "v"]\n[system.equations]\nx = "v"\n'
        'v = "mu*(1 - x^2)*v - x"\n[initial]\nx = 2\nv = 0\n[time]\nstop = 3000\n')
    result = runner.invoke(app, ["run", str(tmp_path / "vdp.toml"), "--runs", str(tmp_path / "runs"),
                                 "--max-steps", "2000"])
    assert result.exit_code == 1
    assert "max_steps = 2000" in result.output and "stiff" in result.output and "ode15s" in result.output
    record = json.loads((tmp_path / "runs" / "vdp" / "ode45" / "result.json").read_text())
    assert record["stats"]["nsteps"] == 2000 and record["points"] == 4 * 2000 + 1
