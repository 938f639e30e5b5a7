"""Round 3 of hostile input (issue 25, point 4): the fault scenarios that are not one bad file.

The bad files themselves (budgets, ranges, names, messages) are in tests/assets/bad with their
expected message and exit code; these are the faults around them: what is written (sweep.csv,
the report's drawing), what is read back (a hand-edited result.json), and the shared mechanisms
(diagram matrices, matrix strings) checked against their slow, obvious versions.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def run(*args):
    return runner.invoke(app, [str(a) for a in args])


SWEPT = """
[parameters]
k = 1
[system]
states = ["y"]
[system.equations]
y = "-k*y"
[initial]
y = 1
[time]
stop = 1
[reference]
method = "none"
[sweep]
"parameters.k" = [1, '-2+3', "-3", '+4*cos(0)', '@1+0' ]
"""


def test_sweep_csv_cells_are_never_live_formulas(tmp_path):
    """OWASP's CSV-injection advice: a text cell starting = + - @ tab CR gets a leading quote;
    numbers (and text that is a plain number, "-3") stay as they are."""
    from odelab.fileio import spreadsheet_cell

    (tmp_path / "swept.toml").write_text(SWEPT.replace("'@1+0' ", "'1+0'"))
    result = run("run", tmp_path / "swept.toml", "--runs", tmp_path / "runs")
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO((tmp_path / "runs" / "swept" / "sweep.csv").read_text())))
    column = [r[1] for r in rows[1:]]
    assert column == ["1", "'-2+3", "-3", "'+4*cos(0)", "1+0"]
    for cell in ("=HYPERLINK(\"http://x\")", "+x", "-x", "@SUM(A1)", "\tx", "\rx", "-1+2", "-nan", "-inf"):
        assert spreadsheet_cell(cell) == "'" + cell
    for cell in ("-3", "-1e-4", "+2.5", 3, -3.0, "abc", "k=-2"):
        assert spreadsheet_cell(cell) == cell


def _diagram_dot(name="figure1.toml"):
    from odelab.experiment.loader import load_experiment
    from odelab.run.runner import diagram_record

    return diagram_record(load_experiment(ROOT / "experiments" / name).cases[0].problem)["dot"]


@pytest.mark.parametrize("name", ["figure1.toml", "feedback_pi.toml"])
def test_the_report_draws_only_dot_as_odelab_writes_it(name):
    from odelab.report.graphviz import render_svg
    from odelab.systems.diagram.draw import dot_problem

    dot = _diagram_dot(name)
    assert dot_problem(dot) is None
    edits = {
        "image": dot.replace("shape=box", 'shape=box, image="/etc/passwd"', 1),
        "a new node": dot.replace("\n}", '\n  "x" [image="/tmp/a.png"];\n}'),
        "html label": dot.replace('label="', "label=<<b>x</b>>, xlabel=\"", 1),
        "a subgraph": dot.replace("\n}", "\n  subgraph s { a }\n}"),
        "shapefile": dot.replace("shape=box", 'shapefile="/etc/hosts"', 1),
        "fontpath": dot.replace("rankdir=LR;", 'rankdir=LR; fontpath="/etc";'),
    }
    for what, text in edits.items():
        assert dot_problem(text), what
        drawn, note = render_svg(text)
        assert drawn is None and "is not drawn" in note and "edited by hand" in note, what


def test_diagram_matrices_many_columns_at_once_equal_one_column_at_a_time():
    """matrices() evaluates 256 unit vectors per pass (10,000 integrators were quadratic): the
    same A, B, C, D, bit for bit, as one evaluation per column, through a gain matrix, a mux,
    a demux, a transfer function and a state-space block."""
    from odelab.experiment.loader import load_experiment

    (ROOT / "tests" / "assets").exists()
    text = """
[system]
kind = "diagram"
outputs = { y = "plant.y", z = "dm.2", w = "tf" }
[blocks]
r = { type = "step", time = 0 }
r2 = { type = "sine", amplitude = 1, frequency = 1 }
e = { type = "sum", signs = "+-", inputs = ["r", "plant.y"] }
mx = { type = "mux", inputs = ["e", "r2"] }
K = { type = "gain", gain = [[1, 2], [3, 4]], input = "mx" }
dm = { type = "demux", outputs = 2, input = "K" }
tf = { type = "transfer-fcn", num = [1, 2], den = [1, 3, 2], input = "dm.1" }
i1 = { type = "integrator", input = "dm.2" }
s2 = { type = "sum", signs = "++", inputs = ["tf", "i1"] }
[blocks.plant]
type = "state-space"
A = [[0, 1], [-3, -4]]
B = [[0], [1]]
C = [[10, 0]]
outputs = ["y"]
states = ["x", "v"]
input = "s2"
[time]
stop = 1
"""
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "lin.toml"
        path.write_text(text)
        d = load_experiment(path).cases[0].problem.system.diagram
    A, B, C, D = d.matrices()
    n, m = len(d.states), len(d.inputs)
    one = np.eye(n)
    assert np.array_equal(A, np.column_stack([d._dynamics(0.0, one[j], np.zeros(m)) for j in range(n)]))
    assert np.array_equal(C, np.column_stack([d._output(0.0, one[j], np.zeros(m)) for j in range(n)]))
    assert np.array_equal(B, np.column_stack([d._dynamics(0.0, np.zeros(n), np.eye(m)[j]) for j in range(m)]))
    assert np.array_equal(D, np.column_stack([d._output(0.0, np.zeros(n), np.eye(m)[j]) for j in range(m)]))
    assert A.shape == (5, 5) and np.any(A != 0) and np.any(B != 0)


def test_a_long_diagram_chain_builds_its_matrices_exactly():
    """600 integrators in a chain (more than two chunks of 256): A is the shift matrix."""
    import tempfile

    from odelab.experiment.loader import load_experiment

    n = 600
    blocks = ['src = { type = "step", time = 0 }'] + [
        f'i{i} = {{ type = "integrator", input = "{"src" if i == 0 else f"i{i - 1}"}" }}' for i in range(n)]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "chain.toml"
        path.write_text('[system]\nkind = "diagram"\noutputs = { y = "i599" }\n[blocks]\n' + "\n".join(blocks)
                        + '\n[time]\nstop = 1\n[reference]\nmethod = "none"\n')
        d = load_experiment(path).cases[0].problem.system.diagram
    A, B, C, D = d.matrices()
    assert np.array_equal(A, np.eye(n, k=-1)) and B[0, 0] == 1 and B[1:].sum() == 0
    assert C[0, n - 1] == 1 and C.sum() == 1 and D.sum() == 0


def test_matlab_matrix_split_is_the_same_on_long_rows():
    from odelab.expressions.matlab import split_matrix

    assert split_matrix("[0 1; -k/m -b/m]") == [["0", "1"], ["-k/m", "-b/m"]]
    assert split_matrix("[a - b, c -d e * f]") == [["a - b", "c", "-d", "e * f"]]
    row = " ".join(["-1"] * 20000)
    assert split_matrix(f"[{row}]") == [["-1"] * 20000]
    assert split_matrix("[" + " * ".join(["x"] * 20000) + "]") == [[" * ".join(["x"] * 20000)]]


def test_unparsable_mathtext_is_drawn_as_plain_text():
    from odelab.report.plots import drawable

    assert drawable("x (m)") == "x (m)" and drawable("y ($m/s^2$)") == "y ($m/s^2$)"
    assert drawable("y ($\\hspace$)") == "y (\\$\\hspace\\$)"
    assert drawable("$5/kg") == "$5/kg"  # one $: matplotlib draws it as text already


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """The bouncing ball and Figure 1 (a diagram), run once and stored."""
    runs = tmp_path_factory.mktemp("stored") / "runs"
    result = run("run", ROOT / "experiments" / "bouncing_ball.toml", ROOT / "experiments" / "figure1.toml",
                 "--runs", runs)
    assert result.exit_code == 0, result.output
    return runs


EDITS = [
    ("bouncing_ball", ["events", 0, "state", "h"], "abc", "`events[0].state.h` must be a number; got 'abc'"),
    ("bouncing_ball", ["events", 0, "t"], 1e308, "`events[0].t` is 1e+308, outside the run's time span [0, 10]"),
    ("bouncing_ball", ["events", 0, "exact_t"], -1e300, "`events[0].exact_t` must be a finite time"),
    ("bouncing_ball", ["events", 0, "reset", "v"], [1], "`events[0].reset.v` must be a number"),
    ("bouncing_ball", ["events", 0, "occurrence"], "zero", "`events[0].occurrence` must be a whole number"),
    ("figure1", ["extra", "diagram", "dot"], 5, "`extra.diagram.dot` must be str; got int"),
    ("figure1", ["extra", "diagram", "A"], [["x"]], "`extra.diagram.A[0][0]` must be a number; got 'x'"),
    ("figure1", ["extra", "diagram", "A"], [[1.0]], "`extra.diagram.A` is not 2 x 2 (states x states)"),
    ("figure1", ["extra", "diagram", "states"], "x", "`extra.diagram.states` must be a list; got str"),
]


@pytest.mark.parametrize("experiment, path, value, message", EDITS, ids=[".".join(map(str, e[1])) for e in EDITS])
def test_a_hand_edited_result_json_is_skipped_with_the_reason(stored, tmp_path, experiment, path, value, message):
    import shutil

    from odelab.report.collect import collect_runs

    runs = tmp_path / "runs"
    shutil.copytree(stored, runs)
    folder = next((runs / experiment).iterdir())
    record = json.loads((folder / "result.json").read_text())
    node = record
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = value
    (folder / "result.json").write_text(json.dumps(record))
    groups, warnings = collect_runs(runs)
    assert [w for w in warnings if message in w and str(folder) in w], warnings
    kept = {(g.name, r.case) for g in groups for r in g.runs}
    other = "figure1" if experiment == "bouncing_ball" else "bouncing_ball"
    assert (experiment, folder.name) not in kept and any(name == other for name, _ in kept)


def test_the_stored_runs_odelab_writes_pass_the_checks(stored):
    from odelab.report.collect import collect_runs

    groups, warnings = collect_runs(stored)
    assert not warnings and sum(len(g.runs) for g in groups) == 4


def test_a_large_sweep_is_summarised_and_its_first_cases_shown(tmp_path, monkeypatch):
    """More stored cases than MAX_SHOWN_CASES: one paragraph over every case (statuses, the range
    of the errors with the cases where they are, steps) and the first cases in the tables and
    figures (5,000 cases drew 5,000 panels: 124 s, 7 MB of HTML)."""
    from odelab.report import content
    from odelab.report.collect import collect_runs

    (tmp_path / "swept.toml").write_text(SWEPT.replace('method = "none"', 'method = "exact"').replace(
        "[sweep]", '[exact]\ny = "exp(-k*t)"\n[sweep]\nstore = "all"').replace(
        "[1, '-2+3', \"-3\", '+4*cos(0)', '@1+0' ]", "[1, 2, 3, 4, 5]"))
    result = run("run", tmp_path / "swept.toml", "--runs", tmp_path / "runs")
    assert result.exit_code == 0, result.output
    monkeypatch.setattr(content, "MAX_SHOWN_CASES", 3)
    groups, warnings = collect_runs(tmp_path / "runs")
    assert not warnings and len(groups[0].runs) == 5
    sections, _ = content.build_sections(groups)
    section = sections[0]
    assert [c.run.case for c in section.cases] == ["k=1", "k=2", "k=3"]
    note = next(n for n in section.notes if "stored cases" in n)
    assert note.startswith("This experiment has 5 stored cases: 5 succeeded, 0 failed.")
    errors = sorted((r.errors["y"].headline, r.case) for r in groups[0].runs)
    assert f"ranges from {errors[0][0]:.3e} ({errors[0][1]}) to {errors[-1][0]:.3e} ({errors[-1][1]})" in note
    assert "show the first 3 cases; every case is in sweep.csv in" in note


def test_the_generated_code_of_a_wide_sum_is_flat():
    """A sum of 300 inputs was one expression nested 300 deep ("too many nested parentheses"):
    one statement per term now, in numpy's order, which Python's compiler takes."""
    import tempfile

    from odelab.experiment.loader import load_experiment

    inputs = ", ".join('"src"' for _ in range(300))
    text = (f'[system]\nkind = "diagram"\noutputs = {{ y = "x" }}\n[blocks]\nsrc = {{ type = "step", time = 0 }}\n'
            f's = {{ type = "sum", signs = "{"+" * 300}", inputs = [{inputs}] }}\n'
            's2 = { type = "saturation", lower = -1, upper = 1, input = "s", zero_crossing = false }\n'
            'x = { type = "integrator", input = "s2" }\n[time]\nstop = 1\n')
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "wide.toml"
        path.write_text(text)
        fast = load_experiment(path).cases[0].problem.system.compiled
    body = fast.body
    assert max(line.count("(") for line in body) < 10
    namespace: dict = {}
    exec(compile("def rhs(t, _y, _p, _out, _u0=1.0):\n" + "\n".join(body), "rhs", "exec"), namespace)
    out = np.zeros(1)
    namespace["rhs"](0.0, np.zeros(1), np.concatenate([[0.0, 0.0], fast.values]), out)
    assert out[0] == 1.0  # 300 x 1, saturated at 1
