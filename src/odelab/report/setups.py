"""Set-ups: an experiment's cases grouped by everything but their solver, and how to name them.

Cases whose resolved configurations differ only in ``[solver]`` share a reference and a
panel (Exercise 2's step, sine and ramp inputs, each with ode45 and ode23); this module finds
those groups, labels them ("sine: f = sin(0.2 t)") and describes input signals as formulas.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.report.collect import StoredRun
from odelab.report.plots import SERIES_COLORS, LineStyle, method_style

__all__ = ["SetUp", "case_label", "describe_signal", "inputs_text", "plot_quantities", "reference_label",
           "reference_union", "setups", "stats_text", "units_of", "what_differs"]

# Keys of a resolved configuration that only say how a case is solved or named.
_SOLVER_ONLY_KEYS = ("solver", "case", "title", "description")


def units_of(run: StoredRun) -> dict[str, str]:
    """The experiment's [units] (name -> unit), with t in seconds unless it says otherwise."""
    units = run.config.get("units")
    out = {"t": "s"}
    if isinstance(units, dict):
        out.update({str(k): str(v) for k, v in units.items() if isinstance(v, str)})
    return out


def _g(value: Any) -> str:
    return f"{value:g}" if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value)


def describe_signal(name: str, spec: Any) -> str:
    """An input signal as a formula where it has one: ``f = sin(0.2 t)``, ``f steps 0 → 1 at t = 0``.

    The signal type describes itself (``describe`` of its class in the signal registry).
    """
    from odelab.signals import SIGNALS, plain_description

    if not isinstance(spec, dict):
        return f"{name} = {spec}"
    kind = spec.get("type")
    v = {k: x for k, x in spec.items() if x is not None}
    cls = SIGNALS.get(kind) if isinstance(kind, str) else None
    try:
        if cls is not None:
            return cls.describe(name, v)
    except TypeError:  # a hand-edited record with odd values: fall through to the plain listing
        pass
    return plain_description(name, kind if isinstance(kind, str) else None, v)


def inputs_text(run: StoredRun) -> str:
    inputs = run.config.get("inputs")
    if not isinstance(inputs, dict) or not inputs:
        return ""
    return "; ".join(describe_signal(name, spec) for name, spec in inputs.items())



def reference_label(kind: str) -> str:
    return {"exact": "exact", "lti": "exact (LTI)", "high-accuracy": "reference (high-accuracy)",
            "linearization": "linearised model"}.get(kind, "reference")


def plot_quantities(runs: list[StoredRun]) -> tuple[list[str], list[str]]:
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
    styles: dict = field(default_factory=dict)  # case -> LineStyle (colour, marker, dash together)


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


_SERIES_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<")
_SERIES_DASHES = ("-", "--", "-.", ":")


def _styles(runs: list[StoredRun]) -> dict[str, LineStyle]:
    """A style per case: its method's when methods tell the cases apart, else a series style."""
    methods = [r.method for r in runs]
    if len(set(methods)) == len(methods):
        return {r.case: method_style(r.method) for r in runs}
    return {r.case: LineStyle(SERIES_COLORS[i % len(SERIES_COLORS)], _SERIES_MARKERS[i % len(_SERIES_MARKERS)],
                              _SERIES_DASHES[i % len(_SERIES_DASHES)], 1.1) for i, r in enumerate(runs)}


def setups(runs: list[StoredRun]) -> list[SetUp]:
    """The experiment's cases grouped by everything but their solver, in case order."""
    groups: dict[str, list[StoredRun]] = {}
    for r in runs:
        groups.setdefault(_setup_key(r), []).append(r)
    out = []
    for members in groups.values():
        prefix = _common_prefix([r.case for r in members]) if len(members) > 1 else ""
        name = prefix or (members[0].case if len(members) == 1 else "")
        inputs = inputs_text(members[0])
        if len(groups) == 1:
            label = ""
        elif name and inputs:
            label = f"{name}: {inputs}"
        else:
            label = name or inputs or members[0].case
        styles = _styles(members)
        out.append(SetUp(label, members, {c: st.color for c, st in styles.items()}, prefix, styles))
    return out


def what_differs(groups: list[SetUp]) -> str:
    keys = set()
    first = groups[0].runs[0].config
    for g in groups[1:]:
        other = g.runs[0].config
        keys |= {k for k in set(first) | set(other)
                 if k not in _SOLVER_ONLY_KEYS and json.dumps(first.get(k), sort_keys=True, default=str)
                 != json.dumps(other.get(k), sort_keys=True, default=str)}
    return "input" if keys == {"inputs"} else "parameter set" if keys == {"parameters"} else "set-up"


def case_label(run: StoredRun, prefix: str = "") -> str:
    """``ode23`` for a case named after its method, else ``step (ode45)``; without a shared ``prefix``."""
    name = run.case
    rest = name[len(prefix):].lstrip("-_ .:/") if prefix and name.startswith(prefix) else ""
    if rest:
        name = rest
    return run.method if name == run.method else f"{name} ({run.method})"


def stats_text(run: StoredRun) -> str:
    def n(v):
        return "n/a" if v is None else str(v)

    return f"{n(run.nsteps)} successful steps, {n(run.nfailed)} failed attempts, {n(run.nfevals)} function evaluations"


def reference_union(runs: list[StoredRun], name: str) -> tuple[np.ndarray, np.ndarray]:
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
