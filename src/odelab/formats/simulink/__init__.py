"""Simulink models (``.slx``, ``.mdl``) read as odelab diagram experiments, never run.

``read(path, options)`` reads the file (an ``.slx`` zip in either layout, a classic or a
text-package ``.mdl``) with every member, size and nesting checked before it is parsed and XML
refused if it declares a DTD or entities (:mod:`~odelab.formats.simulink.container`), takes the
model's workspace variables from its callbacks and the scripts beside it
(:mod:`~odelab.formats.simulink.workspace`), flattens its subsystems and maps each block onto
odelab's block registry with Simulink's defaults (:mod:`~odelab.formats.simulink.translate`,
:mod:`~odelab.formats.simulink.mapping`), and writes the experiment file: ``[parameters]`` (the
workspace's and the masks' numbers), ``[system] kind = "diagram"`` with the model's outputs,
``[blocks]``, ``[time]`` and ``[solver]``, each commented with the block or setting it came from.
The document's ``data`` is the TOML reader's reading of that text, so running the model and
running the written file give the same bits.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from odelab.exceptions import ExperimentError, OdelabError
from odelab.formats.base import GAP, IGNORED, TRANSLATED, Document, ImportOptions, Note
from odelab.formats.emit import Section, write_toml
from odelab.formats.simulink import mapping
from odelab.formats.simulink.container import ContainerError
from odelab.formats.simulink.mexpr import MExprError, V, evaluate
from odelab.formats.simulink.model import Model, ModelError, load_model
from odelab.formats.simulink.scope import Parameters, Scope, identifier
from odelab.formats.simulink.settings import settings
from odelab.formats.simulink.translate import INHERIT, translate
from odelab.formats.simulink.wiring import finish
from odelab.formats.simulink.workspace import read_workspace
from odelab.formats.toml import parse_toml, read_bytes

__all__ = ["MAX_MODEL_BYTES", "read"]

MAX_MODEL_BYTES = 50_000_000
"""A model file is at most 50 MB (a large course model is 100 kB; the slx of a vehicle model 5 MB)."""


def _too_big(size: int | None) -> str:
    shown = f"{size:,}" if size is not None else f"more than {MAX_MODEL_BYTES:,}"
    return f"is {shown} bytes; Simulink models are read up to {MAX_MODEL_BYTES:,} bytes (50 MB)."


def read(path: Path, options: ImportOptions | None = None) -> Document:
    """The :mod:`odelab.formats` reader of ``.slx`` and ``.mdl`` files."""
    try:
        return _read(Path(path), options)
    except (OdelabError, MemoryError, KeyboardInterrupt):
        raise
    except Exception as exc:  # a construct no test has met: one message naming the file, never a traceback
        raise ExperimentError(f"could not be read as a Simulink model ({type(exc).__name__}: {exc}); write the "
                              "experiment file by hand, and report the model so the importer learns it.",
                              source=str(path)) from None


def _read(path: Path, options: ImportOptions | None) -> Document:
    path = Path(path)
    src = str(path)
    options = options or ImportOptions()
    raw = read_bytes(path, limit=MAX_MODEL_BYTES, too_big=_too_big)
    try:
        model = load_model(raw, path.stem)
    except (ContainerError, ModelError) as exc:
        fix = ("; flatten the model's deepest subsystems" if getattr(exc, "depth", False) else "")
        raise ExperimentError(f"is refused: {exc}{fix} (nothing was run, extracted or fetched).", source=src) from None
    _refuse_physical(model, src)
    notes: list[Note] = []
    scope = _root_scope(model, path, options, notes, src)
    tr = translate(model, scope)
    rates = [float(f.spec["sample_time"] if not isinstance(f.spec["sample_time"], list) else f.spec["sample_time"][0])
             for f in tr.flats.values() if isinstance(f.spec.get("sample_time"), (int, float, list))
             and not isinstance(f.spec.get("sample_time"), str)]
    time, solver, step, solver_notes = settings(model.solver, lambda n: scope.lookup(n, "model"), rates)
    tr.fixed_step = step
    finish(tr)
    if not tr.flats:
        raise ExperimentError(f"has nothing to simulate: no block of the model {model.name!r} feeds a Scope, Display, "
                              "To Workspace block or Outport (an empty model, or sinks with nothing connected). "
                              "Connect a source to a Scope in Simulink, or write the experiment file by hand.",
                              source=src)
    solver = _delays(tr, solver, notes)
    notes.extend(tr.notes)
    notes.extend(solver_notes)
    notes.extend(_missing_notes(tr))
    sections = _sections(model, tr, time, solver)
    header = (f"{path.name}: the Simulink model {model.name!r} ({model.format}), imported by odelab.\n"
              "Each block's comment names the Simulink block it came from; block names are made identifiers "
              "(spaces and symbols as _, a subsystem's blocks as Subsystem_Block).")
    text = write_toml(sections, header)
    data = parse_toml(text.encode("utf-8"), src)
    return Document(path=path, data=data, raw=raw, format="simulink", text=text, notes=tuple(notes))


def _all_blocks(model: Model):
    stack = [model.root]
    while stack:
        system = stack.pop()
        for block in system.blocks:
            yield block, system
            if block.system is not None:
                stack.append(block.system)


def _refuse_physical(model: Model, src: str) -> None:
    found = []
    for block, system in _all_blocks(model):
        library = block.source.split("/")[0]
        if block.type in mapping.PHYSICAL_TYPES or library in mapping.PHYSICAL_LIBRARIES:
            found.append(block.path)
    systems = [model.root] + [b.system for b, _ in _all_blocks(model) if b.system is not None]
    for system in systems:
        for line in system.lines:
            for block, port in [line.src, *line.dsts]:
                if port.startswith(("lconn", "rconn", "conn")) and block.path not in found:
                    found.append(block.path)
    if not found:
        return
    shown = ", ".join(found[:8]) + (f" and {len(found) - 8} more" if len(found) > 8 else "")
    raise ExperimentError(f"is a physical-network model (Simscape / Simscape Electrical): its blocks {shown} are "
                          "physical components, which `odelab import` does not translate. Write the circuit or "
                          "mechanism as an odelab network (`kind = \"network\"`, see docs/networks.md) and the "
                          "signal part as a diagram.", source=src)


_NAME = re.compile(r"(?<![\w.'])([A-Za-z][A-Za-z0-9_]*(?:\.[A-Za-z][A-Za-z0-9_]*)*)")
_NOT_VALUES = {"Name", "SID", "Position", "ZOrder", "BlockType", "Ports", "SourceBlock", "SourceType", "BackgroundColor",
               "ForegroundColor", "FontName", "Orientation", "NamePlacement", "ShowName", "LibraryVersion"}


def _names_used(model: Model) -> set[str]:
    out: set[str] = set()
    for block, _ in _all_blocks(model):
        for key, value in block.params.items():
            if key not in _NOT_VALUES and isinstance(value, str) and len(value) < 10_000:
                found = _NAME.findall(value)
                if key in ("Expr", "Expression"):  # a Fcn's input u, u(1), u[2]
                    found = [n for n in found if not re.fullmatch(r"u\d*", n)]
                out.update(found)
        for _, value in block.mask:
            out.update(_NAME.findall(value))
    for value in model.solver.values():
        out.update(_NAME.findall(value))
    return out


def _root_scope(model: Model, path: Path, options: ImportOptions, notes: list[Note], src: str) -> Scope:
    """The workspace: callbacks, scripts beside the model (or --workspace's), then --set."""
    wanted = _names_used(model)
    chosen = tuple(Path(p) for p in options.workspace)
    for p in chosen:
        if not Path(p).is_file():
            raise ExperimentError(f"`--workspace {p}`: no such script; give the MATLAB script that assigns the "
                                  "model's variables.", source=src)
    ws = read_workspace(model.params, path.parent, chosen, wanted, path.stem)
    if ws.drivers:
        notes.append(Note("workspace", ", ".join(ws.drivers), TRANSLATED, "the script beside the model that runs it "
                          "(sim('" + path.stem + "')): its assignments before that call are the workspace"))
    if ws.span is not None:
        _sim_span(model, ws, notes)
    bindings: dict = {}
    for name, a in ws.values.items():
        line = f", line {a.line}" if a.line else ""
        bindings[name] = (a.value, f"{a.source}{line}: {name} = {a.text}")
    notes.extend(ws.notes)
    for name, found in ws.conflicts.items():
        where = "; ".join(f"{a.source}{f' line {a.line}' if a.line else ''}: {name} = {a.text}" for a in found)
        notes.append(Note("workspace", name, GAP, f"scripts beside the model assign it differently ({where}): choose "
                          f"one with --workspace SCRIPT.m, or set it with --set {name}=VALUE"))
    for source, line, stmt, why in ws.skipped:
        notes.append(Note(f"line {line}", stmt[:60], IGNORED, f"not a constant assignment this importer reads "
                          f"({why})", file=source))
    for name, text in options.sets:
        lookup = (lambda n: V(bindings[n][0]) if n in bindings and not isinstance(bindings[n][0], V) else None)
        try:
            value = evaluate(text, lookup)
        except MExprError as exc:
            raise ExperimentError(f"`--set {name}={text}`: {exc}; give a number or a MATLAB matrix "
                                  "(--set K=2.5, --set A=\"[0 1; -2 -3]\").", source=src) from None
        bindings[name] = (value.num, f"--set {name}={text}")
        ws.conflicts.pop(name, None)
        notes[:] = [n for n in notes if not (n.where == "workspace" and n.construct == name)]
    return Scope(None, bindings, params=Parameters())


def _sim_span(model: Model, ws, notes: list[Note]) -> None:
    """``sim('model', [t0 tf])`` in the driver script: its span replaces StartTime and StopTime."""
    script, line, text = ws.span
    try:
        value = evaluate(text, lambda n: V(ws.values[n].value) if n in ws.values else None)
    except MExprError:
        return
    times = value.num.reshape(-1)
    if times.size >= 2 and all(np.isfinite(times[[0, -1]])):
        model.solver["StartTime"], model.solver["StopTime"] = repr(float(times[0])), repr(float(times[-1]))
    elif times.size == 1 and np.isfinite(times[0]):
        model.solver["StopTime"] = repr(float(times[0]))
    else:
        return
    notes.append(Note(f"line {line}", f"sim(..., {text})", TRANSLATED, "the span of the driver's sim call replaces "
                      "the model's StartTime and StopTime", file=script))


def _delays(tr, solver: list, notes: list[Note]) -> list:
    """A transport delay makes the diagram delay equations: odelab solves them with dde23 (MATLAB's), which takes
    RelTol, AbsTol and MaxStep; Simulink's own solver keeps a buffer of the delayed input instead."""
    if not any(f.spec.get("type") == "transport-delay" and not f.gap for f in tr.flats.values()):
        return solver
    method = next(v for k, v, _ in solver if k == "method")
    if method in ("euler", "heun", "rk3", "rk4"):
        return solver
    notes.append(Note("model", "Transport Delay", TRANSLATED, f"delay equations: solved by dde23 (Simulink's {method} "
                      "reads the delayed input from a buffer; odelab's dde23 tracks the delay's discontinuities)"))
    out = [(k, v, c) for k, v, c in solver if k in ("rtol", "atol", "max_step")]
    return [("method", "dde23", "a transport delay: delay equations, MATLAB's dde23"), *out]


def _missing_notes(tr) -> list[Note]:
    out = []
    for name, users in tr.missing.items():
        shown = ", ".join(users[:4]) + (f" and {len(users) - 4} more" if len(users) > 4 else "")
        out.append(Note("workspace", name, GAP, f"nobody sets `{name}` (used by {shown}): give it in a script beside "
                        f"the model ({name} = ...;), with --set {name}=VALUE, or in the written [parameters]"))
    return out


def _sections(model: Model, tr, time, solver) -> list[Section]:
    params = Section("parameters", comment="The model's workspace variables and mask parameters that its blocks use.")
    for p in tr.params.entries.values():
        params.add(p.name, p.value, comment=p.comment)
    for name, users in tr.missing.items():
        params.add(identifier(name), None, gap=f"`{name}` is used by {', '.join(users[:3])} but nobody sets it: "
                   "write its value here")
    system = Section("system", comment="A diagram: the model's blocks, flattened.")
    system.add("kind", "diagram")
    system.add("outputs", dict(tr.outputs), comment="The model's outputs: what its Scopes, Displays, To Workspace "
               "blocks and Outports show.")
    loops = model.solver.get("AlgebraicLoopMsg", "warning").strip().lower()
    if loops in ("error", "none"):
        system.add("algebraic_loops", loops, comment=f"AlgebraicLoopMsg {loops}")
    blocks = Section("blocks")
    for flat in tr.flats.values():
        comment = f"{flat.owner.path} ({flat.owner.type if flat.owner.type != 'Reference' else flat.owner.source})"
        if flat.gap:
            blocks.add(flat.name, None, comment=comment, gap=flat.gap if flat.gap != "not translated" else
                       "this block has no odelab translation (see the import table)")
            continue
        spec = dict(flat.spec)
        if spec.get("sample_time") == INHERIT:
            spec["sample_time"] = 1.0
        if flat.refs:
            if spec.get("type") in ("sum", "product", "mux", "min-max", "switch", "state-space", "fcn", "lookup-table",
                                    "discrete-state-space") and len(flat.refs) > 1:
                spec["inputs"] = list(flat.refs)
            else:
                spec["input"] = flat.refs[0] if len(flat.refs) == 1 else None
                if spec["input"] is None:
                    del spec["input"]
                    spec["inputs"] = list(flat.refs)
        blocks.add(flat.name, spec, comment=comment)
    time_section = Section("time")
    for key, value, comment in time:
        if value is None:
            time_section.add(key, None, comment=comment, gap="StopTime is inf: give the time the run stops")
        else:
            time_section.add(key, value, comment=comment)
    solver_section = Section("solver")
    for key, value, comment in solver:
        solver_section.add(key, value, comment=comment)
    return [Section("", [], ""), _title(model), params, system, blocks, time_section, solver_section]


def _title(model: Model) -> Section:
    top = Section("")
    top.add("title", f"Simulink model {model.name}")
    return top
