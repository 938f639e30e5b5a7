"""The report states only what is true of the data: each error panel sits under its own
set-up's response (checked from the figure's own data), a case with no reference shows no
error, and so on."""

from __future__ import annotations

from odelab.report.collect import collect_runs
from odelab.report.content import build_sections

from .conftest import odelab_run

# Two set-ups of one diagram that differ in input and span; the second has no reference.
TWO_SETUPS = """title = "A saturating PI loop, two set-ups"
[parameters]
Kp = 2
[system]
kind = "diagram"
outputs = { y = "plant" }
[blocks]
ref   = { type = "step", time = 0, final = 1 }
err   = { type = "sum", signs = "+-", inputs = ["ref", "plant"] }
act   = { type = "gain", gain = "Kp", input = "err" }
plant = { type = "transfer-fcn", num = [1], den = [1, 1], input = "act" }
[time]
stop = 10
[solver]
method = "ode45"

[[case]]
name = "linear"

[[case]]
name = "saturating"
time.stop = 0.56
blocks.ref = { type = "step", time = 0, final = 3 }
reference.method = "none"
"""


def test_each_error_panel_is_its_own_set_ups(tmp_path):
    path = tmp_path / "two_setups.toml"
    path.write_text(TWO_SETUPS)
    runs = tmp_path / "runs"
    assert odelab_run([path], runs).exit_code == 0
    groups, _ = collect_runs(runs)
    (section,) = build_sections(groups)[0]
    spec = section.solution_figure
    columns = spec.columns
    assert columns == 2
    panels = spec.panels
    response, error = panels[:columns], panels[columns:2 * columns]
    assert all(p.yscale == "log" for p in error) and all(p.yscale != "log" for p in response)
    for top, bottom in zip(response, error):
        top_end = max(float(line.x.max()) for line in top.lines)
        if bottom.lines:  # the error under a response covers that response's span, not another's
            assert max(float(line.x.max()) for line in bottom.lines) == top_end
    spans = [max(float(line.x.max()) for line in p.lines) for p in response]
    saturating = spans.index(0.56)
    assert error[saturating].lines == () and "no reference" in error[saturating].note
    assert error[1 - saturating].lines and max(float(line.y.max()) for line in error[1 - saturating].lines) > 0


PENDULUM = """title = "A pendulum, not stiff"
[system]
states = ["theta", "w"]
[system.equations]
theta = "w"
w = "-sin(theta)"
[initial]
theta = 0.5
w = 0
[time]
stop = 5
[reference]
method = "none"
[[case]]
name = "ode45"
solver.method = "ode45"
[[case]]
name = "ode15s"
solver.method = "ode15s"
"""


def test_a_non_stiff_problem_gets_no_claim_of_stiffness(tmp_path):
    path = tmp_path / "pendulum.toml"
    path.write_text(PENDULUM)
    runs = tmp_path / "runs"
    assert odelab_run([path], runs).exit_code == 0
    groups, _ = collect_runs(runs)
    (section,) = build_sections(groups)[0]
    view = section.stiffness
    steps = {row["method"]: row["nsteps"] for row in view.rows}
    assert steps["ode45"] < steps["ode15s"]  # the data: the explicit method is the cheaper one
    assert not view.stiff and view.title == "Explicit and stiff solvers on this problem"
    assert "This problem is not stiff" in view.summary and f"ode45 {steps['ode45']}" in view.summary
    text = view.summary + (view.figure.caption if view.figure else "")
    assert "orders of magnitude" not in text and "stability limit" not in text


def test_an_overshoot_of_a_response_still_moving_is_marked(tmp_path):
    from pathlib import Path

    from odelab.report.studies import study_sections

    text = (Path(__file__).resolve().parents[2] / "experiments" / "damping.toml").read_text()
    text = text.replace("stop = 40 ", "stop = 6 ").replace('{ from = 0.5, to = 8, count = 16 }', "[0.5, 4]")
    path = tmp_path / "damping.toml"
    path.write_text(text)
    runs = tmp_path / "runs"
    assert odelab_run([path], runs).exit_code == 0
    import json

    record = json.loads((runs / "damping" / "sweep.json").read_text())
    metrics = {r["case"]: r["metrics"]["y"] for r in record["rows"]}
    assert metrics["b=0.5"]["settled"] is False and metrics["b=4"]["settled"] is True
    (section,), _ = study_sections([record], set())
    rows = {row[0]: row for row in section.rows}
    assert rows["b=0.5"][4].endswith(" *") and not rows["b=4"][4].endswith("*")
    assert any(note.startswith("* not settled by the end of the span (b=0.5)") for note in section.notes)
