"""Work and memory budgets, checked from the file before anything runs (issue 15, class 4)."""

from dataclasses import replace
from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.exceptions import ExperimentError, InputError
from odelab.experiment.limits import DEFAULT_LIMITS, Limits, fixed_step_count, parse_limit
from odelab.experiment.loader import load_experiment

ROOT = Path(__file__).resolve().parents[2]
BASE = '''
[system]
states = ["y"]
[system.equations]
y = "cos(t)"
[initial]
y = 2
'''


def write(tmp_path, text, name="exp.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def run(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def test_the_defaults_are_documented_and_allow_a_million_step_lab_run(tmp_path):
    assert DEFAULT_LIMITS == Limits(steps=1_000_000, points=2_000_000, refine=100, cases=1_000, amplitudes=100,
                                    table_rows=10_000)
    path = write(tmp_path, BASE + '[time]\nstop = 1\n[solver]\nmethod = "rk4"\nh = 1e-6\n')
    case = load_experiment(path).cases[0]  # 1,000,000 steps and 1,000,001 points: within the budgets
    assert fixed_step_count(case.problem.tspan, 1e-6) == 1_000_000
    with pytest.raises(ExperimentError, match=r"`solver.h` = 1e-06 over a span of 1 takes 1e\+06 steps; the budget is "
                                              r"999,999 steps per solve"):
        load_experiment(path, limits=replace(DEFAULT_LIMITS, steps=999_999))


def test_fixed_step_count_matches_the_grid_the_solver_takes():
    import numpy as np

    from odelab.solvers.api import fixed_grid

    for tspan, h in (([0, 1], 0.1), ([0, 1], 0.3), ([0, 0.5, 2], 0.25), ([3, 0], 0.7), ([0, 1], 1e-3)):
        grid, _ = fixed_grid(np.array(tspan, dtype=float), h)
        assert fixed_step_count(np.array(tspan, dtype=float), h) == grid.size - 1


def test_max_steps_applies_to_fixed_step_methods_before_they_run(tmp_path):
    path = write(tmp_path, BASE + '[time]\nstop = 10\n[solver]\nmethod = "euler"\nh = 0.001\n')
    result = run("run", path, "--no-store", "--max-steps", "5000")
    assert result.exit_code == 2
    assert ("`solver.h` = 0.001 over a span of 10 takes 1e+04 steps; the budget is 5,000 steps per solve (or take "
            "a larger h); raise it with `odelab run --max-steps 10000` if you mean it.") in result.output
    assert run("run", path, "--no-store", "--max-steps", "10000").exit_code == 0
    assert run("run", path, "--no-store", "--max-steps", "0").exit_code == 0  # 0: no limit


def test_limit_raises_a_budget_for_one_run(tmp_path):
    cases = "".join(f'\n[[case]]\nname = "c{i}"\n' for i in range(3))
    path = write(tmp_path, BASE + "[time]\nstop = 1\n" + cases)
    refused = run("validate", path, "--limit", "cases=2")
    assert refused.exit_code == 2
    assert ("`case` has 3 [[case]] tables; the budget is 2 cases per file; raise it with `odelab run --limit cases=3` "
            "if you mean it.") in refused.output
    assert run("validate", path, "--limit", "cases=3").exit_code == 0
    points = write(tmp_path, BASE + "[time]\nstop = 1\npoints = 3000000\n", "points.toml")
    assert "`time.points` is 3,000,000; the budget is 2,000,000" in run("validate", points).output
    assert run("validate", points, "--limit", "points=3000000").exit_code == 0


@pytest.mark.parametrize("text, message", [
    ("pointz=3", "`--limit` is 'pointz=3'; write NAME=N with NAME one of steps, points, refine, cases, amplitudes, "
                 "table_rows, events, states (0: no limit), e.g. --limit points=5000000."),
    ("points", "`--limit` is 'points'; write NAME=N"),
    ("points=-1", "`--limit points` must be a whole number >= 0 (0: no limit); got '-1'."),
    ("points=lots", "`--limit points` must be a whole number >= 0 (0: no limit); got 'lots'."),
])
def test_a_bad_limit_is_a_usage_error(text, message):
    with pytest.raises(InputError) as info:
        parse_limit(text)
    assert str(info.value).startswith(message)
    result = run("run", ROOT / "experiments" / "exercise1.toml", "--no-store", "--limit", text)
    assert result.exit_code == 2 and message in result.output and "Traceback" not in result.output


def test_parse_limit_accepts_underscores_and_dashes():
    assert parse_limit("table-rows=20_000").table_rows == 20_000


def test_cases_share_the_build_of_an_unchanged_system(tmp_path, monkeypatch):
    """Loading is linear: a matrix the cases share is built and its expressions compiled once per file."""
    from odelab.expressions import constants as constants_module

    n = 12
    rows = ", ".join("[" + ", ".join('"-k"' if i == j else "1" if j == i + 1 else "0" for j in range(n)) + "]"
                     for i in range(n))
    states = ", ".join(f'"x{i}"' for i in range(n))
    text = (f'[parameters]\nk = 2\n[system]\nkind = "state-space"\nstates = [{states}]\nA = [{rows}]\n[initial]\n'
            + "".join(f"x{i} = 1\n" for i in range(n)) + "[time]\nstop = 1\n"
            + "".join(f'\n[[case]]\nname = "c{c}"\nsolver.rtol = {10.0 ** -(c + 3)}\n' for c in range(5))
            + '\n[[case]]\nname = "stiffer"\nparameters.k = 3\n')
    from odelab.experiment import fields

    monkeypatch.setattr(fields, "_CONSTANTS", {})  # evaluations of earlier tests do not count
    calls = []
    real = constants_module.compile_expression
    monkeypatch.setattr(constants_module, "compile_expression", lambda *a, **k: calls.append(a[0]) or real(*a, **k))
    exp = load_experiment(write(tmp_path, text))
    systems = [c.problem.system.model for c in exp.cases]
    assert all(s is systems[0] for s in systems[:5]) and systems[5] is not systems[0]
    assert systems[5].A[0, 0] == -3 and systems[0].A[0, 0] == -2
    assert calls.count("-k") == 2  # once per value of k, not once per entry and case (72 entries)
    assert "0" not in calls and "1" not in calls  # plain numbers never reach the compiler


def test_cases_share_the_validated_time_table_and_its_output_times(tmp_path, monkeypatch):
    from odelab.experiment import schema

    output = ", ".join(f"{i / 100:g}" for i in range(1001))
    text = (BASE + f"[time]\nstop = 10\noutput = [{output}]\n"
            + "".join(f'\n[[case]]\nname = "c{c}"\nsolver.rtol = {10.0 ** -(c + 3)}\n' for c in range(4))
            + '\n[[case]]\nname = "short"\ntime.stop = 1\ntime.output = [0, 1]\n')
    validated = []
    real = schema.Time.model_validate.__func__
    monkeypatch.setattr(schema.Time, "model_validate", classmethod(lambda cls, v, *a, **k: validated.append(v)
                                                                    or real(cls, v, *a, **k)))
    exp = load_experiment(write(tmp_path, text))
    assert len(validated) == 1  # the base's [time], once for the file
    tspans = [c.problem.tspan for c in exp.cases]
    assert all(t is tspans[0] for t in tspans[:4]) and tspans[0].size == 1001
    assert tspans[4].tolist() == [0.0, 1.0]
    assert not tspans[0].flags.writeable


@pytest.mark.parametrize("method", ["ode45", "ode15s", "Radau"])
def test_max_step_budget_holds_for_every_adaptive_kind(tmp_path, method):
    path = write(tmp_path, BASE + f'[time]\nstop = 10\n[solver]\nmethod = "{method}"\nmax_step = 1e-9\n')
    with pytest.raises(ExperimentError, match=r"`solver.max_step` = 1e-09 over a span of 10 takes at least 1e\+10 "
                                              r"steps; the budget is 1,000,000 steps per solve"):
        load_experiment(path)
