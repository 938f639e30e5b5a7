"""The report's sections for sweeps and studies, read from ``runs/<experiment>/sweep.json``.

- a convergence study: error against h on log-log axes per problem, each method's points with
  its fitted line C h^p drawn dashed, the points left out of the fit as crosses, and a table
  of observed against nominal orders;
- a work-precision study: error against function evaluations and against time, one curve
  per method;
- a sweep without a study: the quantity of interest (overshoot, peak, final value) against
  each swept number, one line per value of the other swept keys.

As in :mod:`odelab.report.content`, this module says what to show as plain data; the
templates format it and :mod:`odelab.report.plots` draws it.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from odelab.report.plots import SERIES_COLORS, FigureSpec, Line, Panel, method_color

__all__ = ["SWEEP_FORMAT", "StudySection", "collect_studies", "study_sections"]

SWEEP_FORMAT = "odelab-sweep/1"
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")


@dataclass(eq=False)
class StudySection:
    """One sweep's section: what the templates show."""

    name: str
    anchor: str
    title: str
    description: str
    source: str
    file_sha256: str
    created: str
    kind: str  # "convergence", "work-precision" or "sweep"
    summary: str
    header: list[str]
    rows: list[list[str]]
    figures: list = field(default_factory=list)  # FigureSpec, then Figure once drawn
    notes: list[str] = field(default_factory=list)
    cases: int = 0
    failed: int = 0


def collect_studies(runs: Path, experiments: list[str] | None = None) -> tuple[list[dict], list[str]]:
    """Every readable ``sweep.json`` under ``runs`` (those of ``experiments`` if given), and warnings."""
    records, warnings = [], []
    for path in sorted(Path(runs).glob("*/sweep.json")):
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
            if not isinstance(record, dict) or record.get("format") != SWEEP_FORMAT:
                raise ValueError(f"not an odelab sweep (format {SWEEP_FORMAT})")
            for key in ("experiment", "sweep", "rows"):
                if key not in record:
                    raise ValueError(f"no {key!r}")
            if not isinstance(record["rows"], list) or not isinstance(record["sweep"], dict):
                raise ValueError("malformed rows or sweep")
        except (OSError, ValueError) as exc:
            warnings.append(f"{path}: skipped, it cannot be read: {exc}")
            continue
        if experiments is None or record["experiment"] in experiments:
            records.append(record)
    return records, warnings


def _g(value: Any, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if isinstance(value, (int, float)):
        return f"{value:.{digits}g}"
    return str(value)


def _label(key: str) -> str:
    return key.rsplit(".", 1)[-1]


def _curve_color(label: str, method: str, i: int) -> str:
    return method_color(label) if label == method else SERIES_COLORS[i % len(SERIES_COLORS)]


def _convergence(record: dict, study: dict, section: StudySection) -> None:
    over = _label(study["over"])
    what = "largest error over the span" if study["error"] == "max" else "error at the final time"
    section.summary = (f"Global error of {study['quantity']} ({what}) against {over}, and the observed order: the "
                       f"least-squares slope of log error on log {over}. Points left out of the fit (crosses) are "
                       "spoiled by round-off or by steps too large for the asymptotic regime.")
    section.header = ["method", f"{over} from", f"{over} to", "points fitted", "observed order", "nominal order",
                      "observed − nominal"]
    lines = []
    for i, c in enumerate(study["curves"]):
        h = np.asarray(c["h"], dtype=float)
        err = np.array([np.nan if e is None else e for e in c["error"]], dtype=float)
        used = np.array([not why for why in c["excluded"]])
        order, nominal = c["order"], c["nominal"]
        color = _curve_color(c["label"], c["method"], i)
        marker = _MARKERS[i % len(_MARKERS)]
        fitted = order is not None and math.isfinite(order)
        name = f"{c['label']}: slope {order:.2f}" if fitted else f"{c['label']}: no fit"
        lines.append(Line(h[used], err[used], name, color, linestyle="none", marker=marker, markersize=5))
        if np.any(~used):
            lines.append(Line(h[~used], err[~used], "_left out", color, linestyle="none", marker="x", markersize=6))
        if fitted and np.count_nonzero(used) >= 2:
            hs = np.array([h[used].min(), h[used].max()])
            lines.append(Line(hs, 10.0 ** (c["intercept"] + order * np.log10(hs)), "_fit", color, linestyle="--",
                              linewidth=1.0))
        diff = order - nominal if fitted and nominal is not None else None
        section.rows.append([c["label"], _g(min(h)), _g(max(h)), f"{int(used.sum())} of {h.size}",
                             (f"{order:.3f} ({c['note']})" if c.get("note") else f"{order:.3f}") if fitted else "—",
                             "—" if nominal is None else f"{nominal:g}",
                             "—" if diff is None else f"{diff:+.3f}"])
    panel = Panel(title=record.get("title") or record["experiment"], xlabel=f"{over} (log)",
                  ylabel=f"{study['quantity']} error (log)", lines=tuple(lines), xscale="log", yscale="log",
                  legend_outside=True, decades=16)  # every point down to round-off
    section.figures.append(FigureSpec(
        name=f"{section.anchor}-convergence", panels=(panel,), panel_height=3.0,
        caption=f"Convergence: {what} of {study['quantity']} against {over}, log-log; dashed: the fitted C {over}^p, "
                "crosses: points left out of the fit.",
        alt=f"log-log plot of the error against {over} for " + ", ".join(c["label"] for c in study["curves"])))


def _work_precision(record: dict, study: dict, section: StudySection) -> None:
    what = "largest error over the span" if study["error"] == "max" else "error at the final time"
    section.summary = (f"Work-precision: the {what} of {study['quantity']} against the work it cost, over a "
                       f"sweep of {_label(study['over'])}. Lower left is better: the same accuracy for less work.")
    section.header = ["method", "loosest: error", "fevals", "tightest: error", "fevals", "time (s)",
                      "fevals ×10 per digit"]
    fev_lines, time_lines = [], []
    for i, c in enumerate(study["curves"]):
        err = np.array([np.nan if e is None else e for e in c["error"]], dtype=float)
        fev = np.asarray(c["nfevals"], dtype=float)
        sec = np.asarray(c["seconds"], dtype=float)
        color = _curve_color(c["label"], c["method"], i)
        marker = _MARKERS[i % len(_MARKERS)]
        fev_lines.append(Line(err, fev, c["label"], color, marker=marker))
        time_lines.append(Line(err, sec, c["label"], color, marker=marker))
        slope = c.get("slope")
        section.rows.append([c["label"], _g(err[0], 3), _g(fev[0], 6), _g(err[-1], 3), _g(fev[-1], 6),
                             _g(float(np.nansum(sec)), 3),
                             "—" if slope is None or not math.isfinite(slope) else f"×{10 ** slope:.2f}"])
    title = record.get("title") or record["experiment"]
    section.figures.append(FigureSpec(
        name=f"{section.anchor}-work-precision", columns=2, panel_height=2.6,
        panels=(Panel(title="function evaluations", xlabel=f"{study['quantity']} error (log)",
                      ylabel="function evaluations (log)", lines=tuple(fev_lines), xscale="log", yscale="log", decades=16),
                Panel(title="time", xlabel=f"{study['quantity']} error (log)", ylabel="seconds (log)",
                      lines=tuple(time_lines), xscale="log", yscale="log", decades=16)),
        caption=f"{title}: {what} of {study['quantity']} against function evaluations (left) and time (right), "
                "one curve per method, from loose to tight tolerances. Times of a few milliseconds are noisy.",
        alt="work-precision diagram of " + ", ".join(c["label"] for c in study["curves"])))


_METRICS = (("overshoot_percent", "overshoot (%)"), ("max", "peak"), ("final", "final value"))


def _parameter_sweep(record: dict, section: StudySection) -> None:
    keys = record["sweep"]["keys"]
    rows = [r for r in record["rows"] if isinstance(r, dict)]
    numeric = [k for k in keys if all(isinstance(r.get("swept", {}).get(k), (int, float))
                                     and not isinstance(r["swept"][k], bool) for r in rows)]
    quantity = next(iter(rows[0].get("metrics") or {}), None) if rows else None
    section.summary = (f"{len(rows)} cases over {', '.join(keys)} ({record['sweep'].get('mode', 'product')}); "
                       "every case's numbers are in sweep.csv next to sweep.json.")
    section.header = ["case", "status", "steps", "fevals"] + ([f"{quantity} {label}" for _, label in _METRICS]
                                                               if quantity else [])
    unsettled = []
    for r in rows:
        m = (r.get("metrics") or {}).get(quantity, {}) if quantity else {}
        if m.get("settled") is False:
            unsettled.append(r["case"])
    for r in rows[:60]:
        m = (r.get("metrics") or {}).get(quantity, {}) if quantity else {}
        cells = [_g(m.get(k)) for k, _ in _METRICS][:len(section.header) - 4]
        if cells and m.get("settled") is False:
            cells[0] += " *"  # the overshoot is measured against a value that is still moving
        section.rows.append([r["case"], r["status"], _g(r.get("nsteps"), 8), _g(r.get("nfevals"), 8)] + cells)
    if len(rows) > 60:
        section.notes.append(f"the table shows the first 60 of {len(rows)} cases")
    if unsettled:
        shown = ", ".join(unsettled[:5]) + (f" and {len(unsettled) - 5} more" if len(unsettled) > 5 else "")
        section.notes.append(f"* not settled by the end of the span ({shown}): over its last tenth the response still "
                             f"moves by more than 2 % of the change, so its overshoot is measured against a value "
                             "that is not yet the steady state (stepinfo's, from the DC gain, can differ): "
                             "lengthen [time] stop")
    if not numeric or quantity is None:
        return
    x_key = numeric[0]
    others = [k for k in keys if k != x_key]
    groups: dict[str, list[dict]] = {}
    for r in rows:
        label = ", ".join(f"{_label(k)}={r['swept'][k]}" for k in others) or "_one line"  # no legend for one line
        groups.setdefault(label, []).append(r)
    panels = []
    for metric, label in _METRICS:
        lines = []
        for i, (name, members) in enumerate(groups.items()):
            members = sorted(members, key=lambda r: r["swept"][x_key])
            x = np.array([r["swept"][x_key] for r in members], dtype=float)
            y = np.array([_num((r.get("metrics") or {}).get(quantity, {}).get(metric)) for r in members])
            lines.append(Line(x, y, name, SERIES_COLORS[i % len(SERIES_COLORS)], marker=_MARKERS[i % len(_MARKERS)]))
        panels.append(Panel(title=f"{quantity}: {label}", xlabel=_label(x_key), ylabel=label, lines=tuple(lines)))
    section.figures.append(FigureSpec(
        name=f"{section.anchor}-sweep", panels=tuple(panels), columns=3, panel_height=2.6,
        caption=f"The quantity of interest against {_label(x_key)}: overshoot (as MATLAB's stepinfo: beyond the final "
                f"value, in % of the change), peak and final value of {quantity}.",
        alt=f"{quantity} overshoot, peak and final value against {_label(x_key)}"))


def _num(value) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan


def study_sections(records: list[dict], taken: set[str]) -> tuple[list[StudySection], list[str]]:
    """One section per stored sweep, with its table and figure specs."""
    from odelab.report.content import anchor_for

    sections, warnings = [], []
    for record in records:
        study = record.get("study") if isinstance(record.get("study"), dict) else None
        rows = record["rows"]
        section = StudySection(
            name=record["experiment"], anchor=anchor_for(record["experiment"], taken),
            title=record.get("title") or record["experiment"], description=record.get("description") or "",
            source=str(record.get("source", "")), file_sha256=str(record.get("file_sha256", "")),
            created=str(record.get("created", "")), kind=study["kind"] if study else "sweep", summary="", header=[],
            rows=[], cases=len(rows), failed=sum(1 for r in rows if isinstance(r, dict) and r.get("status") != "success"))
        try:
            if study and study["kind"] == "convergence":
                _convergence(record, study, section)
            elif study and study["kind"] == "work-precision":
                _work_precision(record, study, section)
            else:
                _parameter_sweep(record, section)
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            text = f"{record['experiment']}: the sweep cannot be shown: {exc!r}"
            warnings.append(text)
            section.notes.append(text)
            section.figures = []
        if record.get("complete") is False:
            section.notes.insert(0, f"the run was interrupted: {len(rows)} of {record.get('cases_total', '?')} cases "
                                    "finished and are shown")
        if study:
            section.notes.extend(str(w) for w in study.get("warnings", []))
        sections.append(section)
    return sections, warnings
