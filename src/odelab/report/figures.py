"""What each figure of an experiment's section shows, as :class:`~odelab.report.plots.FigureSpec` data.

The choice of plots follows the data, not the experiment's name, and every figure follows the
report's one look (see :mod:`odelab.report.plots`): a method has one colour, marker and dash
everywhere; the reference is thin, black and on top; inputs are grey and drawn under the
outputs they drive; axes carry the experiment's ``[units]``.

- one set-up (Exercise 1: ode23 vs ode45): one panel per quantity, inputs underneath;
- several set-ups (Exercise 2's step, sine and ramp inputs, each with ode45, ode23, rk4):
  small multiples, one column per set-up, rows output(s), states, input(s), one legend on top;
- a single solution with several states (the rigid body) is drawn as MATLAB's documentation
  draws it: every state on one axes, markers at the output points;
- a linearisation case: the nonlinear model is the truth (black), the linearised model purple
  and dashed, in every figure of the section.

Error figures plot the quantity the headline measures (:data:`odelab.analysis.errors.HEADLINE_RULE`):
|f - y| / |f| where |f| stays away from zero, |f - y| / max |f| where it does not.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from odelab.report.collect import StoredRun
from odelab.report.events import event_markers, exact_time_lines
from odelab.report.plots import (
    INPUT,
    LINEARISED,
    REFERENCE,
    REFERENCE_ZORDER,
    SERIES_COLORS,
    FigureSpec,
    Line,
    MAX_MARKERS,
    LineStyle,
    Panel,
    RefLine,
    axis_label,
)
from odelab.report.setups import SetUp, case_label, reference_label, reference_union, stats_text, what_differs

__all__ = ["AGAINST", "MAX_GRID", "error_figure", "linearisation_figures", "side_by_side", "solution_figure", "split_grid", "stacked",
           "with_error_row"]

_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
_LINESTYLES = ("-", "--", "-.", ":")
POINTWISE_LABEL = "|f - y| / |f|"
PEAK_LABEL = "|f - y| / max |f|"
NONLINEAR = LineStyle(REFERENCE.color, None, "-", 1.4)  # in a linearisation, the nonlinear model is the truth

AGAINST = {
    "exact": "the exact solution (thin black line, on top)",
    "lti": "the exact LTI response (thin black line, on top)",
    "high-accuracy": "a high-accuracy reference (thin black line, on top)",
    "linearization": "the linearised model (purple, dashed)",
    "data": "each other (the measurements are drawn with the model in the data section below)",
    "none": "each other",
}
MARKERS_NOTE = "Hollow markers are the solver's output points (left out where a line has too many to tell apart)."


def _line(x, y, label: str, style: LineStyle, *, zorder: float = 2.0, marker: bool = True) -> Line:
    return Line(x, y, label, style.color, linestyle=style.linestyle, marker=style.marker if marker else None,
                linewidth=style.linewidth, markersize=4.0, zorder=zorder)


def _member_style(group: SetUp, run: StoredRun, kind: str) -> tuple[LineStyle, str]:
    style = group.styles.get(run.case) or LineStyle(group.colors.get(run.case, "#333333"))
    if kind == "linearization":  # the run *is* the nonlinear model: black, as in the comparison panels
        return LineStyle(NONLINEAR.color, style.marker, "-", NONLINEAR.linewidth), "nonlinear model"
    return style, ""


def _reference_line(members: list[StoredRun], name: str, kind: str) -> Line | None:
    t_ref, f_ref = reference_union(members, name)
    if not t_ref.size:
        return None
    if kind == "linearization":
        return _line(t_ref, f_ref, "linearised model", LINEARISED, zorder=REFERENCE_ZORDER, marker=False)
    return _line(t_ref, f_ref, reference_label(kind), REFERENCE, zorder=REFERENCE_ZORDER, marker=False)


def _solver_lines(group: SetUp, name: str, kind: str, *, points: bool) -> list[Line]:
    """Each member's solution, and the reference on top of them."""
    lines = []
    for i, r in enumerate(group.runs):
        y = r.column(name)
        if y is None or not r.t.size:
            continue
        style, role = _member_style(group, r, kind)
        label = f"{role} ({r.method})" if role else case_label(r, group.prefix)
        if r.status != "success":  # a case cut short says where it stopped, and is drawn on top
            label += f", stopped at t = {float(r.t[-1]):.4g}"
            lines.append(_line(r.t, y, f"{label} ({r.t.size} points)" if points else label,
                               dataclasses.replace(style, linewidth=style.linewidth + 0.8), zorder=REFERENCE_ZORDER + 1))
            continue
        lines.append(_line(r.t, y, f"{label}, {r.t.size} points" if points else label, style, zorder=2 + i))
    ref = _reference_line(group.runs, name, kind)
    return lines + ([ref] if ref is not None else [])


def _input_line(run: StoredRun, name: str) -> Line | None:
    u = run.column(name)
    if u is None or not run.t.size:
        return None
    t, u = with_input_jumps(run.t, u, run.extra.get("input_jumps"), list(run.inputs).index(name)
                            if name in run.inputs else None)
    return _line(t, u, "input", INPUT, zorder=2, marker=False)


def with_input_jumps(t: np.ndarray, u: np.ndarray, jumps: dict | None, column: int | None):
    """The input's rows with its jumps drawn as steps: at each recorded jump time inside the
    rows' span, its value just before and at the jump (``extra["input_jumps"]``), whatever rows
    the solver output there (without them a step is drawn as a slope from the row before)."""
    if not jumps or column is None or t.size < 2 or not t[-1] > t[0]:
        return t, u
    times, before, after = (np.asarray(jumps.get(k, []), dtype=float) for k in ("t", "before", "after"))
    if (times.ndim != 1 or before.ndim != 2 or before.shape != after.shape or before.shape[0] != times.size
            or column >= before.shape[1]):
        return t, u
    inside = (times > t[0]) & (times <= t[-1])
    if not inside.any():
        return t, u
    times, lo, hi = times[inside], before[inside, column], after[inside, column]
    at = np.searchsorted(t, times, side="left")  # before any row already at the jump time
    t_out = np.insert(t.astype(float), np.repeat(at, 2), np.repeat(times, 2))
    u_out = np.insert(np.asarray(u, dtype=float), np.repeat(at, 2), np.column_stack([lo, hi]).reshape(-1))
    return t_out, u_out


def _title(text: str) -> str:
    return text.replace("→", "->")  # the figure font has no arrow


def _shown_text(r: StoredRun, shown: list[str]) -> str:
    """What a one-panel figure shows: "Every state" when it is all of them, else their names."""
    drawn = [n for n in shown if r.column(n) is not None]
    if len(drawn) > 1 and set(drawn) == set(r.states):
        return "Every state"
    return drawn[0] if len(drawn) == 1 else ", ".join(drawn[:-1]) + " and " + drawn[-1]


def solution_figure(stem: str, groups: list[SetUp], shown: list[str], layout: str,
                    units: dict[str, str]) -> FigureSpec | None:
    runs = [r for g in groups for r in g.runs if r.t.size]
    if not runs or not shown:
        return None
    kind = runs[0].reference
    against = AGAINST.get(kind, "the reference")
    t_label = axis_label("t", units.get("t"))
    first = runs[0]
    inputs = list(first.inputs)
    states = [n for n in first.states if n not in shown]
    if layout == "states":
        r = runs[0]
        lines = []
        for j, name in enumerate(shown):
            y, ref = r.column(name), r.column(f"{name}_ref")
            if y is None:
                continue
            style = LineStyle(SERIES_COLORS[j % len(SERIES_COLORS)], _MARKERS[j % len(_MARKERS)],
                              _LINESTYLES[j % len(_LINESTYLES)], 1.1)
            lines.append(_line(r.t, y, f"{name} ({r.method})", style, zorder=2 + j))
            lines.extend(event_markers(r, name, first=j == 0))
            if ref is not None:
                lines.append(_line(r.t, ref, reference_label(kind) if j == 0 else "_nolegend_", REFERENCE,
                                   zorder=REFERENCE_ZORDER, marker=False))
        common = {units.get(n) for n in shown}
        ylabel = axis_label("value", common.pop()) if len(common) == 1 else "value"
        stats = f"{r.nsteps} steps, {r.nfailed if r.nfailed is not None else 'n/a'} failed, {r.nfevals} fevals"
        panels = [Panel(f"{case_label(r)}: {stats}", t_label, ylabel, tuple(lines), legend_outside=True,
                        reflines=exact_time_lines(r))]
        against_ref = f", thin black lines the {reference_label(kind)}" if kind != "none" else ""
        caption = (f"{_shown_text(r, shown)} against t in one panel: "
                   + ("hollow markers at the output points" if r.t.size <= MAX_MARKERS
                      else "lines through the output points (too many to mark)")
                   + f"{against_ref}. {case_label(r)}: {stats_text(r)}.")
        if r.events:
            caption += (" Red triangles mark the located events" + (", dotted vertical lines their exact times"
                                                                      if exact_time_lines(r) else "") + ".")
        return FigureSpec(f"{stem}-solution", caption, f"{stem}: solution against time", tuple(panels),
                          columns=1, panel_height=2.8)
    if layout == "by-quantity" or len(groups) == 1:
        g = groups[0]
        panels = [Panel(name, t_label, axis_label(name, units.get(name)),
                        tuple(_solver_lines(g, name, kind, points=True))
                        + tuple(m for r in g.runs for m in event_markers(r, name, first=r is g.runs[0])),
                        reflines=exact_time_lines(g.runs[0])) for name in shown]
        panels += [Panel("", t_label, axis_label(name, units.get(name)),
                         tuple(x for x in [_input_line(g.runs[0], name)] if x), height=0.6, legend=False)
                   for name in inputs]
        caption = f"Solution against t, every case against {against}. {MARKERS_NOTE}"
        if inputs:
            caption += " The input is drawn under the output it drives."
        return FigureSpec(f"{stem}-solution", caption, f"{stem}: solution against time", tuple(panels),
                          columns=1, panel_height=2.4 if len(shown) == 1 else 2.2)
    # small multiples: one column per set-up; rows: outputs (what the lab shows), states, inputs
    rows = [(name, 1.0) for name in shown] + [(name, 0.8) for name in states] + [(name, 0.55) for name in inputs]
    panels = []
    transpose = len(groups) > 4  # many set-ups: one row per set-up instead
    cells = ([(g, row) for g in groups for row in rows] if transpose else [(g, row) for row in rows for g in groups])
    for g, (name, height) in cells:
        title = _title(g.label) if (transpose and name == rows[0][0]) or (not transpose and name == rows[0][0]) else ""
        if name in inputs:
            line = _input_line(g.runs[0], name)
            lines = (line,) if line else ()
        else:
            lines = tuple(_solver_lines(g, name, kind, points=False))
        panels.append(Panel(title, t_label if (transpose or name == rows[-1][0]) else "",
                            axis_label(name, units.get(name)), lines, height=height, legend=False))
    caption = (f"One column per {what_differs(groups)}: rows show " + ", ".join(n for n, _ in rows)
               + f" against t; cases that differ only in their solver share a panel, every solver against {against}. "
               f"The input is drawn under the responses it drives. {MARKERS_NOTE}")
    return FigureSpec(f"{stem}-solution", caption, f"{stem}: responses and inputs against time", tuple(panels),
                      columns=len(rows) if transpose else len(groups), panel_height=1.5, legend=True)


def _basis(run: StoredRun, name: str) -> str:
    e = run.errors.get(name)
    return e.basis if e is not None else "pointwise"


def error_values(run: StoredRun, name: str) -> tuple[np.ndarray | None, str]:
    """The error curve the headline measures, and its axis label: |f - y| / |f| or |f - y| / max |f|."""
    if _basis(run, name) == "peak":
        abs_err, e = run.column(f"{name}_abs_err"), run.errors.get(name)
        if abs_err is None or e is None or not e.scale:
            return None, PEAK_LABEL
        return abs_err / e.scale, PEAK_LABEL
    return run.column(f"{name}_rel_err"), POINTWISE_LABEL


def error_figure(stem: str, groups: list[SetUp], names: list[str], layout: str,
                 units: dict[str, str]) -> FigureSpec | None:
    runs = [r for g in groups for r in g.runs]
    if not runs:
        return None
    t_label = axis_label("t", units.get("t"))
    kind = runs[0].reference
    panels = []
    note = "the error is zero or undefined at every point"
    if layout == "states":
        r = runs[0]
        lines, labels = [], set()
        for j, name in enumerate(names):
            values, label = error_values(r, name)
            if values is None or not r.t.size:
                continue
            labels.add(label)
            style = LineStyle(SERIES_COLORS[j % len(SERIES_COLORS)], _MARKERS[j % len(_MARKERS)],
                              _LINESTYLES[j % len(_LINESTYLES)], 1.1)
            lines.append(_line(r.t, values, f"{name}: {label}", style))
        if lines:
            ylabel = labels.pop() if len(labels) == 1 else "relative error (see legend)"
            panels.append(Panel(f"error, {case_label(r)}", t_label, ylabel, tuple(lines), yscale="log", note=note,
                                legend_outside=True))
    else:
        # One panel per set-up and quantity, in the solution figure's order, also for a set-up
        # with no reference (an empty panel that says so): with_error_row puts panel g under
        # set-up g, and a skipped one would put another case's errors under this one.
        drawn = False
        for g in groups:
            for name in names:
                lines, label = [], POINTWISE_LABEL
                for i, r in enumerate(g.runs):
                    values, label = error_values(r, name)
                    if values is not None and r.t.size:
                        style, role = _member_style(g, r, kind)
                        lines.append(_line(r.t, values, case_label(r, g.prefix), style, zorder=2 + i))
                drawn = drawn or bool(lines)
                title = _title(g.label) if g.label else f"error of {name}"
                empty = not any(name in r.errors for r in g.runs)
                panels.append(Panel(title, t_label, f"{name}: {label}", tuple(lines), yscale="log",
                                    note="no reference for this set-up: no error to show" if empty else note,
                                    legend=len(groups) == 1))
        if not drawn:
            panels = []
    if not panels:
        return None
    columns = 1 if len(panels) == 1 else min(len(panels), 3)
    caption = ("Error against t on a log scale, as the headline measures it: |f - y| / |f| where the reference "
               "stays above 10% of its peak, |f - y| / max |f| where it comes near zero (the pointwise ratio there "
               "is in the tables). Points where it is zero (the initial point) or undefined are left out.")
    return FigureSpec(f"{stem}-relative-error", caption, f"{stem}: error against time", tuple(panels),
                      columns=columns, panel_height=2.4 if len(panels) == 1 else 2.2,
                      legend=len(groups) > 1 and layout != "states")


def linearisation_figures(stem: str, lin: Any, units: dict[str, str]) -> list[FigureSpec]:
    """The nonlinear (black) and linearised (purple, dashed) responses per amplitude; error against amplitude."""
    figures = []
    panels = []
    t_label = axis_label("t", units.get("t"))
    for comp in lin.comparisons:
        t = comp["t"]
        names = comp["names"]
        lines = []
        for j, name in enumerate(names):
            single = len(names) == 1
            suffix = "" if single else f" {name}"
            nl = NONLINEAR if single else LineStyle(SERIES_COLORS[j % len(SERIES_COLORS)], None, "-", 1.4)
            ln = LINEARISED if single else LineStyle(SERIES_COLORS[j % len(SERIES_COLORS)], None, "--", 1.4)
            lines.append(_line(t, comp["nonlinear"][name], f"nonlinear model{suffix}", nl, marker=False))
            lines.append(_line(t, comp["linear"][name], f"linearised model{suffix}", ln, zorder=3, marker=False))
        err = comp.get("error")
        title = f"step {comp['amplitude']:g}" + (f": {err:.2%}" if err is not None else "")
        if comp.get("status", "success") != "success":
            title += f", {comp['status']}"
        name = names[0] if len(names) == 1 else "value"
        panels.append(Panel(title, t_label, axis_label(name, units.get(name)), tuple(lines), legend=False))
    responses = panels
    lines = []
    amplitudes = np.array(lin.amplitudes, dtype=float)
    for j, name in enumerate(lin.error_names):
        values = np.array([np.nan if row[1][j] is None else row[1][j] for row in lin.error_rows], dtype=float)
        lead = name == lin.quantity or (j == 0 and not lin.quantity)
        # the study's quantity in front; others thinner, dashed, so coinciding curves (y = q x) stay visible
        lines.append(Line(amplitudes, values, name, SERIES_COLORS[j % len(SERIES_COLORS)],
                          linestyle="-" if lead else _LINESTYLES[1 + j % 3], marker=_MARKERS[j % len(_MARKERS)],
                          linewidth=2.0 if lead else 1.1, markersize=5 if lead else 3.5, zorder=2 if lead else 3))
    if lines:
        refs = [RefLine(lin.threshold, f"threshold {lin.threshold:g}")]
        if lin.threshold_amplitude is not None:
            refs.append(RefLine(lin.threshold_amplitude, f"threshold reached at {lin.threshold_amplitude:.3g}",
                                axis="x", color="#555555", linestyle=":"))
        elif lin.max_amplitude_within is not None:
            refs.append(RefLine(lin.max_amplitude_within, f"largest amplitude within: {lin.max_amplitude_within:g}",
                                axis="x", color="#555555", linestyle=":"))
        slope = (f" The log-log slope is {lin.slope:.2f}: the error grows as the amplitude to that power."
                 if lin.slope is not None else "")
        drive = next((v for k, v in lin.settings if k == "input stepped"), "")
        xunit = units.get(drive) if drive else None
        error_panel = Panel("linearisation error", axis_label(f"step of {drive}" if drive else "step", xunit),
                            "error / peak", tuple(lines), xscale="log", yscale="log",
                            reflines=tuple(refs), note="no positive error to show on a log scale", legend=False)
        error_caption = (f"The last panel: the error of the linearised model, max |nonlinear - linear| divided by "
                         f"the peak incremental response, against the step amplitude, with the threshold "
                         f"{lin.threshold:g}.{slope}")
    else:
        error_panel, error_caption = None, ""
    panels = responses + ([error_panel] if error_panel is not None else [])
    if panels:
        n = len(panels)
        cols = 3 if n >= 5 else 2 if n >= 2 else 1  # at most MAX_GRID columns: 8pt ticks stay readable
        caption = ("Nonlinear model (black, solid) and linearised model (purple, dashed) for each step amplitude of "
                   "the input; each title gives the step and the error of the linearised model, relative to the peak "
                   "incremental response." if responses else "") + (" " + error_caption if error_caption else "")
        figures.append(FigureSpec(
            f"{stem}-linearisation", caption.strip(),
            f"{lin.case}: nonlinear and linearised responses per amplitude, and the error against amplitude",
            tuple(panels), columns=cols, panel_height=1.3 if cols >= 3 else 2.0, legend=bool(responses)))
    return figures


def stacked(solution: FigureSpec | None, error: FigureSpec | None, above: int = 1) -> FigureSpec | None:
    """One column: the first ``above`` solution panels, the error panels, then the rest (the inputs).

    The rigid body's states over their errors; a single set-up's outputs over their errors over its input.
    """
    if solution is None or error is None or solution.columns != 1 or len(solution.panels) < above:
        return None

    error_panels = tuple(dataclasses.replace(p, height=0.9) for p in error.panels)
    panels = solution.panels[:above] + error_panels + solution.panels[above:]
    return dataclasses.replace(solution, panels=panels, columns=1, panel_height=2.0,
                               caption=f"Top: {solution.caption} Bottom: {error.caption}",
                               alt=f"{solution.alt}; {error.alt}")


def side_by_side(solution: FigureSpec | None, error: FigureSpec | None) -> FigureSpec | None:
    """One quantity, no inputs (Exercise 1): the solution and its error as one figure of two panels.

    Half a printed page instead of a whole one, and the error sits next to the curve it measures.
    Returns None when the two do not fit that shape (the caller keeps them apart).
    """
    if solution is None or error is None or len(solution.panels) != 1 or len(error.panels) != 1:
        return None
    return FigureSpec(solution.name, f"Left: {solution.caption} Right: {error.caption}",
                      f"{solution.alt}; {error.alt}", solution.panels + error.panels, columns=2, panel_height=2.6)


def with_error_row(solution: FigureSpec | None, error: FigureSpec | None) -> FigureSpec | None:
    """Small multiples (one column per set-up): the error panels as the row under the outputs.

    One figure instead of two, each error right under the response it measures. Returns None
    unless the error figure has exactly one panel per column of the solution figure.
    """
    if solution is None or error is None or not solution.legend:
        return None
    columns = solution.columns
    k, rest = divmod(len(error.panels), columns)  # error panels come set-up by set-up, k quantities each
    if rest or k == 0 or len(solution.panels) < 2 * k * columns:
        return None

    panels: tuple = ()
    for j in range(k):  # row j of the solution (quantity j), then its error row
        row = tuple(dataclasses.replace(error.panels[g * k + j], title="", xlabel="", height=0.9, legend=False)
                    for g in range(columns))
        panels += solution.panels[j * columns:(j + 1) * columns] + row
    panels += solution.panels[k * columns:]
    return dataclasses.replace(solution, panels=panels, caption=f"{solution.caption} Under each response: {error.caption}",
                               alt=f"{solution.alt}, with the error")


#: A printed figure holds at most this many rows and columns of panels (issue 37: a 3 x 7 grid
#: squeezed onto a page had unreadable axis text); a larger grid is split into figures of this size.
MAX_GRID = 3


def _rows_of(spec: FigureSpec) -> list[tuple[Panel, ...]]:
    cols = max(1, min(spec.columns, len(spec.panels)))
    return [spec.panels[i:i + cols] for i in range(0, len(spec.panels), cols)]


def _is_error_row(row: tuple[Panel, ...]) -> bool:
    """A row of errors drawn under the responses above it (with_error_row): it never starts a part."""
    return all(p.height < 1.0 and not p.title and not p.xlabel and p.yscale == "log" for p in row)


def split_grid(spec: FigureSpec | None, limit: int = MAX_GRID) -> list[FigureSpec]:
    """``spec`` as figures of at most ``limit`` x ``limit`` panels, in order (itself if it fits).

    More than ``limit`` columns of panels each titled on its own (an amplitude study) flow into
    ``limit`` columns; more than ``limit`` rows are cut into parts of whole rows, never between a
    response and the error row under it, each part titled with the first row's column titles
    (the set-ups) and captioned as a continuation of the first."""
    if spec is None:
        return []
    if spec.columns > limit and all(p.title for p in spec.panels):
        spec = dataclasses.replace(spec, columns=limit)
    rows = _rows_of(spec)
    if len(rows) <= limit or spec.columns > limit:
        return [spec]
    size = math.ceil(len(rows) / math.ceil(len(rows) / limit))  # balanced: 4 rows as 2 + 2, not 3 + 1
    parts: list[list[tuple[Panel, ...]]] = [[]]
    for k, row in enumerate(rows):
        nxt_is_error = k + 1 < len(rows) and _is_error_row(rows[k + 1])
        full = len(parts[-1]) >= size or (len(parts[-1]) + 1 >= size and nxt_is_error and parts[-1])
        if full and not _is_error_row(row) and len(parts[-1]) < limit or len(parts[-1]) >= limit:
            parts.append([])
        parts[-1].append(row)
    heads = [p.title for p in rows[0]]
    out = []
    for i, part in enumerate(parts):
        first = part[0]
        if i and not any(p.title for p in first) and len(first) == len(heads):
            first = tuple(dataclasses.replace(p, title=h) for p, h in zip(first, heads))
        panels = first + tuple(p for row in part[1:] for p in row)
        if i == 0:
            caption = f"{spec.caption} (Continued in the next {len(parts) - 1} figure{'s' if len(parts) > 2 else ''}.)"
            out.append(dataclasses.replace(spec, panels=panels, caption=caption))
        else:
            out.append(dataclasses.replace(spec, name=f"{spec.name}-{i + 1}", panels=panels,
                                           caption=f"Continued ({i + 1} of {len(parts)}): the next rows of the "
                                                   "figure above, in its styles.", alt=f"{spec.alt} (continued)"))
    return out
