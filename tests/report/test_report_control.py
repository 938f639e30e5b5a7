"""The report's diagram and control-analysis parts (odelab.report.control), from real runs."""

from __future__ import annotations

import os
import re
import shutil

import pytest
from report_support import build

from odelab.systems.diagram.draw import dot_string, to_dot

DOT = shutil.which("dot")
if DOT is None and os.environ.get("ODELAB_REQUIRE_GRAPHVIZ"):
    # CI installs Graphviz and sets this: a missing `dot` there is a failure, not a skip.
    raise RuntimeError("ODELAB_REQUIRE_GRAPHVIZ is set but Graphviz's `dot` was not found")
needs_dot = pytest.mark.skipif(DOT is None, reason="Graphviz is not installed (apt-get install -y graphviz): the "
                                                   "diagram drawing cannot be checked")


def section(html: str, anchor: str) -> str:
    start = html.index(f'<section class="experiment" id="{anchor}">')
    return html[start:html.index("</section>", start)]


@needs_dot
def test_figure1_is_drawn_and_shown_to_be_exercise2(lab_report):
    fig1 = section(lab_report.html, "figure1")
    assert '<figure id="fig-figure1-diagram">' in fig1 and "laid out by system Graphviz dot 2." in fig1
    assert b"<svg" in (lab_report.out / "figures" / "figure1-diagram.svg").read_bytes()[:200]
    assert "The same system as Exercise 2: mass-spring-damper as a state-space model" in fig1
    assert "A and B are equal entry for entry, and so are the rows of C and D for y" in fig1
    # same inputs, same solver, same output times: bit-for-bit the same responses
    for case, points in (("step-ode45", 89), ("sine-ode45", 101), ("ramp-ode45", 69)):
        assert (f"<tr><td>{case}</td><td>y</td><td class=\"num\">{points}</td><td class=\"num\">0.000e+00</td>"
                f"<td class=\"num\">0</td></tr>") in fig1
    assert "<caption>A</caption>" in fig1 and "The same system as" in lab_report.md


def test_exercise2_shows_stepinfo_transfer_function_and_bode(lab_report):
    ex2 = section(lab_report.html, "exercise2")
    assert '<td class="mono">(10) / (s^2 + 4 s + 3)</td><td class="num">3.33333</td>' in ex2
    assert '<td class="num">2.391</td><td class="num">4.317</td><td class="num">0</td><td class="num">0</td>' in ex2
    assert '<span title="approached, never reached">&infin;</span>' in ex2
    assert "phase margin 73.92&deg; at 2.402 rad/s" in ex2
    assert '<figure id="fig-exercise2-bode">' in ex2
    assert (lab_report.out / "figures" / "exercise2-bode.png").is_file()
    assert "| f | y | (10) / (s^2 + 4 s + 3) | 3.33333 |" in lab_report.md


def test_pi_loop_section_shows_the_closed_loop(lab_report):
    pi = section(lab_report.html, "feedback_pi")
    assert "(20 s + 15) / (s^3 + 4 s^2 + 23 s + 15)" in pi
    assert "The diagram has nonlinear blocks" in pi and "Linear model about the operating point" in pi
    assert "Taken as a loop gain" not in pi  # the closed loop's channels are not loop gains ...
    assert ("The loop opened at the input of <code>actuator</code>: L(s) = <span class=\"mono\">(20 s + 15) / "
            "(s^3 + 4 s^2 + 3 s)</span>") in pi  # ... the loop opened at the actuator is
    assert "phase margin 40.53&deg; at 3.968 rad/s" in pi and '<figure id="fig-feedback_pi-bode">' in pi


def test_without_system_graphviz_the_webassembly_one_draws_and_the_caption_says_so(lab_runs, tmp_path, monkeypatch):
    # a fresh machine has no Graphviz: the README's first line must still give the whole report
    runs = tmp_path / "runs"
    shutil.copytree(lab_runs / "figure1", runs / "figure1")
    monkeypatch.setattr("odelab.report.graphviz._system_dot", lambda: None)
    report = build(runs, tmp_path / "report")
    assert "Graphviz is not installed" not in report.html and "apt install graphviz" not in report.md
    assert re.search(r"laid out by Graphviz \d+\.\d+\.\d+ via WebAssembly\.</figcaption>", report.html)
    assert "system Graphviz" not in report.html
    svg = (tmp_path / "report" / "figures" / "figure1-diagram.svg").read_bytes()
    assert svg.startswith(b"<svg") and b">velocity<" in svg
    assert 'src="data:image/svg+xml;base64,' in report.html


def test_dot_strings_are_escaped():
    assert dot_string('a"b\\c\nd') == '"a\\"b\\\\c\\nd"'
    assert dot_string("x];evil[") == '"x];evil["'  # quoted: brackets are plain text


@needs_dot
def test_a_hostile_label_cannot_change_the_drawing():
    from odelab import diagram as dg
    from odelab.report.graphviz import render_svg
    from odelab.signals import Step

    src = dg.Source(Step(), label='step"] ; x -> y [label="\\')
    d = dg.Diagram({"s": src, "i": dg.Integrator(input="s")}, {"y": "i"}).compile()
    text = to_dot(d.wiring)
    import subprocess

    plain = subprocess.run([DOT, "-Tplain"], input=text.encode(), capture_output=True, check=True).stdout.decode()
    assert sum(line.startswith("edge ") for line in plain.splitlines()) == 2  # s -> i, i -> y: no edge added
    assert sum(line.startswith("node ") for line in plain.splitlines()) == 3
    drawn, note = render_svg(text)
    assert note == "" and drawn.svg.startswith(b"<svg")
