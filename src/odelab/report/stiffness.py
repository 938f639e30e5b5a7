"""The "why stiff solvers" part of a section: what each method paid for the same problem.

Shown when an experiment runs a stiff method (ode15s, ode23s, Radau...) next to others. The
table lists each case's successful steps, failed attempts, function evaluations, Jacobians,
LU decompositions, linear solves, run time and how far it got; the figure plots the step size
each method took against t on a log scale, where a non-stiff method's steps stay pinned at its
stability limit (a few 1e-3 for van der Pol with mu = 1000) while the stiff solvers' grow with
the smooth solution. One sentence states the comparison in numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.report.collect import StoredRun
from odelab.report.plots import FigureSpec, Line, Panel, axis_label, method_style
from odelab.solvers.registry import METHODS

__all__ = ["StiffnessView", "stiffness_view"]


@dataclass(eq=False)
class StiffnessView:
    rows: list[dict]  # case, method, kind, status, nsteps, nfailed, nfevals, npds, ndecomps, nsolves, elapsed, reached
    summary: str
    figure: Any = None  # a FigureSpec, replaced by the drawn figure when rendering
    notes: list[str] = field(default_factory=list)
    stiff: bool = True  # the runs show stiffness; False: a plain cost comparison, titled as such

    @property
    def title(self) -> str:
        return "Why stiff solvers" if self.stiff else "Explicit and stiff solvers on this problem"


# An explicit method this many times costlier in steps than a stiff one (or stopped by its step
# limit) is what "stiff" means in the data; short of that the report claims nothing about it.
STIFF_STEP_RATIO = 5.0


def _method(name: str):
    return METHODS.get(name)


def _steps(run: StoredRun) -> tuple[np.ndarray, np.ndarray] | None:
    """(t at the end of each step, step size) from the stored output points, if they are the steps."""
    solver = run.config.get("solver", {}) if isinstance(run.config.get("solver"), dict) else {}
    time = run.config.get("time", {}) if isinstance(run.config.get("time"), dict) else {}
    if time.get("output") is not None or time.get("points") is not None or run.inputs:
        return None  # output at the user's times (or pieces between input breakpoints): steps unknown
    m = _method(run.method)
    if m is None or not m.adaptive or m.delays:
        return None
    refine = int(solver.get("refine", m.refine if m.matlab_defaults else 1) or 1)
    t = run.t[::refine]
    if t.size < 2:
        return None
    return t[1:], np.abs(np.diff(t))


def stiffness_view(stem: str, runs: list[StoredRun], units: dict[str, str]) -> StiffnessView | None:
    methods = [_method(r.method) for r in runs]
    if not any(m is not None and m.stiff for m in methods) or len(runs) < 2:
        return None
    rows = []
    lines = []
    for r, m in zip(runs, methods):
        stats = r.stats if isinstance(getattr(r, "stats", None), dict) else {}
        reached = float(r.t[-1]) if r.t.size else float("nan")
        rows.append({
            "case": r.case, "method": r.method, "kind": m.kind_label if m else "", "status": r.status,
            "nsteps": r.nsteps, "nfailed": r.nfailed, "nfevals": r.nfevals, "npds": stats.get("npds"),
            "ndecomps": stats.get("ndecomps"), "nsolves": stats.get("nsolves"), "elapsed": r.elapsed_s,
            "reached": reached,
        })
        steps = _steps(r)
        if steps is not None:
            style = method_style(r.method)
            label = r.method if r.case == r.method else f"{r.case} ({r.method})"
            lines.append(Line(steps[0], steps[1], label, style.color, linestyle=style.linestyle, marker=None,
                              linewidth=1.3))
    stiff = [row for row, m in zip(rows, methods) if m is not None and m.stiff and row["status"] == "success"]
    other = [row for row, m in zip(rows, methods) if m is None or not m.stiff]
    stopped = [r for r, m in zip(runs, methods) if (m is None or not m.stiff) and r.status != "success"
               and "after max_steps" in r.message]
    fewest = min((row["nsteps"] for row in stiff if row["nsteps"]), default=None)
    costly = [row for row in other if row["status"] == "success" and fewest and row["nsteps"]
              and row["nsteps"] >= STIFF_STEP_RATIO * fewest]
    evidence = bool(stiff and other and (stopped or costly))
    summary = ""
    if stiff and other and not evidence:
        explicit = ", ".join(f"{row['method']} {row['nsteps']:,}" for row in other if row["nsteps"] is not None)
        implicit = ", ".join(f"{row['method']} {row['nsteps']:,}" for row in stiff)
        summary = (f"This problem is not stiff: the explicit methods took no more steps than the stiff ones "
                   f"({explicit}; {implicit}). A stiff solver's step costs a Jacobian and linear solves, which pays "
                   "off only where stability, not accuracy, holds an explicit method's step down "
                   "(experiments/stiff.toml shows such a problem).")
    if evidence:
        end = max(row["reached"] for row in stiff)
        start = float(runs[0].t[0]) if runs[0].t.size else 0.0
        first, *rest = stiff
        covered = (f"Over the whole span {first['method']} took {first['nsteps']:,} steps "
                   f"({first['nfevals']:,} evaluations)"
                   + "".join(f", {row['method']} {row['nsteps']:,} ({row['nfevals']:,})" for row in rest))
        parts = []
        for row in other:
            if row["status"] == "success":
                parts.append(f"{row['method']} needed {row['nsteps']:,} steps and {row['nfevals']:,} evaluations")
            else:
                rate = row["nsteps"] / max(row["reached"] - start, 1e-300)
                parts.append(f"{row['method']} stopped at t = {row['reached']:.4g} of {end:.4g} after "
                             f"{row['nsteps']:,} steps (at that pace the whole span would take about "
                             f"{rate * (end - start):,.0f} steps)")
        summary = (covered + "; " + "; ".join(parts) + ". An explicit method's step is held at its stability "
                   "limit wherever the solution is smooth, so its cost grows with the length of the span; an "
                   "implicit method's step follows the accuracy the tolerance asks for.")
    figure = None
    if lines:
        panel = Panel("step size against t", axis_label("t", units.get("t")), "step size h", tuple(lines),
                      yscale="log")
        caption = ("The step size each method took, against t (log scale)."
                   + (" Where the solution is smooth the stiff solvers take steps many orders of magnitude longer "
                      "than the explicit method can." if evidence else ""))
        figure = FigureSpec(f"{stem}-step-size", caption, f"{stem}: step size against time", (panel,),
                            panel_height=2.6)
    return StiffnessView(rows=rows, summary=summary, figure=figure, stiff=evidence)
