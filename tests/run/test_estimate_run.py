"""The global error estimate in a run: when it is made, what it stores, ok? and --strict, sweeps, events."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.run.runner import run_experiment
from odelab.store.records import parse_record
from odelab.store.results import read_run, write_case

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()

OSCILLATOR = """
[system]
states = ["x", "v"]
[system.equations]
x = "v"
v = "-x"
[initial]
x = 1
v = 0
[time]
stop = 10
"""

E5 = """
title = "E5 (Bari test set) at its own tolerances"
[parameters]
A = 7.89e-10
B = 1.1e7
C = 1.13e3
M = 1e6
[system]
states = ["y1", "y2", "y3", "y4"]
[system.equations]
y1 = "-A*y1 - B*y1*y3"
y2 = "A*y1 - M*C*y2*y3"
y3 = "A*y1 - B*y1*y3 - M*C*y2*y3 + C*y4"
y4 = "B*y1*y3 - C*y4"
[initial]
y1 = 1.76e-3
y2 = 0
y3 = 0
y4 = 0
[time]
stop = 1e13
[solver]
method = "ode15s"
rtol = 1e-6
atol = 1.7e-24
[[case]]
name = "ode15s"
[[case]]
name = "ode23tb"
solver.method = "ode23tb"
"""

ROBERTSON = """
[system]
states = ["y1", "y2", "y3"]
[system.equations]
y1 = "-0.04*y1 + 1e4*y2*y3"
y2 = "0.04*y1 - 1e4*y2*y3 - 3e7*y2^2"
y3 = "3e7*y2^2"
[initial]
y1 = 1
y2 = 0
y3 = 0
[time]
stop = 1e11
[solver]
method = "ode23t"
rtol = 1e-4
atol = 1e-6
"""


def write(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_case_without_a_reference_gets_an_estimate_near_its_true_error(tmp_path):
    (r,) = run_experiment(write(tmp_path, OSCILLATOR))
    assert r.reference_kind == "none" and not r.errors
    est = r.estimate
    assert est["verdict"] == "ok" and est["factor"] == 10 and est["method"] == "ode45"
    true = np.abs(r.x[:, 0] - np.cos(r.t)).max()
    assert 0.1 < est["quantities"]["x"]["max_abs"] / true < 10
    assert est["quantities"]["x"]["digits"] == pytest.approx(-math.log10(est["quantities"]["x"]["rel_error"]))
    assert est["tight"]["nsteps"] > r.stats.nsteps
    folder = write_case(r, tmp_path / "runs")
    stored = read_run(folder)
    assert stored["estimate"]["quantities"]["v"]["max_abs"] == est["quantities"]["v"]["max_abs"]
    typed = parse_record(stored)
    assert typed.verdict == "ok" and not typed.unreliable and typed.estimate["x"].digits > 2


def test_what_is_on_by_default_and_the_switches(tmp_path):
    with_exact = OSCILLATOR + '[exact]\nx = "cos(t)"\nv = "-sin(t)"\n'
    (r,) = run_experiment(write(tmp_path, with_exact))
    assert r.errors and r.estimate is None  # a reference: the true error is shown, no second solve
    (r,) = run_experiment(write(tmp_path, with_exact + "[solver]\nestimate_error = true\n"))
    assert r.errors and r.estimate["verdict"] == "ok"  # asked: both
    (r,) = run_experiment(write(tmp_path, OSCILLATOR + "[solver]\nestimate_error = false\n"))
    assert r.estimate is None
    (r,) = run_experiment(write(tmp_path, OSCILLATOR), estimate=False)
    assert r.estimate is None
    sweep = OSCILLATOR + '[sweep]\n"solver.rtol" = [1e-3, 1e-4]\n'
    assert all(r.estimate is None for r in run_experiment(write(tmp_path, sweep)))  # a sweep: off unasked
    assert all(r.estimate["verdict"] == "ok" for r in run_experiment(write(tmp_path, sweep), estimate=True))


def test_e5_at_its_own_tolerances_is_ok_question_mark_with_the_reason(tmp_path):
    path = write(tmp_path, E5, "e5.toml")
    results = run_experiment(path)
    for r in results:
        assert r.status == "success" and r.unreliable and r.estimate["verdict"] == "unreliable"
        warning = next(w for w in r.warnings if w.startswith("unreliable (the error estimate): "))
        assert "times the accuracy asked for (RelTol |y" in warning and "against" in warning
        assert warning.endswith("or another stiff method (ode15s, ode23tb, Radau), and compare.")
    result = runner.invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs")], terminal_width=200)
    assert result.exit_code == 0, result.output  # a warning, not a failure
    assert "ok? " in result.output and "est. error" in result.output
    strict = runner.invoke(app, ["run", str(path), "--no-store", "--strict"], terminal_width=200)
    assert strict.exit_code == 1
    stored = json.loads(next((tmp_path / "runs").rglob("result.json")).read_text())
    assert stored["estimate"]["verdict"] == "unreliable" and stored["status"] == "success"


def test_robertson_ode23t_at_loose_abstol_is_flagged(tmp_path):
    (r,) = run_experiment(write(tmp_path, ROBERTSON))
    assert r.status == "success" and r.unreliable
    assert r.estimate["quantities"]["y1"]["flagged"] and r.estimate["quantities"]["y1"]["digits"] == 0
    assert any("y1 = -5.68" in w for w in r.warnings)


@pytest.mark.parametrize("name", sorted(p.name for p in (ROOT / "experiments").rglob("*.toml")))
def test_no_shipped_experiment_is_flagged(name):
    from odelab.experiment.loader import load_experiments

    path = next((ROOT / "experiments").rglob(name))
    for exp in load_experiments(path):
        for r in run_experiment(exp):
            assert not r.unreliable, (name, r.case.name, [w for w in r.warnings if w.startswith("unreliable")])


def test_events_and_a_fixed_step_method(tmp_path):
    (ball,) = run_experiment(ROOT / "experiments" / "bouncing_ball.toml", estimate=True)
    assert ball.estimate["verdict"] == "ok" and ball.estimate["points"] > 0.8 * np.unique(ball.t).size
    assert ball.estimate["quantities"]["h"]["max_abs"] < 1e-6  # ode45 is exact on parabolas
    (rk4,) = run_experiment(write(tmp_path, OSCILLATOR + '[solver]\nmethod = "rk4"\nh = 0.1\n'))
    true = np.abs(rk4.x[:, 0] - np.cos(rk4.t)).max()
    assert rk4.estimate["factor"] == 2 and "h/2" in rk4.estimate["rule"]
    assert 0.5 < rk4.estimate["quantities"]["x"]["max_abs"] / true < 2  # Richardson: 2^4/(2^4 - 1)


def test_sweep_csv_and_the_report_show_the_estimate(tmp_path):
    from odelab.report import build_report

    sweep = OSCILLATOR + '[sweep]\n"solver.rtol" = [1e-3, 1e-5]\n'
    path = write(tmp_path, sweep, "sweep.toml")
    runs = tmp_path / "runs"
    result = runner.invoke(app, ["run", str(path), str(write(tmp_path, ROBERTSON, "rober.toml")), "--runs",
                                 str(runs), "--estimate"], terminal_width=200)
    assert result.exit_code == 0, result.output
    header, first = (runs / "sweep" / "sweep.csv").read_text().splitlines()[:2]
    assert header.endswith("estimate,v_est_abs,v_est_digits,x_est_abs,x_est_digits")
    assert ",ok," in first
    text = build_report(runs, tmp_path / "report", formats="md", jobs=1).markdown.read_text()
    assert "| Est. error |" in text and "**ok?**" in text and "(0.0 digits)" in text


def test_a_compiled_run_is_estimated_on_the_compiled_engine_at_its_steps_ends(tmp_path, monkeypatch):
    import odelab.run.estimate as estimate

    path = write(tmp_path, OSCILLATOR.replace("stop = 10", "stop = 100"))
    (py,) = run_experiment(path, backend="python")
    kept = estimate._dense_solve
    monkeypatch.setattr(estimate, "_dense_solve", lambda *a: pytest.fail("the Python engine's dense solve ran"))
    import odelab.analysis.estimate as analysis

    compare = analysis.compare_solves

    def contiguous(t, run, tight, **kw):  # its phase check takes windows point by point: a strided array copied each
        assert all(a.flags.c_contiguous for a in (t, *run.values(), *tight.values()))
        return compare(t, run, tight, **kw)

    monkeypatch.setattr(analysis, "compare_solves", contiguous)  # imported by estimate_case when it runs
    (r,) = run_experiment(path, backend="compiled")
    assert r.backend == "compiled" and r.estimate["verdict"] == "ok"
    # the same steps on both engines; compared at the same points, the steps' ends (a quarter of Refine 4's rows)
    assert r.estimate["tight"]["nsteps"] == py.estimate["tight"]["nsteps"] > r.stats.nsteps
    assert r.estimate["points"] == py.estimate["points"] == r.stats.nsteps + 1 == (r.t.size - 1) // 4 + 1
    # the tighter solve's values at the run's step ends from its interpolant, as deval gives them: the same bits
    assert r.estimate["quantities"] == py.estimate["quantities"] and r.estimate["quantities"]["x"]["max_abs"] > 0
    monkeypatch.setattr(estimate, "_dense_solve", kept)
