"""Units of the report package: escaping, number formats, content helpers, the linearisation view."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from odelab.report.collect import parse_record
from odelab.report.content import (
    StepTable,
    anchor_for,
    describe_signal,
    format_bound,
    linearisation_view,
)
from odelab.report.plots import METHOD_COLORS, FigureSpec, Line, Panel, method_color, render_png
from odelab.report.render import MarkdownText, md_code, md_escape, md_fence, md_html, num, sci


@pytest.mark.parametrize("text, expected", [
    ("a|b", r"a\|b"),
    ("<script>alert(1)</script>", r"\<script\>alert(1)\</script\>"),
    ("*bold* and `code`", r"\*bold\* and \`code\`"),
    ("[0, pi]", "[0, pi]"),
    ("[link](http://x)", r"[link\](http://x)"),
    ("[ref]: http://x", r"[ref\]: http://x"),
    ("over [0, 2 pi]: the sheet", "over [0, 2 pi]: the sheet"),
    ("exercise1_2pi", "exercise1_2pi"),
    ("_emph_", r"\_emph\_"),
    ("a\\b", r"a\\b"),
    ("two\nlines", "two lines"),
    ("AT&T #1 ~x~", r"AT\&T \#1 \~x\~"),
])
def test_md_escape(text, expected):
    out = md_escape(text)
    assert out == expected and isinstance(out, MarkdownText)
    assert md_escape(out) is out  # already Markdown: not escaped twice


def test_md_html_escapes_for_raw_html_blocks():
    assert md_html("<img src=x onerror=alert(1)>|a") == "&lt;img src=x onerror=alert(1)&gt;|a"
    assert isinstance(md_html("x"), MarkdownText)


def test_md_fence_and_code_cannot_be_closed_from_inside():
    fenced = md_fence('x = "```"\n', "toml")
    assert fenced.startswith("````toml\n") and fenced.endswith("\n````")
    assert md_code("a`b") == "``a`b``"
    assert md_code("`x`") == "`` `x` ``"


@pytest.mark.parametrize("value, expected", [
    (1.0677e-4, "1.068e-04"), (6.90695e-4, "6.907e-04"), (0.0, "0.000e+00"), (None, "—"), (math.nan, "—"),
])
def test_sci_quotes_four_significant_digits(value, expected):
    assert sci(value) == expected


def test_num_and_missing_values():
    assert num(3.14159265) == "3.14159"
    assert num(None) == "—"
    assert sci(None, "undefined") == "undefined"


@pytest.mark.parametrize("value, expected", [
    (0.0, "0"), (math.pi, "pi"), (2 * math.pi, "2 pi"), (math.pi / 2, "pi/2"), (-math.pi, "-pi"),
    (12.0, "12"), (0.25, "0.25"), ("x", "x"),
])
def test_format_bound(value, expected):
    assert format_bound(value) == expected


@pytest.mark.parametrize("spec, expected", [
    ({"type": "step", "time": 0.0, "initial": 0.0, "final": 1.0}, "f steps 0 → 1 at t = 0"),
    ({"type": "sine", "amplitude": 1, "frequency": 0.2, "phase": 0.0, "bias": 0.0}, "f = sin(0.2 t)"),
    ({"type": "sine", "amplitude": 2, "frequency": 1, "phase": 0.5, "bias": 1}, "f = 1 + 2 sin(t + 0.5)"),
    ({"type": "ramp", "slope": 1.0, "start": 0.0, "initial": 0.0}, "f = t"),
    ({"type": "ramp", "slope": 2.0, "start": 1.0, "initial": 0.0}, "f = 2 (t - 1) for t >= 1"),
    ({"type": "constant", "value": 3}, "f = 3"),
    ({"type": "pulse", "amplitude": 1, "period": 2}, "f: pulse (amplitude 1, period 2)"),
])
def test_describe_signal(spec, expected):
    assert describe_signal("f", spec) == expected


def test_anchor_for_is_safe_and_unique():
    taken: set[str] = set()
    assert anchor_for("exercise1", taken) == "exercise1"
    assert anchor_for("exercise1", taken) == "exercise1-2"
    assert anchor_for("<b>x</b> y", taken) == "b-x-b-y"
    assert anchor_for("***", taken) == "x"


def test_step_table_caps_in_the_middle_and_keeps_the_maxima():
    t = np.arange(100.0)
    rel = np.full(100, 1e-4)
    rel[0] = np.nan
    rel[50] = 3e-4  # the largest relative error, in the middle
    abs_err = np.zeros(100)
    abs_err[60] = 1e-6  # the largest absolute error
    table = StepTable("ode45", "ode45", "y", t, t + 1, t + 1, abs_err, rel)
    full = table.lines(100)
    assert len(full) == 100 and all(line.row is not None for line in full) and full[0].row[4] is None
    part = table.lines(40)
    shown = [line.row[0] for line in part if line.row is not None]
    assert shown == [*map(float, range(20)), 50.0, 60.0, *map(float, range(80, 100))]
    assert [line.gap for line in part if line.row is None] == [30, 9, 19]
    # printing keeps the first and last rows and both maxima, and says how many rows it leaves out between
    printed = table.lines(40, 20)
    assert [line.row[0] for line in printed if line.row is not None and line.printed] == [0.0, 50.0, 60.0, 99.0]
    assert [line.gap for line in printed if line.row is None and not line.screen] == [49, 9, 38]
    assert table.label == "ode45"


def test_method_colours_are_fixed_and_distinct():
    assert method_color("ode23") == METHOD_COLORS["ode23"] != METHOD_COLORS["ode45"]
    assert method_color("some-future-method") == method_color("some-future-method")
    assert len(set(METHOD_COLORS.values())) == len(METHOD_COLORS)


def test_render_png_closes_its_figure_and_leaves_gaps_on_log_axes():
    import matplotlib.pyplot as plt

    x = np.linspace(0, 1, 50)
    y = np.where(x < 0.5, np.nan, x)
    y[-1] = 0.0  # a zero on a log axis is a gap, not an error
    spec = FigureSpec("t", "caption", "alt", (
        Panel("p", "t (s)", "e", (Line(x, y, "a", "#000000", marker="o"),), yscale="log"),
        Panel("empty", "t (s)", "e", (), note="nothing here"),
        Panel("third", "t (s)", "e", (Line(x, x, "b", "#D55E00"),)),
    ), columns=2)
    png = render_png(spec)
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 5_000
    assert plt.get_fignums() == []


def test_linearisation_view_from_a_hand_made_study(study):
    view = linearisation_view("ode45", study)
    assert view.quantity == "y" and view.threshold == 0.05
    assert ("state", "x", 0.0) in view.operating_point and ("input", "f", 0.0) in view.operating_point
    a = next(m for m in view.matrices if m.name == "A")
    assert a.columns == ["x", "v"] and a.rows == [("x", [0.0, 1.0]), ("v", [-3.0, -4.0])]
    b = next(m for m in view.matrices if m.name == "B")
    assert b.columns == ["f"] and b.rows == [("x", [0.0]), ("v", [1.0])]
    assert view.amplitudes == [0.1, 0.3, 1.0, 3.0, 10.0]
    assert [row[2] for row in view.error_rows] == [e <= 0.05 for e in study["errors"]["y"]]
    assert view.max_amplitude_within == study["max_amplitude_within"]
    assert len(view.comparisons) == 5 and view.comparisons[0]["names"] == ["y"]
    assert view.comparisons[2]["error"] == pytest.approx(study["errors"]["y"][2])


def test_linearisation_view_takes_the_runner_s_extra_keys(study):
    lin = copy.deepcopy(study)
    lin.update({"start": "operating-point", "drive": "f", "step_time": 1.0, "threshold_amplitude": 0.33,
                "slope": 1.01, "abs_errors": {"y": [0.0] * 5}})
    lin["comparisons"][1]["status"] = "failed"
    view = linearisation_view("about-0", lin)
    assert view.threshold_amplitude == 0.33 and view.slope == 1.01
    assert ("start", "operating-point") in view.settings and ("step time (s)", "1.0") in view.settings
    assert view.failed_amplitudes == [0.3]


@pytest.mark.parametrize("change, message", [
    (lambda d: d.update(errors={"y": [0.1]}), "5 amplitudes"),
    (lambda d: d.update(A="not a matrix"), "`A`"),
    (lambda d: d.update(A=[[1.0, 2.0], [3.0]]), "different lengths"),
    (lambda d: d["comparisons"][0]["nonlinear"].update(y=[1.0, 2.0]), "comparisons[0].nonlinear.y"),
    (lambda d: d.update(threshold="five percent"), "`threshold`"),
    (lambda d: d["operating_point"].update(x=[0.0, 0.0]), "operating_point.x"),
])
def test_linearisation_view_rejects_malformed_studies(study, change, message):
    lin = copy.deepcopy(study)
    change(lin)
    with pytest.raises(ValueError, match=re_escape(message)):
        linearisation_view("ode45", lin)


def re_escape(text: str) -> str:
    import re

    return re.escape(text)


def test_parse_record_names_the_bad_field():
    record = {"experiment": "e", "case": "c", "status": "success", "method": "ode45",
              "stats": {"nsteps": 1, "nfailed": None, "nfevals": 7}, "trajectory": {"t": np.array([0.0, 1.0])}}
    run = parse_record(record)
    assert run.nfailed is None and run.points == 2 and run.reference == "none"
    with pytest.raises(ValueError, match="stats.nsteps"):
        parse_record({**record, "stats": {"nsteps": "many"}})
    with pytest.raises(ValueError, match="errors"):
        parse_record({**record, "errors": ["y"]})
    with pytest.raises(ValueError, match="`t` column"):
        parse_record({**record, "trajectory": {"y": np.array([1.0])}})


def test_markdown_shows_control_characters_as_escapes():
    """report.md is read with cat and less: an ESC sequence in a title must not reach the terminal."""
    from odelab.report.render import md_code, md_escape, md_fence

    assert md_escape("\x1b]52;c;aGk=\x07 ball") == "\\\\x1b]52;c;aGk=\\\\x07 ball"
    assert md_code("a\x1b[2Jb") == "`a\\x1b[2Jb`"
    assert md_fence('title = "\x9b31m"\nx = 1\n') == '```\ntitle = "\\x9b31m"\nx = 1\n```'
