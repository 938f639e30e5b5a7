"""The report's figures as data: one look everywhere, units on the axes, nothing hidden or cut off."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from odelab.report.collect import collect_runs
from odelab.report.content import build_sections
from odelab.report.plots import (
    INPUT,
    LINEARISED,
    REFERENCE,
    REFERENCE_ZORDER,
    clipped_texts,
    draw_figure,
    legends_over_data,
    method_style,
)


@pytest.fixture(scope="module")
def sections(lab_runs):
    groups, warnings = collect_runs(lab_runs)
    found, more = build_sections(groups)
    assert warnings == [] and more == []
    return {s.name: s for s in found}


def specs(section):
    out = [section.solution_figure, *section.solution_parts, section.error_figure, *section.error_parts]
    out += [f for lin in section.linearisations for f in lin.figures]
    return [f for f in out if f is not None]


def test_every_method_has_its_own_colour_marker_and_dash():
    ode23, ode45, rk4 = method_style("ode23"), method_style("ode45"), method_style("rk4")
    for a, b in ((ode23, ode45), (ode23, rk4), (ode45, rk4)):
        assert a.color != b.color and a.marker != b.marker and a.linestyle != b.linestyle
    assert method_style("a-future-method") == method_style("a-future-method")


def test_exercise1_reference_is_drawn_thin_black_and_on_top(sections):
    panel, error = sections["exercise1"].solution_figure.panels  # side by side: solution, error
    assert sections["exercise1"].error_figure is None and error.ylabel == "y: |f - y| / |f|"
    by_label = {line.label: line for line in panel.lines}
    assert list(by_label) == ["ode23, 12 points", "ode45, 41 points", "exact"]
    exact = by_label["exact"]
    assert exact.color == REFERENCE.color == "#000000" and exact.zorder == REFERENCE_ZORDER and exact.marker is None
    assert all(exact.linewidth < line.linewidth for line in panel.lines if line is not exact)
    assert by_label["ode23, 12 points"].marker == "o" and by_label["ode45, 41 points"].marker == "s"
    assert panel.xlabel == "t (s)"


def test_exercise2_shows_output_states_and_input_with_units(sections):
    first, (rest,) = sections["exercise2"].solution_figure, sections["exercise2"].solution_parts
    assert first.columns == rest.columns == 3 and first.legend  # one column per input, one legend a figure
    # rows: the output, its error, the states, the input under them: 3 rows, then 2 (at most 3 x 3 a figure)
    assert [p.ylabel for p in first.panels + rest.panels] == [
        u for u in ("y (V)", "y: |f - y| / max |f|", "x (m)", "v (m/s)", "f (N)") for _ in range(3)]
    assert [p.title for p in rest.panels[:3]] == [p.title for p in first.panels[:3]]  # the set-ups, again
    spec = dataclasses.replace(first, panels=first.panels + tuple(dataclasses.replace(p, title="")
                                                                   for p in rest.panels[:3]) + rest.panels[3:])
    assert sections["exercise2"].error_figure is None  # merged as the second row
    assert [p.title for p in spec.panels[:3]] == ["step: f steps 0 -> 1 at t = 0", "sine: f = sin(0.2 t)",
                                                   "ramp: f = t"]
    inputs = spec.panels[12:]
    assert all(p.height < 1 and [ln.color for ln in p.lines] == [INPUT.color] for p in inputs)
    assert all(p.xlabel == "t (s)" for p in inputs) and all(p.xlabel == "" for p in spec.panels[:12])
    assert all(p.yscale == "log" for p in spec.panels[3:6])
    step_y = {ln.label: ln for ln in spec.panels[0].lines}
    assert set(step_y) == {"ode45", "ode23", "rk4", "exact (LTI)"}


def test_linearisation_colours_mean_the_same_in_every_figure(sections):
    section = sections["linearisation"]
    lines = [ln for p in section.solution_figure.panels for ln in p.lines]
    lines += [ln for lin in section.linearisations for p in lin.figures[0].panels[:-1] for ln in p.lines]
    nonlinear = [ln for ln in lines if ln.label.startswith("nonlinear model")]
    linearised = [ln for ln in lines if ln.label.startswith("linearised model")]
    assert nonlinear and linearised
    assert {ln.color for ln in nonlinear} == {REFERENCE.color}
    assert {(ln.color, ln.linestyle) for ln in linearised} == {(LINEARISED.color, "--")}
    assert section.error_figure is None  # the amplitude study shows the linearisation error
    (figure,) = section.linearisations[0].figures
    assert len(figure.panels) == 8  # seven amplitudes, then the error against amplitude
    error = figure.panels[-1]
    assert error.xlabel == "step of f (N)" and error.ylabel == "error / peak"
    assert error.xscale == error.yscale == "log" and [r.value for r in error.reflines][0] == 0.05


def test_no_title_label_or_legend_is_cut_off(sections):
    import matplotlib.pyplot as plt

    checked = 0
    for section in sections.values():
        for spec in specs(section):
            fig = draw_figure(spec)
            try:
                assert clipped_texts(fig) == [], spec.name
            finally:
                plt.close(fig)
            checked += 1
    assert checked >= 8


def test_the_check_finds_a_cut_off_title():
    import matplotlib.pyplot as plt
    import numpy as np

    from odelab.report.plots import FigureSpec, Line, Panel

    panel = Panel("x", "t (s)", "y", (Line(np.arange(3.0), np.arange(3.0), "y", "#000000"),))
    fig = draw_figure(FigureSpec("f", "", "", (panel,)))
    try:
        fig.axes[0].set_title("a title far too long for any figure " * 6)
        fig.canvas.draw()
        assert clipped_texts(fig) != []
    finally:
        plt.close(fig)


def test_an_input_step_is_drawn_as_a_step_not_a_slope(sections):
    # linearisation.toml's f steps 0 -> 1 (about-0) and 1 -> 2 (about-f1) at t = 1; ode45's last
    # row before it is near t = 0.8, so drawn from the rows alone the step was a slope from there
    section = sections["linearisation"]
    inputs = [p for spec in (section.solution_figure, *section.solution_parts) for p in spec.panels
              if p.ylabel == "f (N)"]
    assert len(inputs) == 2
    for panel, (lo, hi) in zip(inputs, [(0.0, 1.0), (1.0, 2.0)]):
        (line,) = panel.lines
        t, u = np.asarray(line.x), np.asarray(line.y)
        k = int(np.flatnonzero(t == 1.0)[0])
        assert (u[k], u[k + 1]) == (lo, hi)  # the left limit, then the value at the jump
        assert np.all(u[t < 1.0] == lo) and np.all(u[k + 1:] == hi)


def test_input_jumps_are_inserted_where_the_rows_miss_them():
    from odelab.report.figures import with_input_jumps

    t, u = np.array([0.0, 0.8, 1.3, 2.0]), np.array([0.0, 0.0, 1.0, 1.0])
    jumps = {"t": [1.0, 5.0], "before": [[9.0, 0.0], [9.0, 1.0]], "after": [[9.0, 1.0], [9.0, 0.0]]}
    t2, u2 = with_input_jumps(t, u, jumps, 1)  # the second input's column; t = 5 is beyond the rows
    assert t2.tolist() == [0.0, 0.8, 1.0, 1.0, 1.3, 2.0] and u2.tolist() == [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
    for bad in (None, {}, {"t": [1.0], "before": [[0.0]], "after": [[1.0, 2.0]]}):  # absent, or not odelab's
        assert with_input_jumps(t, u, bad, 0)[0] is t


def _all_specs(sections):
    out = []
    for section in sections.values():
        out += specs(section)
        if section.control is not None and section.control.bode_figure is not None:
            out.append(section.control.bode_figure)
        if section.stiffness is not None and section.stiffness.figure is not None:
            out.append(section.stiffness.figure)
    return out


def test_print_readable_figures(sections):
    """Issue 37: at most 3 x 3 panels a figure, every text at least 8 pt at the size the figure is drawn
    (and printed: figure img.plot is 7.2 in wide in print), no legend over the curves, no offset
    tick labels (a "1e-4+3.333" over an axis)."""
    import math

    import matplotlib.pyplot as plt

    from odelab.report.figures import MAX_GRID

    checked = 0
    for spec in _all_specs(sections):
        cols = max(1, min(spec.columns, len(spec.panels)))
        assert cols <= MAX_GRID and math.ceil(len(spec.panels) / cols) <= MAX_GRID, spec.name
        fig = draw_figure(spec)
        try:
            assert legends_over_data(fig) == [], spec.name
            for ax in fig.axes:
                for axis in (ax.xaxis, ax.yaxis):
                    assert axis.get_offset_text().get_text() in ("",) or "+" not in axis.get_offset_text().get_text(), \
                        (spec.name, axis.get_offset_text().get_text())
                    sizes = [t.get_fontsize() for t in axis.get_ticklabels() if t.get_text()]
                    assert min(sizes, default=8) >= 8, spec.name
            for text in fig.findobj(lambda a: hasattr(a, "get_fontsize") and hasattr(a, "get_text")):
                if text.get_text() and text.get_visible():
                    assert text.get_fontsize() >= 8, (spec.name, text.get_text())
        finally:
            plt.close(fig)
        checked += 1
    assert checked >= 12


def test_a_large_grid_is_split_into_figures_of_three_rows():
    from odelab.report.figures import split_grid
    from odelab.report.plots import FigureSpec, Line, Panel

    line = (Line(np.arange(3.0), np.arange(3.0), "y", "#000000"),)
    rows = []
    for k in range(7):  # response rows, each followed by its error row (with_error_row's shape)
        error = k % 2 == 1
        rows += [Panel("" if error or k else f"set-up {c}", "" if error else "t (s)", "e" if error else "y", line,
                       yscale="log" if error else "linear", height=0.9 if error else 1.0) for c in range(3)]
    parts = split_grid(FigureSpec("big", "The caption.", "alt", tuple(rows), columns=3))
    assert [len(p.panels) // 3 for p in parts] == [2, 2, 3]  # a response and its error row stay together
    assert [p.name for p in parts] == ["big", "big-2", "big-3"]
    assert parts[0].caption == "The caption. (Continued in the next 2 figures.)"
    assert parts[1].caption.startswith("Continued (2 of 3)")
    for part in parts:  # each part titled by set-up, and never starting on an error row
        assert [p.title for p in part.panels[:3]] == ["set-up 0", "set-up 1", "set-up 2"]
        assert part.panels[0].yscale == "linear"
    # a grid of independent panels flows into three columns
    flat = split_grid(FigureSpec("amp", "", "", tuple(Panel(f"step {k}", "t", "y", line) for k in range(8)), columns=4))
    assert len(flat) == 1 and flat[0].columns == 3
