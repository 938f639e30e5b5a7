"""What the report says about each experiment: tables, notes and figure specs, as plain data.

Nothing here formats text for one output or draws: the templates format (HTML or Markdown)
and :mod:`odelab.report.plots` draws the :class:`~odelab.report.plots.FigureSpec` objects.
The choice of plots follows the data, not the experiment's name. Cases are grouped into
*set-ups*: cases whose resolved configurations differ only in ``[solver]`` share a reference
and a panel, each solver drawn in its report-wide colour against the reference in black.

- one set-up (Exercise 1: ode23 vs ode45): one panel per quantity;
- several set-ups (Exercise 2's step, sine and ramp inputs, each with ode45 and ode23): one
  panel per set-up;
- a single solution with several states (the rigid body) is drawn as MATLAB's documentation
  draws it: every state on one axes, markers at the output points, with the step statistics;
- a case carrying ``extra["linearization"]`` gets the nonlinear-vs-linearised comparison per
  amplitude, the error against amplitude with its threshold, the operating point and A, B, C, D.

Systems with outputs are shown by their outputs (the lab displays y), others by their states;
the error tables list every quantity with a reference.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.report.collect import ExperimentRuns, QuantityErrors, StoredRun
from odelab.report.events import event_table
from odelab.report.figures import (
    error_figure,
    linearisation_figures,
    side_by_side,
    solution_figure,
    split_grid,
    stacked,
    with_error_row,
)
from odelab.report.settings import settings_diff, toml_text
from odelab.report.setups import SetUp, describe_signal, inputs_text, plot_quantities, setups, units_of

__all__ = [
    "CaseView",
    "LabNote",
    "LinearisationView",
    "Section",
    "SetUp",
    "StepTable",
    "anchor_for",
    "build_sections",
    "describe_signal",
    "format_bound",
    "linearisation_view",
    "setups",
]

REFERENCE_TEXT = {
    "exact": "the exact solution given in the experiment file",
    "lti": "the exact response of the linear system (matrix exponential)",
    "high-accuracy": "a high-accuracy solve",
    "linearization": "the linearised model (the error is the linearisation error)",
    "data": "the measurements in [data], at the measured times",
    "none": "no reference",
}


# --- small views ------------------------------------------------------------------------------


@dataclass(frozen=True)
class StepLine:
    """A line of a per-step table as shown: a row, or a gap saying how many rows are left out there."""

    row: tuple | None  # (t, y, reference, |f - y|, |f - y| / |f|), or None for a gap
    gap: int = 0  # rows left out at a gap
    printed: bool = True  # the line is printed
    screen: bool = True  # the line is on screen


@dataclass(frozen=True, eq=False)
class StepTable:
    """The lab's per-step table of one quantity of one case: t, y, reference, |f - y|, |f - y| / |f|."""

    case: str
    method: str
    quantity: str
    t: np.ndarray
    value: np.ndarray
    reference: np.ndarray
    abs_err: np.ndarray
    rel_err: np.ndarray

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def label(self) -> str:
        return self.method if self.case == self.method else f"{self.case} ({self.method})"

    def _row(self, i: int) -> tuple:
        rel = float(self.rel_err[i])
        return (float(self.t[i]), float(self.value[i]), float(self.reference[i]), float(self.abs_err[i]),
                None if math.isnan(rel) else rel)

    def maxima(self) -> set[int]:
        """The rows of the largest absolute and the largest relative error."""
        return {int(np.nanargmax(column)) for column in (self.abs_err, self.rel_err) if np.any(np.isfinite(column))}

    def print_rows(self, limit: int) -> set[int]:
        """Rows a printed report keeps: all up to ``limit``, else the first and last and the maxima."""
        n = len(self)
        return set(range(n)) if n <= limit else {0, n - 1} | self.maxima()

    def lines(self, limit: int, print_limit: int | None = None) -> list[StepLine]:
        """The table's lines: every row up to ``limit`` rows, else the first and last ``limit // 2``
        and the rows of the maxima, with a gap line where rows are left out; with
        ``print_limit``, the rows printed (:meth:`print_rows`) and the print's own gap lines."""
        n = len(self)
        if n <= limit:
            shown = list(range(n))
        else:
            half = max(limit // 2, 1)
            shown = sorted(set(range(half)) | set(range(n - half, n)) | self.maxima())
        if print_limit is None:  # one medium: its gaps are the only ones
            return [StepLine(None, i - last - 1) if row is None else StepLine(row)
                    for last, i, row in self._with_gaps(shown)]
        keep = self.print_rows(print_limit)
        out: list[StepLine] = []
        last, last_printed = -1, -1
        for i in shown:
            if i - last > 1:
                out.append(StepLine(None, i - last - 1, printed=False))
            if i in keep and i - last_printed > 1:
                out.append(StepLine(None, i - last_printed - 1, screen=False))
            if i in keep:
                last_printed = i
            out.append(StepLine(self._row(i), printed=i in keep))
            last = i
        return out

    def _with_gaps(self, shown: list[int]):
        """(previous index, index, None) before each jump in ``shown``, then (index, index, row)."""
        last = -1
        for i in shown:
            if i - last > 1:
                yield last, i, None
            yield i, i, self._row(i)
            last = i


@dataclass(frozen=True, eq=False)
class CaseView:
    """One case as the templates show it."""

    run: StoredRun
    anchor: str
    errors: list[QuantityErrors]
    inputs_text: str  # the input signals, for cases that differ by input
    summary_errors: list[QuantityErrors]  # the quantities the figures show (outputs, if any)

    @property
    def summary_names(self) -> list[str]:
        """The quantities of the summary table: those with errors, else those with an error estimate."""
        if self.summary_errors:
            return [e.name for e in self.summary_errors]
        shown = [n for n in (*self.run.outputs, *self.run.states) if n in self.run.estimate]
        return [n for n in shown if n in self.run.outputs] or shown

    def error(self, name: str):
        """The quantity's stored errors (QuantityErrors), or None."""
        return self.run.errors.get(name)

    def est_text(self, name: str) -> str:
        """Its global error estimate as the tables show it: '1.2e-05 (4.3 digits)', or '—'."""
        q = self.run.estimate.get(name)
        if q is None or q.max_abs is None:
            return "—"
        from odelab.report.render import sci

        digits = "" if q.digits is None else f" ({q.digits:.1f} digits)"
        return f"{sci(q.max_abs)}{digits}"

    @property
    def notes(self) -> list[str]:
        """The run's warnings, less the undefined-relative-error counts its error table already shows."""
        return [w for w in self.run.warnings if not w.startswith("relative error undefined")]

    def __getattr__(self, name: str) -> Any:  # the stored fields: case, method, status, nsteps...
        return getattr(self.run, name)


@dataclass(frozen=True)
class LabNote:
    """An experiment file's [report] note, with the stored errors it quotes (``quote``).

    Exercise 1's note says that the lab sheet's 6.907e-4 is ode23 on [0, 2 pi], quoting the
    stored maximum relative errors of exercise1/ode23 and exercise1_2pi/ode23: the numbers come
    from the runs, the words from the file, nothing from the experiment's name.
    """

    parts: list[tuple[bool, str]]  # the note's text, (bold, text) pieces: **bold** in the file
    lead: str  # "From the stored runs, the maximum relative error of ode23 is" (empty: nothing quoted)
    entries: list[dict]  # {"experiment", "case", "label", "quantity", "interval", "max_rel", "points", "anchor"}
    missing: list[str]  # quoted experiments with no usable run of the quoted case
    missing_case: str = ""  # the case they lack, when they all lack the same one


@dataclass(frozen=True)
class MatrixView:
    name: str
    columns: list[str]
    rows: list[tuple[str, list[float]]]


@dataclass(eq=False)
class LinearisationView:
    """``extra["linearization"]`` of one case, checked and laid out for tables."""

    case: str
    threshold: float
    quantity: str
    operating_point: list[tuple[str, str, float]]  # (kind: state/input/output, name, value)
    residual: float | None
    matrices: list[MatrixView]
    amplitudes: list[float]
    error_names: list[str]
    error_rows: list[tuple[float, list[float | None], bool | None]]  # amplitude, errors, within threshold
    max_amplitude_within: float | None
    comparisons: list[dict]
    threshold_amplitude: float | None = None  # where the error crosses the threshold (interpolated)
    slope: float | None = None  # of log(error) against log(amplitude): 1 if the nonlinearity is locally
    # quadratic at the operating point, 2 if cubic (the hardening spring about x = 0)
    settings: list[tuple[str, str]] = field(default_factory=list)  # (what, value): start, drive, step time
    failed_amplitudes: list[float] = field(default_factory=list)
    figures: list = field(default_factory=list)  # FigureSpec, replaced by drawn figures when rendering


@dataclass(eq=False)
class Section:
    """Everything one experiment's section shows."""

    name: str
    anchor: str
    title: str
    description: str
    source: str
    file_hashes: list[str]
    created: list[str]
    versions: list[str]
    notes: list[str]
    reference_text: str
    cases: list[CaseView]
    solution_figure: Any = None  # a FigureSpec, replaced by the drawn figure when rendering
    error_figure: Any = None
    solution_parts: list = field(default_factory=list)  # the solution figure's continuations (figures.split_grid)
    error_parts: list = field(default_factory=list)  # the error figure's
    step_tables: list[StepTable] = field(default_factory=list)
    linearisations: list[LinearisationView] = field(default_factory=list)
    event_tables: list = field(default_factory=list)  # report.events.EventTable per case with events
    settings: list[tuple[str, str]] = field(default_factory=list)  # (case, resolved TOML)
    lab_note: LabNote | None = None
    solver_text: str = ""  # "ode23, ode45 (rtol 0.001, atol 1e-06); rk4 (h 0.05)": what a grader checks
    stiffness: Any = None  # a StiffnessView when stiff and non-stiff methods meet (report/stiffness.py)
    layout: str = ""  # "by-quantity", "by-setup" or "states": how the figures are laid out
    control: Any = None  # report.control.ControlView: the diagram and [analysis] parts, if any
    fit: Any = None  # report.fit.FitView: the model over [data], the [fit] estimates and residuals, if any

    @property
    def summary_rows(self) -> int:
        """Rows of the section in the summary table: one per quantity shown (at least one per case)."""
        return sum(max(len(c.summary_names), 1) for c in self.cases)


# --- helpers ----------------------------------------------------------------------------------


_ANCHOR = re.compile(r"[^A-Za-z0-9_-]+")


def anchor_for(name: str, taken: set[str]) -> str:
    """An id/file stem made of safe characters, unique within ``taken`` (which it updates)."""
    base = _ANCHOR.sub("-", name).strip("-")[:60] or "x"
    out, i = base, 2
    while out in taken:
        out, i = f"{base}-{i}", i + 1
    taken.add(out)
    return out


def format_bound(value: Any) -> str:
    """A time bound as the lab writes it: 0, pi, 2 pi, pi/2; otherwise a plain number."""
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return str(value)
    if value == 0:
        return "0"
    for den in (1, 2, 4):
        k = value * den / math.pi
        if abs(k - round(k)) < 1e-9 and round(k) != 0:
            num = int(round(k))
            sign = "-" if num < 0 else ""
            num = abs(num)
            head = "pi" if num == 1 else f"{num} pi"
            return sign + (head if den == 1 else f"{head}/{den}")
    return f"{value:g}"


def _interval(run: StoredRun) -> str:
    time = run.config.get("time") if isinstance(run.config.get("time"), dict) else {}
    start, stop = time.get("start"), time.get("stop")
    if start is None or stop is None:
        t = run.t
        start, stop = (float(t[0]), float(t[-1])) if t.size else (0.0, 0.0)
    return f"[{format_bound(start)}, {format_bound(stop)}]"


def _toml(config: dict) -> str:
    try:
        return toml_text(config)
    except (TypeError, ValueError):  # a hand-edited record: show it as JSON instead
        return json.dumps(config, indent=2, default=str)


# --- linearisation ------------------------------------------------------------------------------


def _solver_text(runs: list[StoredRun]) -> str:
    """The methods and their options, grouped: 'ode23, ode45 (rtol 0.001, atol 1e-06); rk4 (h 0.05)'."""
    groups: dict[str, list[str]] = {}
    for r in runs:
        solver = r.config.get("solver") if isinstance(r.config.get("solver"), dict) else {}
        options = ", ".join(f"{k} {_value_text(v)}" for k, v in solver.items() if k != "method" and v is not None)
        methods = groups.setdefault(options, [])
        if r.method not in methods:
            methods.append(r.method)
    return "; ".join(", ".join(m) + (f" ({o})" if o else "") for o, m in groups.items())


def _value_text(value: Any) -> str:
    if isinstance(value, list):
        return "[" + " ".join(_value_text(v) for v in value) + "]"
    return f"{value:g}" if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value)


def _settings(runs: list[StoredRun]) -> list[tuple[str, str]]:
    """The first case's resolved settings in full, then for each other case only what differs."""
    out = []
    base = runs[0].config if runs else {}
    for i, r in enumerate(runs):
        if i == 0:
            out.append((r.case, _toml(r.config)))
            continue
        out.append((r.case, settings_diff(base, r.config)))
    return out


def _float_list(value: Any, what: str) -> list[float]:
    if not isinstance(value, list):
        raise ValueError(f"{what} must be a list of numbers")
    out = []
    for v in value:
        if v is None:
            out.append(math.nan)
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(float(v))
        else:
            raise ValueError(f"{what} must be a list of numbers; got {v!r}")
    return out


def _optional_number(value: Any) -> float | None:
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def _matrix(value: Any, name: str, rows: list[str], cols: list[str]) -> MatrixView:
    if value is None:
        value = []
    if not isinstance(value, list) or not all(isinstance(r, list) for r in value):
        raise ValueError(f"`{name}` must be a list of rows")
    data = [_float_list(r, f"`{name}` row {i + 1}") for i, r in enumerate(value)]
    width = {len(r) for r in data}
    if len(width) > 1:
        raise ValueError(f"`{name}` has rows of different lengths")
    ncols = width.pop() if width else 0
    col_names = cols if len(cols) == ncols else [f"{i + 1}" for i in range(ncols)]
    row_names = rows if len(rows) == len(data) else [f"{i + 1}" for i in range(len(data))]
    return MatrixView(name, col_names, list(zip(row_names, data)))


def linearisation_view(case: str, lin: dict[str, Any]) -> LinearisationView:
    """Check ``extra["linearization"]`` and lay it out; raises ValueError naming what is malformed."""
    if not isinstance(lin, dict):
        raise ValueError("`linearization` must be a table")
    states = [str(s) for s in lin.get("states") or []]
    inputs = [str(s) for s in lin.get("inputs") or []]
    outputs = [str(s) for s in lin.get("outputs") or []]
    op = lin.get("operating_point") or {}
    if not isinstance(op, dict):
        raise ValueError("`operating_point` must be a table")
    point = []
    for kind, key in (("state", "x"), ("input", "u"), ("output", "y")):
        values = op.get(key) or {}
        if not isinstance(values, dict):
            raise ValueError(f"`operating_point.{key}` must be a table of name = value")
        for name, v in values.items():
            point.append((kind, str(name), float(v)))
    residual = op.get("residual")
    residual = float(residual) if isinstance(residual, (int, float)) and not isinstance(residual, bool) else None
    matrices = [
        _matrix(lin.get("A"), "A", states, states),
        _matrix(lin.get("B"), "B", states, inputs),
        _matrix(lin.get("C"), "C", outputs, states),
        _matrix(lin.get("D"), "D", outputs, inputs),
    ]
    threshold = lin.get("threshold", 0.05)
    if not isinstance(threshold, (int, float)) or isinstance(threshold, bool):
        raise ValueError("`threshold` must be a number")
    amplitudes = _float_list(lin.get("amplitudes") or [], "`amplitudes`")
    errors = lin.get("errors") or {}
    if not isinstance(errors, dict):
        raise ValueError("`errors` must be a table of quantity = [error per amplitude]")
    quantity = lin.get("quantity")
    quantity = str(quantity) if quantity is not None else (next(iter(errors), "") if errors else "")
    names = list(errors)
    if quantity in names:  # the study's quantity first
        names.remove(quantity)
        names.insert(0, quantity)
    columns = {}
    for name in names:
        values = _float_list(errors[name], f"`errors.{name}`")
        if len(values) != len(amplitudes):
            raise ValueError(f"`errors.{name}` has {len(values)} values for {len(amplitudes)} amplitudes")
        columns[name] = values
    rows = []
    for i, a in enumerate(amplitudes):
        errs = [None if math.isnan(columns[n][i]) else columns[n][i] for n in names]
        lead = columns[quantity][i] if quantity in columns else math.nan
        rows.append((a, errs, None if math.isnan(lead) else bool(lead <= threshold)))
    within = _optional_number(lin.get("max_amplitude_within"))
    settings = [(label, str(lin[key])) for key, label in (("start", "start"), ("drive", "input stepped"),
                                                          ("step_time", "step time (s)")) if lin.get(key) is not None]
    failed = []
    comparisons = []
    for i, comp in enumerate(lin.get("comparisons") or []):
        if not isinstance(comp, dict):
            raise ValueError(f"`comparisons[{i}]` must be a table")
        t = np.array(_float_list(comp.get("t") or [], f"`comparisons[{i}].t`"))
        nonlinear, linear = comp.get("nonlinear") or {}, comp.get("linear") or {}
        if not isinstance(nonlinear, dict) or not isinstance(linear, dict):
            raise ValueError(f"`comparisons[{i}]` needs tables `nonlinear` and `linear`")
        common = [n for n in nonlinear if n in linear]
        shown = [quantity] if quantity in common else common
        series = {}
        for side, data in (("nonlinear", nonlinear), ("linear", linear)):
            series[side] = {}
            for n in shown:
                values = np.array(_float_list(data[n], f"`comparisons[{i}].{side}.{n}`"))
                if values.size != t.size:
                    raise ValueError(f"`comparisons[{i}].{side}.{n}` has {values.size} values for {t.size} times")
                series[side][n] = values
        amplitude = comp.get("amplitude")
        if not isinstance(amplitude, (int, float)) or isinstance(amplitude, bool):
            raise ValueError(f"`comparisons[{i}].amplitude` must be a number")
        err = None
        if quantity in columns and float(amplitude) in amplitudes:
            value = columns[quantity][amplitudes.index(float(amplitude))]
            err = None if math.isnan(value) else value
        status = comp.get("status", "success")
        if status != "success":
            failed.append(float(amplitude))
        if shown:
            comparisons.append({"amplitude": float(amplitude), "t": t, "names": shown, "error": err,
                                "status": str(status), **series})
    return LinearisationView(case=case, threshold=float(threshold), quantity=quantity, operating_point=point,
                             residual=residual, matrices=[m for m in matrices if m.rows or m.columns],
                             amplitudes=amplitudes, error_names=names, error_rows=rows,
                             max_amplitude_within=within, comparisons=comparisons,
                             threshold_amplitude=_optional_number(lin.get("threshold_amplitude")),
                             slope=_optional_number(lin.get("slope")), settings=settings, failed_amplitudes=failed)


# --- sections -------------------------------------------------------------------------------


def _note_parts(text: str) -> list[tuple[bool, str]]:
    """A note's text as (bold, text) pieces: ``**...**`` marks bold, as in Markdown; nothing else is markup."""
    pieces = text.split("**")
    if len(pieces) % 2 == 0:  # an unmatched ** is literal
        pieces[-2:] = [pieces[-2] + "**" + pieces[-1]]
    return [(i % 2 == 1, p) for i, p in enumerate(pieces) if p]


def _lab_note(group: ExperimentRuns, groups: dict[str, ExperimentRuns], anchors: dict[str, str]) -> LabNote | None:
    """The note of ``group``'s [report] table, quoting the maximum relative errors of the stored runs it names."""
    spec = group.report
    note = spec.get("note")
    if not isinstance(note, str) or not note.strip():
        return None
    entries, missing = [], []
    for quoted in spec.get("quote") or []:
        name, _, case = str(quoted).partition("/")
        other = groups.get(name)
        run = next((r for r in (other.runs if other else []) if r.case == case and r.ok and r.errors), None)
        err = run.errors[next(iter(run.errors))] if run is not None else None
        if err is None or err.max_rel is None:
            missing.append((name, case))
            continue
        entries.append({"experiment": name, "case": case, "method": run.method, "quantity": next(iter(run.errors)),
                        "interval": _interval(run), "max_rel": err.max_rel, "points": run.points,
                        "anchor": anchors[name]})
    methods = sorted({e["method"] for e in entries})
    lead = ""
    if len(methods) == 1:
        lead = f"From the stored runs, the maximum relative error of {methods[0]} is"
    elif methods:
        lead = "From the stored runs, the maximum relative errors are"
    for e in entries:  # named one by one where they are not all the same method
        e["label"] = "" if len(methods) == 1 else f"{e['experiment']}/{e['case']} ({e['method']}): "
    cases = {c for _, c in missing}
    return LabNote(_note_parts(note), lead, entries, [n for n, _ in missing] if len(cases) == 1 else
                   [f"{n}/{c}" for n, c in missing], cases.pop() if len(cases) == 1 else "")


#: An experiment with more stored cases than this (a large sweep) is summarised: counts and the
#: range of its errors over every case, then its first cases in the figures and tables (a report
#: of 5,000 cases drew 5,000 panels: 124 s and 7 MB of HTML). Every case is in sweep.csv.
MAX_SHOWN_CASES = 12


def _large_summary(group: ExperimentRuns) -> str:
    """One paragraph over every stored case of a large experiment: statuses, error ranges, where the rest is."""
    runs = group.runs
    failed = [r for r in runs if not r.ok]
    parts = [f"This experiment has {len(runs):,} stored cases: {len(runs) - len(failed):,} succeeded, "
             f"{len(failed):,} failed" + (f" (first: {', '.join(r.case for r in failed[:3])})" if failed else "") + "."]
    names = sorted({n for r in runs for n in r.errors})
    for name in names[:6]:
        values = [(r.errors[name].headline, r.case) for r in runs if name in r.errors
                  and r.errors[name].headline is not None]
        if not values:
            continue
        values.sort()
        median = values[len(values) // 2][0]
        parts.append(f"The relative error of {name} ranges from {values[0][0]:.3e} ({values[0][1]}) to "
                     f"{values[-1][0]:.3e} ({values[-1][1]}), median {median:.3e}, over {len(values):,} cases.")
    steps = [r.nsteps for r in runs if r.nsteps is not None]
    if steps:
        parts.append(f"Steps per case: {min(steps):,} to {max(steps):,}.")
    folder = runs[0].folder.parent if str(runs[0].folder) not in ("", ".") else None
    if folder is not None and (folder / "sweep.csv").is_file():
        where = f"sweep.csv in {folder} (one row per case)"
    else:
        where = f"the results folder {folder} (one folder per case)" if folder is not None else "the results folder"
    parts.append(f"The figures and tables below show the first {MAX_SHOWN_CASES} cases; every case is in {where}.")
    return " ".join(parts)


def build_sections(groups: list[ExperimentRuns]) -> tuple[list[Section], list[str]]:
    """The report's sections, one per experiment in the given order, and any warnings."""
    warnings: list[str] = []
    taken: set[str] = {"summary", "header", "problems", "contents", "failed", "provenance", "settings"}
    anchors = {g.name: anchor_for(g.name, taken) for g in groups}
    by_name = {g.name: g for g in groups}
    every = list(groups)
    sections = []
    for group in every:
        runs = group.runs
        anchor = anchors[group.name]
        summary = None
        if len(runs) > MAX_SHOWN_CASES:  # a large sweep: summarised, its first cases shown
            summary = _large_summary(group)
            runs = runs[:MAX_SHOWN_CASES]
        shown, referenced = plot_quantities(runs)
        units = units_of(runs[0])
        groups = setups(runs)
        if len(runs) == 1 and len(shown) > 1:
            layout = "states"
        elif len(groups) > 1:
            layout = "by-setup"
        else:
            layout = "by-quantity"
        cases = []
        for r in runs:
            order = [n for n in (*r.states, *r.outputs) if n in r.errors] + [n for n in r.errors
                                                                             if n not in (*r.states, *r.outputs)]
            errors = [r.errors[n] for n in order]
            cases.append(CaseView(run=r, anchor=anchor_for(f"{anchor}-{r.case}", taken), errors=errors,
                                  inputs_text=inputs_text(r),
                                  summary_errors=[e for e in errors if e.name in shown] or errors))
        kinds = sorted({r.reference for r in runs if r.errors})
        section = Section(
            name=group.name, anchor=anchor, title=group.title, description=group.description, source=group.source,
            file_hashes=group.file_hashes, created=sorted({r.created for r in runs if r.created}),
            versions=sorted({", ".join(f"{k} {v}" for k, v in r.versions.items()) for r in runs if r.versions}),
            notes=list(group.notes) + ([summary] if summary else []),
            reference_text="; ".join(REFERENCE_TEXT.get(k, k) for k in kinds),
            cases=cases, layout=layout)
        section.solution_figure = solution_figure(anchor, groups, shown, layout, units)
        if not all(r.reference == "linearization" for r in runs):  # else the amplitude study shows the error
            section.error_figure = error_figure(anchor, groups, referenced, layout, units)
        if layout == "by-quantity":
            pair = (stacked(section.solution_figure, section.error_figure, above=len(shown)) if runs[0].inputs
                    else side_by_side(section.solution_figure, section.error_figure))
            if pair is not None:
                section.solution_figure, section.error_figure = pair, None
        elif layout == "states":
            merged = stacked(section.solution_figure, section.error_figure)
            if merged is not None:
                section.solution_figure, section.error_figure = merged, None
        elif layout == "by-setup":
            merged = with_error_row(section.solution_figure, section.error_figure)
            if merged is not None:
                section.solution_figure, section.error_figure = merged, None
        from odelab.report.axes import apply_plot_settings

        section.solution_figure = apply_plot_settings(section.solution_figure, runs)
        section.error_figure = apply_plot_settings(section.error_figure, runs, scaled=False)
        for which in ("solution", "error"):  # at most MAX_GRID x MAX_GRID panels a printed figure
            parts = split_grid(getattr(section, f"{which}_figure"))
            setattr(section, f"{which}_figure", parts[0] if parts else None)
            setattr(section, f"{which}_parts", parts[1:])
        for r in runs:
            for name in referenced:
                cols = [r.column(c) for c in (name, f"{name}_ref", f"{name}_abs_err", f"{name}_rel_err")]
                if all(c is not None for c in cols) and r.t.size:
                    section.step_tables.append(StepTable(r.case, r.method, name, r.t, *cols))
        section.event_tables = [t for t in (event_table(r) for r in runs) if t is not None]
        section.settings = _settings(runs)
        section.solver_text = _solver_text(runs)
        from odelab.report.stiffness import stiffness_view

        section.stiffness = stiffness_view(anchor, runs, units)
        if section.stiffness is not None:
            section.stiffness.figure = apply_plot_settings(section.stiffness.figure, runs, scaled=False)
        for r in runs:
            lin = r.extra.get("linearization")
            if lin is None:
                continue
            try:
                view = linearisation_view(r.case, lin)
            except (ValueError, TypeError, KeyError) as exc:
                text = f"{group.name}/{r.case}: the linearisation study cannot be shown: {exc}"
                warnings.append(text)
                section.notes.append(text)
                continue
            stem = anchor if len(runs) == 1 else f"{anchor}-{anchor_for(r.case, set())}"
            view.figures = [part for spec in linearisation_figures(stem, view, units) for part in split_grid(spec)]
            section.linearisations.append(view)
        from odelab.report.control import control_view

        section.control = control_view(anchor, runs, every)
        from odelab.report.fit import fit_view

        section.fit = fit_view(anchor, runs, units)
        section.lab_note = _lab_note(group, by_name, anchors)
        sections.append(section)
    return sections, warnings
