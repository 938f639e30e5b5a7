"""The report's sweep and study sections, from stored sweep.json files."""

import json
import math

import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.report import build_report

CONVERGENCE = """
title = "Euler and RK4 on Exercise 1"
[system]
states = ["y"]
[system.equations]
y = "cos(t)"
[initial]
y = 2
[time]
stop = "pi"
[exact]
y = "sin(t) + 2"
[solver]
method = "euler"
[sweep]
"solver.method" = ["euler", "rk4"]
"solver.h" = [0.1, 0.05, 0.025, 0.0125]
[study]
kind = "convergence"
"""

DAMPING = """
title = "Overshoot against damping"
[parameters]
k = 3
b = 4
[system]
kind = "state-space"
states = ["x", "v"]
inputs = ["f"]
outputs = ["y"]
A = [[0, 1], ["-k", "-b"]]
B = [[0], [1]]
C = [[10, 0]]
D = [[0]]
[initial]
x = 0
v = 0
[time]
stop = 40                # long enough to settle: overshoot is relative to the final value
[inputs.f]
type = "step"
time = 0
[reference]
method = "none"
[sweep]
"parameters.b" = [0.5, 1, 2, 4]
"""


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("studies")
    (tmp / "convergence.toml").write_text(CONVERGENCE)
    (tmp / "damping.toml").write_text(DAMPING)
    result = CliRunner().invoke(app, ["run", str(tmp / "convergence.toml"), str(tmp / "damping.toml"), "--runs",
                                      str(tmp / "runs"), "--executor", "serial"])
    assert result.exit_code == 0, result.output
    built = build_report(tmp / "runs", tmp / "out")
    return tmp, built, (tmp / "out" / "index.html").read_text(), (tmp / "out" / "report.md").read_text()


def test_convergence_section_table_and_plot(report):
    tmp, built, html, md = report
    assert not built.warnings
    assert "Euler and RK4 on Exercise 1" in html and "observed order" in html
    record = json.loads((tmp / "runs" / "convergence" / "sweep.json").read_text())
    orders = {c["label"]: c["order"] for c in record["study"]["curves"]}
    assert abs(orders["euler"] - 1) < 0.05 and abs(orders["rk4"] - 4) < 0.05
    row = next(line for line in md.splitlines() if line.startswith("| euler |"))
    assert row == f"| euler | 0.0125 | 0.1 | 4 of 4 | {orders['euler']:.3f} | 1 | {orders['euler'] - 1:+.3f} |"
    assert (tmp / "out" / "figures" / "convergence-convergence.png").stat().st_size > 10_000


def test_parameter_sweep_shows_overshoot_against_b(report):
    tmp, _, html, md = report
    assert (tmp / "out" / "figures" / "damping-sweep.png").exists()
    record = json.loads((tmp / "runs" / "damping" / "sweep.json").read_text())
    overshoot = [r["metrics"]["y"]["overshoot_percent"] for r in record["rows"]]
    # x'' + b x' + 3 x = 1: underdamped below b = 2 sqrt(3); overshoot exp(-pi zeta / sqrt(1 - zeta^2)),
    # measured at ode45's output points (MATLAB's Refine = 4), so a little below the true peak
    for b, measured in zip([0.5, 1, 2], overshoot):
        zeta = b / (2 * math.sqrt(3))
        exact = 100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2))
        assert exact - 1.0 < measured <= exact + 1e-6, (b, measured, exact)
    assert overshoot[3] < 0.01  # b = 4: overdamped, no overshoot (beyond the solver error, rtol 1e-3)
    assert "| b=0.5 | success |" in md and "overshoot (%)" in md
