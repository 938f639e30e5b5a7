"""The report's view of located events: a table per case, markers on the solution plots.

A stored run lists its events in result.json (``events``: name, t, state, exact_t, reset; see
:mod:`odelab.experiment.events`). The report lists them in a table, with the exact time and
the error when the experiment gives one (the bouncing ball's geometric series), draws each
event as a filled marker on the curves, and the exact times as thin vertical lines.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from odelab.report.collect import StoredRun
from odelab.report.plots import Line, RefLine

__all__ = ["EventTable", "event_table", "event_markers", "exact_time_lines"]

EVENT_COLOR = "#B00020"
MAX_EXACT_LINES = 12  # more vertical lines than this would hide the curves
MAX_ROWS = 60  # events listed per case; result.json has them all


@dataclass(frozen=True, eq=False)
class EventTable:
    """The events of one case, as table rows."""

    case: str
    method: str
    states: list[str]
    exact: bool  # whether the exact time and its error are shown
    rows: list[tuple]  # (number, name, t, exact t or None, |t - exact| or None, [state values], reset text)
    omitted: int
    max_error: float | None  # largest |t - exact| over all events with an exact time

    def __len__(self) -> int:
        return len(self.rows) + self.omitted


def event_table(run: StoredRun) -> EventTable | None:
    events = run.events
    if not events:
        return None
    exact = any("exact_t" in e for e in events)
    states = list(run.states)
    rows = []
    errors = [abs(e["t"] - e["exact_t"]) for e in events if "exact_t" in e]
    for number, e in enumerate(events[:MAX_ROWS], start=1):
        exact_t = e.get("exact_t")
        values = [e["state"].get(s) for s in states]
        reset = e.get("reset") or {}
        changed = ", ".join(f"{k} = {v:.6g}" for k, v in reset.items()
                            if isinstance(v, (int, float)) and v != e["state"].get(k))
        rows.append((number, e["name"], e["t"], exact_t, None if exact_t is None else abs(e["t"] - exact_t),
                     values, changed))
    return EventTable(case=run.case, method=run.method, states=states, exact=exact, rows=rows,
                      omitted=max(0, len(events) - MAX_ROWS), max_error=max(errors) if errors else None)


def event_markers(run: StoredRun, name: str, *, first: bool = True) -> list[Line]:
    """The events of ``run`` as filled markers on the curve of ``name`` (state values at the events)."""
    points = [(e["t"], e["state"][name]) for e in run.events if isinstance(e["state"].get(name), (int, float))]
    if not points:
        return []
    t, y = np.array(points, dtype=float).T
    return [Line(t, y, "events" if first else "_nolegend_", EVENT_COLOR, linestyle="none", marker="v",
                 linewidth=0.0, markersize=6.0, zorder=6.0)]


def exact_time_lines(run: StoredRun) -> tuple[RefLine, ...]:
    """The exact event times as thin vertical lines, when the experiment gives them (and few)."""
    times = [e["exact_t"] for e in run.events if "exact_t" in e]
    if not times or len(times) > MAX_EXACT_LINES:
        return ()
    return tuple(RefLine(value=float(t), label="exact event times" if i == 0 else "_nolegend_", axis="x",
                         color="#888888", linestyle=":") for i, t in enumerate(times))
