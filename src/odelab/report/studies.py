"""The report's sections for sweeps and studies, read from ``runs/<experiment>/sweep.json``.

- a study: its kind's section (:mod:`odelab.report.study_sections`), e.g. a convergence study's
  error against h on log-log axes with each method's fitted C h^p, or a work-precision study's
  error against function evaluations and time;
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

import numpy as np

from odelab.experiment.studykinds import STUDY_KINDS
from odelab.experiment.studykinds import fmt_number as _g
from odelab.experiment.studykinds import key_label as _label
from odelab.report.plots import SERIES_COLORS, FigureSpec, Line, Panel
from odelab.report.study_sections import MARKERS as _MARKERS
from odelab.report.study_sections import draw_study
from odelab.store.sweeps import SWEEP_FORMAT

__all__ = ["StudySection", "asked_for", "collect_studies", "study_sections"]


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
    kind: str  # a study kind (odelab.experiment.studykinds.STUDY_KINDS) or "sweep"
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
        if experiments is None or asked_for(record, experiments):
            records.append(record)
    return records, warnings


def asked_for(record: dict, experiments: list[str]) -> str | None:
    """The name in ``experiments`` that asks for this sweep record: its own, or, for a study, its
    file's name (a study file ``work-precision`` stores one record per target, ``work-precision_exercise1``)."""
    name = str(record.get("experiment", ""))
    if name in experiments:
        return name
    if isinstance(record.get("study"), dict):
        return next((n for n in experiments if name.startswith(f"{n}_")), None)
    return None


_METRICS = (("overshoot_percent", "overshoot (%)"), ("max", "peak"), ("final", "final value"))


_STEP_INFO = (("RiseTime", "rise time"), ("SettlingTime", "settling time"), ("Overshoot", "overshoot (%)"),
              ("Peak", "peak"), ("PeakTime", "peak time"))


def _step_info_table(rows: list[dict], section: StudySection) -> None:
    """[analysis] step_info in a sweep: MATLAB's stepinfo of each case's first channel, beside its response."""
    channel = next(((s.get("output"), s.get("input")) for r in rows for s in (r.get("step_info") or [])
                    if isinstance(s, dict)), None)
    if channel is None:
        return
    # stepinfo's overshoot and peak replace those read off the sampled trajectory (the same quantities,
    # exactly): the final value stays
    drop = [i for i, h in enumerate(section.header) if h.endswith((" overshoot (%)", " peak"))]
    section.header = [h for i, h in enumerate(section.header) if i not in drop] + [label for _, label in _STEP_INFO]
    section.rows = [[c for i, c in enumerate(cells) if i not in drop] for cells in section.rows]
    for r, cells in zip(rows, section.rows):
        s = next((s for s in (r.get("step_info") or []) if isinstance(s, dict)
                  and (s.get("output"), s.get("input")) == channel), {})
        for key, _ in _STEP_INFO:
            value = s.get(key)
            if key == "SettlingTime" and value is None and s.get("SteadyStateValue") is not None:
                cells.append("does not settle")
            elif key == "PeakTime" and value is None and s:
                cells.append("∞")
            else:
                cells.append(_g(value))
    section.notes.append(f"rise time to peak time: MATLAB's stepinfo of {channel[1]} -> {channel[0]} in each case's "
                         "linear model ([analysis] step_info; all channels in sweep.csv); peak time ∞: the response "
                         "approaches its final value without passing it")


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
    _step_info_table(rows, section)
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
            if study and study["kind"] in STUDY_KINDS:  # each kind's section: report/study_sections.py
                draw_study(record, study, section)
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
