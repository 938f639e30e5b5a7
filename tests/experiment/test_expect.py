"""`expect = "max-steps"`: a case that stops by its step limit on purpose is reported as
"stopped, as expected", stored honestly as failed, and does not make the run exit 1."""

import json

from typer.testing import CliRunner

from odelab.cli import app

runner = CliRunner()

VDP = """title = "van der Pol, mu = 1000"
[parameters]
mu = 1000
[system]
states = ["x", "v"]
[system.equations]
x = "v"
v = "mu*(1 - x^2)*v - x"
[initial]
x = 2
v = 0
[time]
stop = 3000
[reference]
method = "none"
[solver]
method = "ode15s"

[[case]]
name = "ode45"
solver.method = "ode45"
solver.max_steps = 300
{expect}

[[case]]
name = "ode15s"
"""


def _run(tmp_path, expect: str):
    path = tmp_path / "vdp.toml"
    path.write_text(VDP.format(expect=expect))
    runs = tmp_path / "runs"
    result = runner.invoke(app, ["run", str(path), "--runs", str(runs)])
    return result, runs


def test_a_declared_stop_is_reported_as_expected_and_the_run_exits_0(tmp_path):
    result, runs = _run(tmp_path, 'expect = "max-steps"')
    assert result.exit_code == 0, result.output
    assert "stopped, as expected" in result.output
    assert "expect = 'max-steps'" in result.output
    record = json.loads((runs / "vdp" / "ode45" / "result.json").read_text())
    assert record["status"] == "failed" and record["expected"] is True and record["expect"] == "max-steps"
    assert record["stats"]["nsteps"] == 300


def test_without_expect_the_same_stop_is_a_failure(tmp_path):
    result, runs = _run(tmp_path, "")
    assert result.exit_code == 1
    assert "FAILED" in result.output and "stopped, as expected" not in result.output
    assert "expected" not in json.loads((runs / "vdp" / "ode45" / "result.json").read_text())


def test_a_stop_for_another_reason_is_still_a_failure(tmp_path):
    # expect = "max-steps" covers the step limit only: a non-finite derivative is a real failure
    path = tmp_path / "blow.toml"
    path.write_text('expect = "max-steps"\n[system]\nstates = ["y"]\n[system.equations]\ny = "y^2"\n[initial]\n'
                    'y = 1\n[time]\nstop = 2\n[reference]\nmethod = "none"\n')
    result = runner.invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs")])
    assert result.exit_code == 1 and "FAILED" in result.output


def test_an_expected_stop_that_does_not_happen_is_said(tmp_path):
    path = tmp_path / "fine.toml"
    path.write_text('expect = "max-steps"\n[system]\nstates = ["y"]\n[system.equations]\ny = "cos(t)"\n[initial]\n'
                    'y = 2\n[time]\nstop = 1\n[reference]\nmethod = "none"\n')
    result = runner.invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs")])
    assert result.exit_code == 0
    assert "expects this case to stop (expect = 'max-steps'), but it reached the end" in result.output


def test_expect_lists_its_choices(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('expect = "maxsteps"\n[system]\nstates = ["y"]\n[system.equations]\ny = "1"\n[time]\nstop = 1\n')
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 2
    assert "max-steps" in result.output and "failure" in result.output


def test_the_report_lists_only_real_failures_in_its_first_box(tmp_path):
    from odelab.report.build import build_report

    _, runs = _run(tmp_path, 'expect = "max-steps"')
    out = tmp_path / "report"
    build_report(runs, out, formats=("html",))
    html = (out / "index.html").read_text()
    assert 'id="failed"' not in html
    assert "stopped, as expected" in html
    assert "ode45 failed:" not in html and "<strong>ode45 stopped, as expected:</strong>" in html
