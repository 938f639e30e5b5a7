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


ROBERTSON = """title = "Robertson's kinetics"
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
stop = 4e10
[solver]
method = "ode15s"
rtol = 1e-4
atol = 1e-10
[reference]
method = "none"
{plot}
"""


def _section(tmp_path, text, name="robertson"):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    runs = tmp_path / "runs"
    result = odelab_run([path], runs)
    assert result.exit_code == 0, result.output
    groups, _ = collect_runs(runs)
    return build_sections(groups)[0][0]


def test_a_process_over_many_decades_gets_a_log_time_axis_and_scaled_quantities(tmp_path):
    section = _section(tmp_path, ROBERTSON.format(plot="[plot]\nscale = { y2 = 1e4 }"))
    (panel,) = section.solution_figure.panels
    assert panel.xscale == "log" and "time axis is logarithmic" in section.solution_figure.caption
    y2 = next(line for line in panel.lines if line.label.startswith("10^4 y2"))
    assert 0.3 < float(max(y2.y)) < 0.4  # y2 peaks at 3.65e-5 (Hairer & Wanner)
    (tmp_path / "linear").mkdir()
    linear = _section(tmp_path / "linear", ROBERTSON.format(plot='[plot]\nt_scale = "linear"'))
    assert linear.solution_figure.panels[0].xscale == "linear"


def test_a_case_cut_short_says_where_it_stopped(tmp_path):
    text = ('[parameters]\nmu = 1000\n[system]\nstates = ["x", "v"]\n[system.equations]\nx = "v"\n'
            'v = "mu*(1 - x^2)*v - x"\n[initial]\nx = 2\nv = 0\n[time]\nstop = 3000\n[reference]\nmethod = "none"\n'
            '[[case]]\nname = "ode45"\nsolver.method = "ode45"\nsolver.max_steps = 300\nexpect = "max-steps"\n'
            '[[case]]\nname = "ode15s"\nsolver.method = "ode15s"\n')
    section = _section(tmp_path, text, "vdp")
    labels = [line.label for p in section.solution_figure.panels for line in p.lines]
    stopped = [label for label in labels if "stopped at t = " in label]
    assert stopped and all(label.startswith("ode45") for label in stopped)
    assert section.solution_figure.panels[0].xscale == "linear"  # van der Pol moves over the whole span
