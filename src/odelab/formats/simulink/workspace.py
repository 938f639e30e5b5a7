"""A model's workspace variables: its callbacks and the MATLAB scripts beside it, read, never run.

Simulink takes a block's ``m``, ``k`` and ``num`` from the MATLAB workspace, which a course fills
with a script next to the model (``params.m``) or with the model's own callbacks (``PreLoadFcn``,
``InitFcn``). This module reads the constant assignments of both (``m = 2;``, ``A = [0 1; -k/m
-b/m];``, ``p.g = 9.81;``) in order, each evaluated by :mod:`~odelab.formats.simulink.mexpr`
from the values before it. When :mod:`odelab.formats.matlab` offers ``workspace`` (the MATLAB
reader's evaluator of scripts' constant assignments) it is used instead; either way nothing is
executed. ``--set NAME=VALUE`` overrides a variable, and ``--workspace SCRIPT.m`` chooses the
scripts when several beside the model assign the same name differently.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from odelab.exceptions import OdelabError
from odelab.formats.base import IGNORED, Note
from odelab.formats.simulink.mexpr import MExprError, V, evaluate

__all__ = ["CALLBACKS", "MAX_SCRIPTS", "Assignment", "Workspace", "assignments", "read_workspace"]

CALLBACKS = ("PreLoadFcn", "PostLoadFcn", "InitFcn", "StartFcn")
"""The model callbacks whose assignments Simulink has run before a simulation starts, in that order."""
MAX_SCRIPTS = 50
"""At most 50 scripts beside a model are read (a course folder holds a handful)."""
MAX_SCRIPT_BYTES = 1_000_000


@dataclass(frozen=True)
class Assignment:
    name: str
    value: np.ndarray
    source: str  # "PreLoadFcn", "params.m"
    line: int
    text: str  # the right-hand side as written


@dataclass
class Workspace:
    """The variables by name (the last assignment of each source wins), and what could not be read."""

    values: dict[str, Assignment] = field(default_factory=dict)
    drivers: list[str] = field(default_factory=list)  # the scripts that call sim('model'): the only ones read
    span: tuple[str, str, str] | None = None  # (script, line, text): sim('model', [t0 tf]) of a driver script
    conflicts: dict[str, list[Assignment]] = field(default_factory=dict)  # several scripts, different values
    skipped: list[tuple[str, int, str, str]] = field(default_factory=list)  # (source, line, text, why)
    notes: list = field(default_factory=list)  # the MATLAB reader's notes about the scripts (what it did not read)


def _statements(text: str):
    """(line, statement) of a script: comments dropped, ``...`` continuations joined, split at ``;``, ``,`` and
    newlines outside brackets."""
    text = re.sub(r"\.\.\.[^\n]*\n", " ", text)
    out, current, depth, line, start = [], [], 0, 1, 1
    quote = False
    i = 0
    while i < len(text):
        ch = text[i]
        if ch == "'" and not quote and current and (current[-1].isalnum() or current[-1] in ")]}'_."):
            current.append(ch)  # a transpose
        elif ch == "'":
            quote = not quote
            current.append(ch)
        elif quote:
            current.append(ch)
            if ch == "\n":
                quote = False
        elif ch == "%":
            end = text.find("\n", i)
            i = len(text) if end < 0 else end
            continue
        elif ch in "([{":
            depth += 1
            current.append(ch)
        elif ch in ")]}":
            depth = max(0, depth - 1)
            current.append(ch)
        elif (ch in ";," and depth == 0) or (ch == "\n" and depth == 0):
            if "".join(current).strip():
                out.append((start, "".join(current).strip()))
            current = []
            start = line + (ch == "\n")
        else:
            current.append(" " if ch == "\n" else ch)
        if ch == "\n":
            line += 1
        i += 1
    if "".join(current).strip():
        out.append((start, "".join(current).strip()))
    return out


_ASSIGN = re.compile(r"^([A-Za-z][A-Za-z0-9_]*(?:\.[A-Za-z][A-Za-z0-9_]*)*)\s*=(?!=)\s*(.+)$", re.DOTALL)


def assignments(text: str, source: str, known: dict[str, Assignment] | None = None):
    """The constant assignments of a script or callback, in order: (assignments, skipped statements)."""
    values: dict[str, Assignment] = dict(known or {})
    found: list[Assignment] = []
    skipped = []
    for line, stmt in _statements(text):
        m = _ASSIGN.match(stmt)
        if not m:
            continue
        name, rhs = m.group(1), m.group(2).strip()
        missing: set[str] = set()

        def lookup(n):
            a = values.get(n)
            return None if a is None else V(a.value)

        try:
            v = evaluate(rhs, lookup, missing)
        except MExprError as exc:
            skipped.append((source, line, stmt, str(exc)))
            continue
        if missing:
            skipped.append((source, line, stmt, f"it uses {', '.join(sorted(missing))}, which nothing before it sets"))
            continue
        a = Assignment(name, v.num, source, line, rhs)
        values[name] = a
        found.append(a)
    return found, skipped


def _matlab_reader():
    """The MATLAB reader's workspace evaluator, when the MATLAB room offers one."""
    try:
        from odelab.formats import matlab  # noqa: F401  (lands with the MATLAB reader)
    except ImportError:
        return None
    return getattr(matlab, "workspace", None)


def _driver_text(text: str, model: str):
    """A driver script's text up to its call of ``sim('model'...)`` (what it assigns before the model runs) and
    that call's time span argument; (None, None) when the script does not call the model."""
    call = re.search(r"\bsim\s*\(\s*['\"]" + re.escape(model) + r"(?:\.slx|\.mdl)?['\"]\s*(?:,\s*(\[[^\]]*\]|[A-Za-z0-9_.]+))?",
                     text, re.IGNORECASE)
    if call is None:
        return None, None
    line = text.count("\n", 0, call.start()) + 1
    return text[:call.start()], (line, call.group(1)) if call.group(1) else None


def _flatten(name: str, value, out: dict) -> None:
    """A workspace value as numbers by name: a struct's fields as ``p.m`` (the name a block parameter writes)."""
    if isinstance(value, dict):
        for key, inner in value.items():
            _flatten(f"{name}.{key}", inner, out)
        return
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        out[name] = np.array([[float(value)]])
    elif isinstance(value, np.ndarray) and value.dtype.kind in "fiu" and value.ndim <= 2:
        out[name] = np.atleast_2d(np.asarray(value, dtype=float))


def _read_with(reader, scripts: list[Path], wanted: set[str]):
    """The MATLAB reader's ``workspace`` on ``scripts``: (assignments, its notes about the wanted names); a script it
    refuses (it calls ``system``, ``eval``...) is a note, never the model's failure."""
    source = ", ".join(p.name for p in scripts)
    try:
        values, notes = reader(scripts)
    except OdelabError as exc:  # refused or not parsed whole: its constant assignments read one by one
        found: list[Assignment] = []
        known: dict[str, Assignment] = {}
        for script in scripts:
            text = script.read_bytes()[:MAX_SCRIPT_BYTES].decode("utf-8", "replace")
            more, _ = assignments(text, script.name, known)
            known.update({a.name: a for a in more})
            found.extend(more)
        if not any(a.name in wanted for a in found):
            return found, []
        why = str(exc).split(": ", 1)[-1]
        return found, [Note("script", source, IGNORED, f"read assignment by assignment (the MATLAB reader stopped: "
                            f"{why})", file=source)]
    flat: dict[str, np.ndarray] = {}
    for name, value in values.items():
        _flatten(name, value, flat)
    found = [Assignment(name, value, source, 0, _shown(value)) for name, value in flat.items()]
    kept = [n for n in notes if n.construct in wanted]
    return found, kept


def _shown(value: np.ndarray) -> str:
    if value.size == 1:
        return repr(float(value.reshape(-1)[0]))
    rows = "; ".join(" ".join(repr(float(x)) for x in row) for row in value[:4])
    return f"[{rows}{' ...' if value.shape[0] > 4 or value.size > 40 else ''}]"[:80]


def _scripts(folder: Path, chosen: tuple[Path, ...]) -> list[Path]:
    if chosen:
        return list(chosen)
    found = sorted(p for p in folder.glob("*.m") if p.is_file())[:MAX_SCRIPTS]
    out = []
    for p in found:
        try:
            head = p.read_bytes()[:MAX_SCRIPT_BYTES]
        except OSError:
            continue
        first = next((ln.strip() for ln in head.decode("utf-8", "replace").splitlines()
                      if ln.strip() and not ln.strip().startswith("%")), "")
        if not first.startswith("function"):  # a function file assigns nothing in the workspace
            out.append(p)
    return out


def read_workspace(model_params: dict[str, str], folder: Path, chosen: tuple[Path, ...], wanted: set[str],
                   model: str = "") -> Workspace:
    """The variables the model's callbacks and the scripts beside it (or those ``chosen``) assign.

    Scripts are read only for the names in ``wanted`` (those the model uses): two scripts that assign one
    of them differently are a conflict the caller reports unless ``--workspace`` chose; the callbacks are
    the model's own and come first. A script beside the model that runs it (``sim('model')``, any case) is its
    driver: when there is one, only the drivers are read, each up to its ``sim`` call, and the call's time span
    (``sim('model', [0 120])``) is kept.
    """
    ws = Workspace()
    base: dict[str, Assignment] = {}
    for cb in CALLBACKS:
        text = model_params.get(cb)
        if text:
            found, skipped = assignments(text, cb, base)
            base.update({a.name: a for a in found})
            ws.skipped.extend(skipped)
    ws.values.update(base)
    per_script: dict[str, list[Assignment]] = {}
    running = dict(base)  # chosen scripts run in the order given, each seeing the ones before it
    texts = {}
    for script in _scripts(folder, chosen):
        try:
            raw = script.read_bytes()[:MAX_SCRIPT_BYTES + 1]
        except OSError:
            continue
        if len(raw) > MAX_SCRIPT_BYTES or b"\x00" in raw:
            ws.skipped.append((script.name, 0, "", "not a MATLAB text script of at most 1 MB"))
            continue
        texts[script] = raw.decode("utf-8", "replace")
    if not chosen and model:
        drivers = {}
        for script, text in texts.items():
            before, span = _driver_text(text, model)
            if before is not None:
                drivers[script] = before
                if span is not None and ws.span is None:
                    ws.span = (script.name, *span)
        if drivers:
            texts = drivers
            ws.drivers = [p.name for p in drivers]
    reader = _matlab_reader()
    if reader is not None and chosen:  # the MATLAB reader runs the chosen scripts in order, in one workspace
        found, notes = _read_with(reader, list(texts), wanted)
        ws.notes.extend(notes)
        for a in found:
            per_script.setdefault(a.name, []).append(a)
        texts = {}
    for script, text in texts.items():
        if reader is not None and not ws.drivers:  # a driver is read up to its sim call: assignment by assignment
            found, notes = _read_with(reader, [script], wanted)
            ws.notes.extend(notes)
            skipped = []
        else:
            found, skipped = assignments(text, script.name, running if chosen else base)
        last = {a.name: a for a in found}
        if chosen:
            running.update(last)
        if not any(n in wanted for n in last) and not chosen:
            continue
        ws.skipped.extend(s for s in skipped if s[2].split("=")[0].strip() in wanted)
        for name, a in last.items():
            per_script.setdefault(name, []).append(a)
    for name, found in per_script.items():
        distinct = {a.value.tobytes() + bytes(str(a.value.shape), "ascii") for a in found}
        if len(distinct) > 1 and not chosen and name in wanted:
            ws.conflicts[name] = found
        ws.values[name] = found[-1]
    return ws
