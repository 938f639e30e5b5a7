"""A MATLAB file to an experiment file: read the driver (never run it), one case per solver call, TOML out.

``translate(path, raw, options)`` reads the file (a script, a driver function, or a right-hand
side alone), the files beside it that it calls, and ``--workspace`` scripts; records each solver
call (:mod:`.calls`); reads each call's right-hand side, options and events (:mod:`.cases`); and
writes the experiment: one case as plain tables, several as ``[[case]]`` tables over a shared
base (the same system) or ``[[problem]]`` tables (different systems). The TOML text is what the
document's dict is read from, so running the ``.m`` file and running the written file are the
same experiment, bit for bit.
"""

from __future__ import annotations

import os
from pathlib import Path

from odelab.exceptions import ExperimentError
from odelab.formats.base import GAP, TRANSLATED, Document, ImportOptions
from odelab.formats.emit import Entry, Section, write_toml
from odelab.formats.matlab import nodes as n
from odelab.formats.matlab.branches import _solver_calls
from odelab.formats.matlab.calls import Recorder
from odelab.formats.matlab.cases import CaseSpec, build_case
from odelab.formats.matlab.exprtext import identifier
from odelab.formats.matlab.machine import make_interpreter
from odelab.formats.matlab.parser import parse_text
from odelab.formats.matlab.scope import Notes, Scope
from odelab.formats.matlab.source import decode, read_source
from odelab.formats.toml import parse_toml

__all__ = ["translate", "Siblings", "parse_sets", "MAX_FILES"]

MAX_FILES = 64
"""The most MATLAB files one import reads (the file, the files it calls, workspace scripts)."""


class Siblings:
    """The ``.m`` files beside the imported one, read (and parsed) when a name is called, each once."""

    def __init__(self, folder: Path, main: n.SourceFile, main_path: Path):
        self.folder = folder
        self.cache: dict[str, n.SourceFile | None] = {main_path.stem: main}
        self.count = 1

    def __call__(self, name: str) -> n.SourceFile | None:
        if name in self.cache:
            return self.cache[name]
        if not name.isidentifier():
            return None
        path = self.folder / f"{name}.m"
        if not path.is_file():
            self.cache[name] = None
            return None
        self.count += 1
        if self.count > MAX_FILES:
            raise ExperimentError(f"calls more than {MAX_FILES} MATLAB files; odelab reads the driver, its right-hand "
                                  "sides and helpers, not a toolbox.", source=str(path))
        raw = read_source(path)
        self.cache[name] = parse_text(decode(raw, str(path)), str(path))
        return self.cache[name]

    def load_path(self, path: Path) -> n.SourceFile:
        raw = read_source(path)
        return parse_text(decode(raw, str(path)), str(path))


def parse_sets(sets, interp) -> dict:
    """``--set NAME=VALUE``: each VALUE read as a MATLAB expression (``k=2``, ``A=[0 1; -2 -3]``)."""
    out = {}
    for name, text in sets:
        if not name.isidentifier():
            raise ExperimentError(f"`--set {name}={text}`: {name!r} is not a MATLAB variable name.")
        try:
            parsed = parse_text(f"{name} = {text};", f"--set {name}")
            scope = Scope(f"--set {name}", mode="script")
            value = interp.eval(parsed.script[0].value, scope)
        except ExperimentError as exc:
            raise ExperimentError(f"`--set {name}={text}`: {exc.message}") from None
        except Exception as exc:  # Unsupported, TooBig: what the value cannot be
            raise ExperimentError(f"`--set {name}={text}`: the value is not a constant odelab can read ({exc}).") \
                from None
        out[name] = interp.named_value(name, value, scope, 0, first=True)
    return out


def _has_solver_call(body: list[n.Stmt]) -> bool:
    return bool(_solver_calls([body]))


def _title(text: str, path: Path, raw: bytes = b"") -> str:
    """The file's H1 line (its first comment), MATLAB's one-line description (not when the file's encoding had to be
    guessed: its comment would be shown garbled)."""
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError:
        return f"{path.name} (MATLAB)"
    for line in text.splitlines()[:40]:
        stripped = line.strip()
        if stripped.startswith(("%", "#")) and not stripped.startswith(("%{", "%%%")):
            words = stripped.lstrip("%#").strip()
            first, _, rest = words.partition(" ")
            if first.upper() == path.stem.upper() and rest.strip():
                words = rest.strip()  # MATLAB's H1 line starts with the name in capitals
            if len(words) > 3:
                return words[:100]
    return f"{path.name} (MATLAB)"


def translate(path: Path, raw: bytes, options: ImportOptions) -> Document:
    path = Path(path)
    src = str(path)
    text = decode(raw, src)
    source = parse_text(text, src)
    notes = Notes(main=path.name)
    siblings = Siblings(path.parent, source, path)
    recorder = Recorder()
    interp = make_interpreter(source, notes, loader=siblings, on_solver=recorder)
    interp.pinned = parse_sets(options.sets, interp)
    scope = Scope(src, mode="script")
    for ws in options.workspace:
        ws_source = siblings.load_path(Path(ws))
        interp.run_script_file(ws_source, scope, 0)
    function_alone = _run(interp, source, scope, options, siblings)
    if recorder.calls:
        inputs: dict = {}
        specs = [build_case(interp, call, name, inputs) for call, name in zip(recorder.calls,
                                                                                _case_names(recorder.calls))]
    elif function_alone is not None:
        from odelab.formats.matlab.alone import function_case

        specs = [function_case(interp, function_alone)]
    else:
        raise ExperimentError("holds no call to an ODE solver (ode45, ode23, ...) and no function to read as a "
                              "right-hand side: nothing to translate. Give the driver script (or the function file "
                              "with --call \"[t,y] = ode45(@f, [0 1], y0)\").", source=src)
    out_dir = Path(options.output) if getattr(options, "output", None) else path.parent
    for spec in specs:
        _relative_files(spec, out_dir)
    sections = assemble(specs, _title(text, path, raw))
    header = (f"Imported from {path.name} by `odelab import` (odelab's MATLAB reader; nothing was run).\n"
              f"Running this file gives the same results, bit for bit, as `odelab run {path.name}`; each section "
              "names the MATLAB line it came from.")
    gaps = sum(len(spec.gaps) for spec in specs)
    if gaps:
        header += f"\n{gaps} gap{'s' if gaps != 1 else ''} (GAP: below) must be filled in before this file runs."
    toml_text = write_toml(sections, header)
    data = parse_toml(toml_text.encode(), src)
    return Document(path=path, data=data, raw=raw, format="matlab", text=toml_text, notes=tuple(notes.rows))


def _run(interp, source: n.SourceFile, scope: Scope, options: ImportOptions, siblings) -> n.Function | None:
    """Read the driver; returns the right-hand side function when the file is one alone (no solver call)."""
    if source.script is not None:
        interp.run_block(source.script, scope)
    elif source.main is not None and _has_solver_call(source.main.body) and not options.call:
        interp.run_driver_function(source.main, scope)
    if options.call:
        call_source = parse_text(options.call, "--call")
        if call_source.script is None:
            raise ExperimentError("`--call` must be a statement such as \"[t,y] = ode45(@f, [0 1], y0)\", not a "
                                  "function.", source="--call")
        siblings.cache["--call"] = call_source
        saved = scope.file
        scope.file = "--call"
        interp.run_block(call_source.script, scope)
        scope.file = saved
        return None
    if source.script is None and source.main is not None and not _has_solver_call(source.main.body):
        return source.main
    return None


def _case_names(calls) -> list[str]:
    names = []
    methods = [c.method for c in calls]
    for call in calls:
        if methods.count(call.method) == 1:
            name = call.method
        elif call.loop:
            name = f"{call.method} {call.loop}"
        else:
            name = f"{call.method} line {call.line}"
        base, k = name, 2
        while name in names or name.lower() in [x.lower() for x in names]:
            name = f"{base} ({k})"
            k += 1
        names.append(name)
    return names


def _relative_files(spec: CaseSpec, out_dir: Path) -> None:
    for table in (spec.tables.get("inputs") or {}).values():
        if "file" in table and os.path.isabs(table["file"]):
            table["file"] = Path(os.path.relpath(table["file"], out_dir.resolve() if out_dir.exists() else out_dir))\
                .as_posix()


# --- writing ----------------------------------------------------------------------------------------------


def _flatten(tables: dict, prefix: tuple = ()) -> dict[tuple, object]:
    out: dict[tuple, object] = {}
    for key, value in tables.items():
        path = prefix + (key,)
        if isinstance(value, dict) and not (len(path) == 3 and path[0] == "events" and key == "reset"):
            if not value:
                continue
            out.update(_flatten(value, path))
        else:
            out[path] = value
    return out


def _section_of(path: tuple) -> tuple[str, str]:
    """The [section] a key path is written in, and its key there."""
    head = path[0]
    if len(path) == 1:
        return "", head
    if head == "system" and len(path) == 3:
        return f"system.{path[1]}", path[2]
    if head == "initial" and len(path) == 3:
        return "initial.fixed", path[2]
    if head in ("inputs", "events") and len(path) == 3:
        return f"{head}.{path[1]}", path[2]
    return head, path[1]


_ORDER = ("", "parameters", "system", "system.equations", "system.residuals", "inputs", "initial", "initial.fixed",
          "time", "solver", "events")


def _rank(section: str) -> tuple:
    head = section.split(".")[0] if section not in _ORDER else section
    base = section if section in _ORDER else head
    return (_ORDER.index(base) if base in _ORDER else len(_ORDER), section)


def _sections(flat: dict, spec: CaseSpec, top: Section, prefix: str = "") -> list[Section]:
    """The key paths as sections (top-level keys and gaps go to ``top``), in the order a reader expects."""
    groups: dict[str, Section] = {}

    def section(name: str) -> Section:
        if not name:
            return top
        if name not in groups:
            parts = tuple(name.split("."))
            comment = spec.comments.get(parts, "") or (spec.comments.get(parts[:1], "") if len(parts) > 1 and
                                                        parts[0] not in ("system",) else "")
            groups[name] = Section(f"{prefix}.{name}" if prefix else name, comment=comment)
        return groups[name]

    for path, value in flat.items():
        name, key = _section_of(path)
        section(name).add(key, value, spec.comments.get(path, ""))
    for path, why in spec.gaps.items():
        name, key = _section_of(path) if len(path) > 1 else ("", path[0])
        section(name).add(key, None, gap=why)
    return [groups[k] for k in sorted(groups, key=_rank)]


def assemble(specs: list[CaseSpec], title: str) -> list[Section]:
    """One case as plain tables; several as [[case]] over a shared base, or [[problem]] tables."""
    top = Section("")
    top.add("title", title)
    if len(specs) == 1:
        flat = _flatten(specs[0].tables)
        return [top] + _sections(flat, specs[0], top)
    flats = [_flatten(s.tables) for s in specs]
    keys = set().union(*flats)
    if all(set(f) == keys for f in flats) and not any(s.gaps.get(("system",)) for s in specs):
        base = {p: v for p, v in flats[0].items() if all(f[p] == v for f in flats[1:])}
        out = [top] + _sections(base, specs[0], top)
        for spec, flat in zip(specs, flats):
            case = Section("case", array=True, comment=spec.comments.get(("solver",), ""))
            case.add("name", spec.name)
            for path, value in flat.items():
                if path not in base:
                    case.add(path, value)
            for path, why in spec.gaps.items():
                case.add(path, None, gap=why)
            out.append(case)
        return out
    out = [top]
    names = _problem_names(specs)
    for spec, flat, name in zip(specs, flats, names):
        problem = Section("problem", array=True, comment=spec.comments.get(("solver",), ""))
        problem.add("name", name)
        out.append(problem)
        out.extend(_sections(flat, spec, problem, prefix="problem"))
    return out


def _problem_names(specs: list[CaseSpec]) -> list[str]:
    names = []
    for spec in specs:
        base = identifier(spec.function if spec.function != "anonymous" else spec.name.replace(" ", "_"), set())
        name, k = base, 2
        while name in names:
            name = f"{base}_{k}"
            k += 1
        names.append(name)
    return names


__all__ += ["Entry", "TRANSLATED"]
