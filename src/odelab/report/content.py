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
from odelab.report.plots import (
    REFERENCE_COLOR,
    SERIES_COLORS,
    FigureSpec,
    Line,
    Panel,
    RefLine,
    method_color,
)

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

TIME_LABEL = "t (s)"
REL_LABEL = "relative error |f - y| / |f|"
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
_LINESTYLES = ("-", "-.", ":", "--")
LINEARISED_COLOR = "#AA4499"  # a series colour, never a method's
# Keys of a resolved configuration that only say how a case is solved or named.
_SOLVER_ONLY_KEYS = ("solver", "case", "title", "description")

AGAINST = {
    "exact": "the exact solution (black)",
    "lti": "the exact LTI response (black)",
    "high-accuracy": "a high-accuracy reference (black)",
    "linearization": "the linearised model (black)",
    "none": "each other",
}
MARKERS_NOTE = "Markers are the solver's output points (left out where a line has too many to tell apart)."

REFERENCE_TEXT = {
    "exact": "the exact solution given in the experiment file",
    "lti": "the exact response of the linear system (matrix exponential)",
    "high-accuracy": "a high-accuracy solve",
    "linearization": "the linearised model (the error is the linearisation error)",
    "none": "no reference",
}


# --- small views ------------------------------------------------------------------------------


@dataclass(frozen=True)
class CappedRows:
    """A long table cut in the middle: the first and last rows, and how many were left out."""

    head: list[tuple]
    omitted: int
    tail: list[tuple]


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

    def capped(self, limit: int) -> CappedRows:
        """All rows if there are at most ``limit``, else the first and last ``limit // 2``."""
        n = len(self)
        if n <= limit:
            return CappedRows([self._row(i) for i in range(n)], 0, [])
        half = max(limit // 2, 1)
        return CappedRows([self._row(i) for i in range(half)], n - 2 * half,
                          [self._row(i) for i in range(n - half, n)])


@dataclass(frozen=True, eq=False)
class CaseView:
    """One case as the templates show it."""

    run: StoredRun
    anchor: str
    errors: list[QuantityErrors]
    inputs_text: str  # the input signals, for cases that differ by input
    summary_errors: list[QuantityErrors]  # the quantities the figures show (outputs, if any)

    def __getattr__(self, name: str) -> Any:  # the stored fields: case, method, status, nsteps...
        return getattr(self.run, name)


@dataclass(frozen=True)
class LabNote:
    """The lab sheet's 6.907e-4, computed from the stored Exercise 1 runs."""

    entries: list[dict]  # {"experiment", "interval", "max_rel", "points", "anchor"}
    missing: list[str]  # experiments of the pair with no usable ode23 run


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
    step_tables: list[StepTable] = field(default_factory=list)
    linearisations: list[LinearisationView] = field(default_factory=list)
    settings: list[tuple[str, str]] = field(default_factory=list)  # (case, resolved TOML)
    lab_note: LabNote | None = None
    layout: str = ""  # "by-quantity", "by-setup" or "states": how the figures are laid out

    @property
    def summary_rows(self) -> int:
        """Rows of the section in the summary table: one per quantity shown (at least one per case)."""
        return sum(max(len(c.summary_errors), 1) for c in self.cases)


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


def _g(value: Any) -> str:
    return f"{value:g}" if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value)


def describe_signal(name: str, spec: Any) -> str:
    """An input signal as a formula where it has one: ``f = sin(0.2 t)``, ``f steps 0 → 1 at t = 0``."""
    if not isinstance(spec, dict):
        return f"{name} = {spec}"
    kind = spec.get("type")
    v = {k: x for k, x in spec.items() if x is not None}
    try:
        if kind == "step":
            return f"{name} steps {_g(v.get('initial', 0))} → {_g(v.get('final', 1))} at t = {_g(v.get('time', 0))}"
        if kind == "sine":
            a, w, phi, bias = (v.get("amplitude", 1), v.get("frequency", 1), v.get("phase", 0), v.get("bias", 0))
            arg = f"{_g(w)} t" if w != 1 else "t"
            arg += f" + {_g(phi)}" if phi else ""
            term = ("" if a == 1 else "-" if a == -1 else f"{_g(a)} ") + f"sin({arg})"
            return f"{name} = " + (f"{_g(bias)} + {term}" if bias else term)
        if kind == "ramp":
            slope, start, initial = v.get("slope", 1), v.get("start", 0), v.get("initial", 0)
            var = "t" if not start else f"(t - {_g(start)})"
            term = var if slope == 1 else f"{_g(slope)} {var}"
            text = f"{_g(initial)} + {term}" if initial else term
            return f"{name} = {text}" + (f" for t >= {_g(start)}" if start else "")
        if kind == "constant":
            return f"{name} = {_g(v.get('value'))}"
        if kind == "expression":
            return f"{name} = {v.get('expression')}"
        if kind == "table":
            return f"{name}: table {v.get('file')}"
    except TypeError:  # a hand-edited record with odd values: fall through to the plain listing
        pass
    args = ", ".join(f"{k} {_g(x)}" for k, x in v.items() if k != "type")
    return f"{name}: {kind or 'signal'}" + (f" ({args})" if args else "")


def _inputs_text(run: StoredRun) -> str:
    inputs = run.config.get("inputs")
    if not isinstance(inputs, dict) or not inputs:
        return ""
    return "; ".join(describe_signal(name, spec) for name, spec in inputs.items())


def _toml(config: dict) -> str:
    import tomli_w

    def clean(value):
        if isinstance(value, dict):
            return {str(k): clean(v) for k, v in value.items() if v is not None}
        if isinstance(value, list):
            return [clean(v) for v in value if v is not None]
        return value

    try:
        return tomli_w.dumps(clean(config))
    except (TypeError, ValueError):  # a hand-edited record: show it as JSON instead
        return json.dumps(config, indent=2, default=str)


def _reference_label(kind: str) -> str:
    return {"exact": "exact", "lti": "exact (LTI)", "high-accuracy": "reference (high-accuracy)",
            "linearization": "linearised model"}.get(kind, "reference")


def _plot_quantities(runs: list[StoredRun]) -> tuple[list[str], list[str]]:
    """Quantities to draw, and those of them with a reference (outputs first, as the lab shows y)."""
    states = list(dict.fromkeys(n for r in runs for n in r.states))
    outputs = list(dict.fromkeys(n for r in runs for n in r.outputs))
    referenced = [n for n in states + outputs if any(r.has_reference(n) for r in runs)]
    if outputs:
        shown = [n for n in outputs if n in referenced] or outputs
    else:
        shown = states or [n for n in referenced]
    return shown, [n for n in shown if n in referenced]


@dataclass(frozen=True, eq=False)
class SetUp:
    """Cases that differ only in how they are solved: they share one reference and one panel."""

    label: str
    runs: list[StoredRun]
    colors: dict[str, str]  # case -> colour
    prefix: str = ""  # what the members' names share, left out of their legend labels


def _setup_key(run: StoredRun) -> str:
    rest = {k: v for k, v in run.config.items() if k not in _SOLVER_ONLY_KEYS}
    return json.dumps(rest, sort_keys=True, default=str)


_NAME_PARTS = re.compile(r"[-_ .:/]+")


def _common_prefix(names: list[str]) -> str:
    """The words the names start with: "sine" for sine-ode45 and sine-ode23."""
    split = [_NAME_PARTS.split(n) for n in names]
    words = []
    for parts in zip(*split):
        if len(set(parts)) != 1:
            break
        words.append(parts[0])
    if not words:
        return ""
    # the prefix as written in the first name (with its own separators)
    match = re.match(r"^" + r"[-_ .:/]+".join(re.escape(w) for w in words), names[0])
    return match.group(0) if match else ""


def _colors(runs: list[StoredRun]) -> dict[str, str]:
    """A colour per case: its method's colour when methods tell the cases apart, else a series colour."""
    methods = [r.method for r in runs]
    if len(set(methods)) == len(methods):
        return {r.case: method_color(r.method) for r in runs}
    return {r.case: SERIES_COLORS[i % len(SERIES_COLORS)] for i, r in enumerate(runs)}


def setups(runs: list[StoredRun]) -> list[SetUp]:
    """The experiment's cases grouped by everything but their solver, in case order."""
    groups: dict[str, list[StoredRun]] = {}
    for r in runs:
        groups.setdefault(_setup_key(r), []).append(r)
    out = []
    for members in groups.values():
        prefix = _common_prefix([r.case for r in members]) if len(members) > 1 else ""
        name = prefix or (members[0].case if len(members) == 1 else "")
        inputs = _inputs_text(members[0])
        if len(groups) == 1:
            label = ""
        elif name and inputs:
            label = f"{name}: {inputs}"
        else:
            label = name or inputs or members[0].case
        out.append(SetUp(label, members, _colors(members), prefix))
    return out


def _what_differs(groups: list[SetUp]) -> str:
    keys = set()
    first = groups[0].runs[0].config
    for g in groups[1:]:
        other = g.runs[0].config
        keys |= {k for k in set(first) | set(other)
                 if k not in _SOLVER_ONLY_KEYS and json.dumps(first.get(k), sort_keys=True, default=str)
                 != json.dumps(other.get(k), sort_keys=True, default=str)}
    return "input" if keys == {"inputs"} else "parameter set" if keys == {"parameters"} else "set-up"


def _case_label(run: StoredRun, prefix: str = "") -> str:
    """``ode23`` for a case named after its method, else ``step (ode45)``; without a shared ``prefix``."""
    name = run.case
    rest = name[len(prefix):].lstrip("-_ .:/") if prefix and name.startswith(prefix) else ""
    if rest:
        name = rest
    return run.method if name == run.method else f"{name} ({run.method})"


def _stats_text(run: StoredRun) -> str:
    def n(v):
        return "n/a" if v is None else str(v)

    return f"{n(run.nsteps)} successful steps, {n(run.nfailed)} failed attempts, {n(run.nfevals)} function evaluations"


def _reference_union(runs: list[StoredRun], name: str) -> tuple[np.ndarray, np.ndarray]:
    """The reference of ``name`` through every case's output times (the cases share it)."""
    ts, fs = [], []
    for r in runs:
        ref = r.column(f"{name}_ref")
        if ref is not None:
            ts.append(r.t)
            fs.append(ref)
    if not ts:
        return np.array([]), np.array([])
    t = np.concatenate(ts)
    f = np.concatenate(fs)
    order = np.argsort(t, kind="stable")
    t, f = t[order], f[order]
    keep = np.concatenate([[True], np.diff(t) > 0]) if t.size else np.array([], dtype=bool)
    return t[keep], f[keep]


# --- figures ----------------------------------------------------------------------------------


def _solver_lines(group: SetUp, name: str, ref_label: str) -> list[Line]:
    """The reference (black, through every member's output times) and each member's solution."""
    members, colors = group.runs, group.colors
    lines = []
    t_ref, f_ref = _reference_union(members, name)
    if t_ref.size:
        lines.append(Line(t_ref, f_ref, ref_label, REFERENCE_COLOR, linewidth=1.0, zorder=1))
    for i, r in enumerate(members):
        y = r.column(name)
        if y is not None and r.t.size:
            lines.append(Line(r.t, y, f"{_case_label(r, group.prefix)}, {r.t.size} points", colors[r.case],
                              marker=_MARKERS[i % len(_MARKERS)], linewidth=1.0, markersize=3.5, zorder=2 + i))
    return lines


def _solution_figure(stem: str, groups: list[SetUp], shown: list[str], layout: str) -> FigureSpec | None:
    runs = [r for g in groups for r in g.runs if r.t.size]
    if not runs or not shown:
        return None
    kind = runs[0].reference
    ref_label = _reference_label(kind)
    against = AGAINST.get(kind, "the reference")
    panels = []
    if layout == "states":
        r = runs[0]
        lines = []
        for j, name in enumerate(shown):
            y, ref = r.column(name), r.column(f"{name}_ref")
            if y is None:
                continue
            if ref is not None:
                lines.append(Line(r.t, ref, ref_label if j == 0 else "_nolegend_", REFERENCE_COLOR, linewidth=0.9,
                                  zorder=1))
            lines.append(Line(r.t, y, f"{name} ({r.method})", SERIES_COLORS[j % len(SERIES_COLORS)],
                              linestyle=_LINESTYLES[j % len(_LINESTYLES)], marker=_MARKERS[j % len(_MARKERS)],
                              linewidth=1.2, markersize=3.5, zorder=2 + j))
        stats = f"{r.nsteps} steps, {r.nfailed if r.nfailed is not None else 'n/a'} failed, {r.nfevals} fevals"
        panels.append(Panel(f"{_case_label(r)}: {stats}", TIME_LABEL, "value", tuple(lines), legend_outside=True))
        caption = ("Every state against t, as MATLAB's documentation plots the rigid body: markers at the output "
                   f"points, thin black lines the {ref_label}. {_case_label(r)}: {_stats_text(r)}.")
    else:
        for g in groups:
            for name in shown:
                title = (f"{g.label}: {name}" if len(shown) > 1 else g.label) if g.label else name
                panels.append(Panel(title, TIME_LABEL, name, tuple(_solver_lines(g, name, ref_label))))
        if layout == "by-quantity":
            caption = f"Solution against t, every case against {against}. {MARKERS_NOTE}"
        else:
            caption = (f"One panel per {_what_differs(groups)}; cases that differ only in their solver share a "
                       f"panel, every solver against {against}. {MARKERS_NOTE}")
    columns = 1 if len(panels) == 1 else 2
    return FigureSpec(f"{stem}-solution", caption, f"{stem}: solution against time", tuple(panels),
                      columns=columns, panel_height=3.0 if len(panels) == 1 else 2.6)


def _error_lines(group: SetUp, name: str) -> list[Line]:
    lines = []
    for i, r in enumerate(group.runs):
        rel = r.column(f"{name}_rel_err")
        if rel is not None and r.t.size:
            lines.append(Line(r.t, rel, _case_label(r, group.prefix), group.colors[r.case], linestyle=_LINESTYLES[i % len(_LINESTYLES)],
                              marker=_MARKERS[i % len(_MARKERS)], linewidth=1.1, markersize=3.5))
    return lines


def _error_figure(stem: str, groups: list[SetUp], names: list[str], layout: str) -> FigureSpec | None:
    runs = [r for g in groups for r in g.runs]
    panels = []
    note = "the relative error is zero or undefined at every point"
    per = "case"
    if layout == "states":
        # one solution, several quantities: one panel, coloured as the states in the solution figure
        r = runs[0]
        lines = []
        for j, name in enumerate(names):
            rel = r.column(f"{name}_rel_err")
            if rel is not None and r.t.size:
                lines.append(Line(r.t, rel, f"{name} ({r.method})", SERIES_COLORS[j % len(SERIES_COLORS)],
                                  linestyle=_LINESTYLES[j % len(_LINESTYLES)], marker=_MARKERS[j % len(_MARKERS)],
                                  linewidth=1.1, markersize=3.5))
        if lines:
            panels.append(Panel(f"relative error, {_case_label(r)}", TIME_LABEL, REL_LABEL, tuple(lines),
                                yscale="log", note=note, legend_outside=True))
        per = "quantity"
    else:
        for g in groups:
            for name in names:
                lines = _error_lines(g, name)
                if not lines:
                    continue
                title = f"relative error of {name}" + (f", {g.label}" if g.label else "")
                panels.append(Panel(title, TIME_LABEL, REL_LABEL, tuple(lines), yscale="log", note=note))
    if not panels:
        return None
    caption = (f"Relative error against t on a log scale, one line per {per}. Points where it is undefined "
               "(reference zero or tiny) or exactly zero (the initial point) are left out.")
    return FigureSpec(f"{stem}-relative-error", caption, f"{stem}: relative error against time", tuple(panels),
                      columns=1 if len(panels) == 1 else 2, panel_height=3.0 if len(panels) == 1 else 2.6)


def _linearisation_figures(stem: str, lin: LinearisationView) -> list[FigureSpec]:
    figures = []
    panels = []
    for comp in lin.comparisons:
        t = comp["t"]
        names = comp["names"]
        lines = []
        for j, name in enumerate(names):
            single = len(names) == 1
            nl_color = REFERENCE_COLOR if single else SERIES_COLORS[j % len(SERIES_COLORS)]
            lin_color = LINEARISED_COLOR if single else SERIES_COLORS[j % len(SERIES_COLORS)]
            suffix = "" if single else f" {name}"
            lines.append(Line(t, comp["nonlinear"][name], f"nonlinear{suffix}", nl_color, linewidth=1.4))
            lines.append(Line(t, comp["linear"][name], f"linearised{suffix}", lin_color, linestyle="--",
                              linewidth=1.4, zorder=3))
        err = comp.get("error")
        title = f"amplitude {comp['amplitude']:g}" + (f" (error {err:.2%})" if err is not None else "")
        if comp.get("status", "success") != "success":
            title += f", {comp['status']}"
        panels.append(Panel(title, TIME_LABEL, names[0] if len(names) == 1 else "value", tuple(lines)))
    if panels:
        cols = 3 if len(panels) >= 5 else 2 if len(panels) >= 2 else 1
        figures.append(FigureSpec(
            f"{stem}-linearised-responses",
            "Nonlinear model (solid) and linearised model (dashed) for each input amplitude.",
            f"{lin.case}: nonlinear and linearised responses, one panel per amplitude", tuple(panels),
            columns=cols, panel_height=2.3 if cols == 3 else 2.6))
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
        figures.append(FigureSpec(
            f"{stem}-linearisation-error",
            f"Relative error of the linearised model against the input amplitude (log-log), with the "
            f"threshold {lin.threshold:g}.{slope}",
            f"{lin.case}: linearisation error against amplitude", (
                Panel("error of the linearised model", "input amplitude", "relative error", tuple(lines),
                      xscale="log", yscale="log", reflines=tuple(refs),
                      note="no positive error to show on a log scale"),),
            columns=1, panel_height=3.0))
    return figures


# --- linearisation ------------------------------------------------------------------------------


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


def _lab_note(groups: dict[str, ExperimentRuns], anchors: dict[str, str]) -> LabNote | None:
    """Exercise 1's maximum relative error of ode23 on [0, pi] and on [0, 2 pi], from the runs."""
    pair = ("exercise1", "exercise1_2pi")
    if not any(name in groups for name in pair):
        return None
    entries, missing = [], []
    for name in pair:
        group = groups.get(name)
        runs = [r for r in (group.runs if group else []) if r.method == "ode23" and r.ok and r.errors]
        run = next((r for r in runs if r.case == "ode23"), runs[0] if runs else None)
        if run is None:
            missing.append(name)
            continue
        quantity = "y" if "y" in run.errors else next(iter(run.errors))
        err = run.errors[quantity]
        if err.max_rel is None:
            missing.append(name)
            continue
        entries.append({"experiment": name, "case": run.case, "quantity": quantity, "interval": _interval(run),
                        "max_rel": err.max_rel, "points": run.points, "anchor": anchors[name]})
    return LabNote(entries, missing)


def build_sections(groups: list[ExperimentRuns]) -> tuple[list[Section], list[str]]:
    """The report's sections, one per experiment in the given order, and any warnings."""
    warnings: list[str] = []
    taken: set[str] = {"summary", "header", "problems", "contents", "failed", "provenance", "settings"}
    anchors = {g.name: anchor_for(g.name, taken) for g in groups}
    by_name = {g.name: g for g in groups}
    lab_note = _lab_note(by_name, anchors)
    sections = []
    for group in groups:
        runs = group.runs
        anchor = anchors[group.name]
        shown, referenced = _plot_quantities(runs)
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
                                  inputs_text=_inputs_text(r),
                                  summary_errors=[e for e in errors if e.name in shown] or errors))
        kinds = sorted({r.reference for r in runs if r.errors})
        section = Section(
            name=group.name, anchor=anchor, title=group.title, description=group.description, source=group.source,
            file_hashes=group.file_hashes, created=sorted({r.created for r in runs if r.created}),
            versions=sorted({", ".join(f"{k} {v}" for k, v in r.versions.items()) for r in runs if r.versions}),
            notes=list(group.notes), reference_text="; ".join(REFERENCE_TEXT.get(k, k) for k in kinds),
            cases=cases, layout=layout)
        section.solution_figure = _solution_figure(anchor, groups, shown, layout)
        section.error_figure = _error_figure(anchor, groups, referenced, layout)
        for r in runs:
            for name in referenced:
                cols = [r.column(c) for c in (name, f"{name}_ref", f"{name}_abs_err", f"{name}_rel_err")]
                if all(c is not None for c in cols) and r.t.size:
                    section.step_tables.append(StepTable(r.case, r.method, name, r.t, *cols))
            section.settings.append((r.case, _toml(r.config)))
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
            view.figures = _linearisation_figures(stem, view)
            section.linearisations.append(view)
        if group.name in ("exercise1", "exercise1_2pi") and lab_note is not None and not any(
                s.lab_note for s in sections):
            section.lab_note = lab_note
        sections.append(section)
    return sections, warnings
