"""The high-accuracy reference: stiffness detected and handed to Radau, bounded by the budget,
solved once per problem, with a status line in the CLI."""

import textwrap

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.analysis import reference as ra
from odelab.cli import app


def rober(t, y):
    return [-0.04 * y[0] + 1e4 * y[1] * y[2], 0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2, 3e7 * y[1] ** 2]


# Robertson at t = 4e10 (SciPy's Radau at rtol 1e-13, atol 1e-22; tests/solvers/implicit) and at
# t = 0.4 (Hairer & Wanner's published 0.9851721138, 3.386395e-5, 1.479402e-2).
AT_4E10 = np.array([5.208345176799e-08, 2.083338177925e-13, 9.999999479163e-01])
AT_04 = np.array([9.851721138610e-01, 3.386395378975e-05, 1.479402218522e-02])


def test_a_stiff_problem_is_handed_to_radau_with_the_reason():
    lines = []
    ref = ra.high_accuracy(rober, 0.0, 4e10, [1, 0, 0], rtol=1e-10, atol=1e-20, progress=lines.append)
    assert ref.status == "success" and ref.solver == "Radau"
    assert ref.note.startswith("the problem is stiff: DOP853's steps were held by stability")
    assert ref.nsteps < 20_000  # DOP853 would need hundreds of millions
    v = ref.values([0.0, 0.4, 4e10])
    np.testing.assert_array_equal(v[0], [1, 0, 0])
    np.testing.assert_allclose(v[1], AT_04, rtol=1e-8)  # inside a step: the continuous extension
    np.testing.assert_allclose(v[2], AT_4E10, rtol=1e-6)
    assert lines[0] == "reference by DOP853 at rtol 1e-10"
    assert any(line.startswith("stiff (DOP853 held by stability at t = ") and line.endswith("reference by Radau")
               for line in lines)
    assert lines[-1].startswith("reference done: Radau")


def test_a_non_stiff_problem_stays_with_dop853():
    ref = ra.high_accuracy(lambda t, y: [y[1], -y[0]], 0.0, 100.0, [1, 0], rtol=1e-12, atol=1e-14)
    assert ref.status == "success" and ref.solver == "DOP853" and ref.note == ""
    t = np.linspace(0, 100, 7)
    np.testing.assert_allclose(ref.values(t)[:, 0], np.cos(t), atol=1e-10)


@pytest.mark.parametrize("solver", ["auto", "DOP853", "Radau"])
def test_the_budget_bounds_the_reference(solver):
    ref = ra.high_accuracy(rober, 0.0, 4e10, [1, 0, 0], solver=solver, max_steps=300)
    assert ref.status == "failed" and ref.nsteps == 300
    assert "after max_steps = 300 steps (the run's budget, --max-steps)" in ref.message


STUDY = """
    title = "Robertson, a small work-precision study"
    [system]
    states = ["y1", "y2", "y3"]
    equations = { y1 = "-0.04*y1 + 1e4*y2*y3", y2 = "0.04*y1 - 1e4*y2*y3 - 3e7*y2^2", y3 = "3e7*y2^2" }
    [initial]
    y1 = 1
    y2 = 0
    y3 = 0
    [time]
    stop = 4e10
    [reference]
    method = "high-accuracy"
    rtol = 1e-9
    atol = 1e-20
    [solver]
    method = "ode15s"
    atol = 1e-14
    [sweep]
    "solver.method" = ["ode15s", "BDF"]
    "solver.rtol" = [1e-3, 1e-5]
    store = "summary"
    [study]
    kind = "work-precision"
    quantity = "y1"
"""


def test_a_stiff_study_shares_one_bounded_reference_with_a_status_line(tmp_path, monkeypatch):
    path = tmp_path / "robertson.toml"
    path.write_text(textwrap.dedent(STUDY))
    calls = []
    real = ra.high_accuracy

    def counted(*args, **kwargs):
        calls.append(kwargs.get("max_steps"))
        return real(*args, **kwargs)

    monkeypatch.setattr(ra, "high_accuracy", counted)
    ra.clear_cache()
    monkeypatch.setenv("FORCE_COLOR", "1")  # the status line is for a terminal (a log gets the case's notes)
    monkeypatch.setenv("COLUMNS", "200")
    result = CliRunner().invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    assert calls == [1_000_000]  # one solve for the four cases, bounded by --max-steps' default
    err = result.stderr if hasattr(result, "stderr") else result.output
    assert "robertson: reference by DOP853 at rtol 1e-09" in err
    assert "robertson: stiff (DOP853 held by stability" in err and "reference done: Radau" in err
    # the budget: a reference that cannot finish in --max-steps fails with the reason, and fast
    ra.clear_cache()
    calls.clear()
    result = CliRunner().invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs2"), "--max-steps", "400"])
    assert calls == [400]
    assert "reference failed: Radau stopped at t = " in result.output + getattr(result, "stderr", "")
