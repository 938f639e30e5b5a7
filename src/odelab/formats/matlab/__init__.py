"""MATLAB ODE files (``.m``): read, never run, and written as an experiment file.

:func:`read` is the :mod:`odelab.formats` reader of ``.m`` files: a driver script (or a driver
function, or a right-hand side alone with ``--call``) becomes the experiment its solver calls
describe, with the notes of what was translated, ignored, or could not be (the gaps).
:func:`workspace` evaluates the constant assignments of workspace scripts (``m = 2; k = 3;
A = [0 1; -k/m -b/m];``), as a Simulink model's reader needs them.

The pieces: :mod:`.lexer` and :mod:`.parser` (the MATLAB subset ODE code uses, to a syntax
tree), :mod:`.interp` with :mod:`.evaluate`, :mod:`.branches` and :mod:`.builtins` (reading
that tree on symbolic values, :mod:`.values`), :mod:`.calls` and :mod:`.cases` (each solver
call a case), :mod:`.translate` (the experiment file).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from odelab.exceptions import ExperimentError
from odelab.formats.base import IGNORED, Document, ImportOptions, Note

__all__ = ["read", "workspace", "plain_value", "is_experiment", "EXPLAIN"]

EXPLAIN = """import.m  (MATLAB .m files: a driver script, a driver function, or a right-hand side alone with --call)
  Read, never run. Each call of ode45, ode23, ode113, ode78, ode89, ode15s, ode23s, ode23t, ode23tb or
  ode15i is a case ([t,y] = ... and sol = ... forms; several calls of one system are [[case]]s, of
  different systems [[problem]]s); its right-hand side (a function of the file or beside it, nested or
  local, an anonymous function, MATLAB 5's ode45('f', ...) with a flag argument) is read with t and y as
  symbols: y(1) is the first state, named by `S = y(1)` or else y1, y2...; intermediate variables are
  inlined, if/else on the state becomes where(...), for loops with constant bounds are unrolled, a
  constant matrix times y is written out. Constants become [parameters] however they are passed
  (trailing arguments, values in the function, closures, vectors p(2) -> p_2, structs p.k -> p_k,
  globals, a nested function's parent). odeset: RelTol, AbsTol, MaxStep, InitialStep, Refine,
  NormControl, MaxOrder, BDF, Vectorized, NonNegative, Mass, MStateDependence, Jacobian, Events;
  OutputFcn, OutputSel, Stats, JPattern are noted and ignored. tspan: [t0 tf], a vector, linspace,
  a:h:b. Events functions become [events.NAME]; a loop that restarts the solver from the state at a
  terminal event (MATLAB's ballode) becomes the event's reset and max_events. interp1 of a table in t
  is a table input (the data file's name when the table is a file's two columns). decic's fixed
  components become [initial.fixed].
  Ignored with a note: plotting, printing, figures, clc/clear/close, tic/toc. Gaps (named with their
  line): values odelab cannot know (input(), rand, a file it does not read, a solver's output used as a
  number), a while loop with a data-dependent bound, feval of a computed name, complex numbers, dde23.
  Refused (exit 2): eval, evalin, assignin, system, unix, dos, !, and files beyond the budgets (1 MB,
  nesting, 100,000 loop iterations, recursion). A function file alone (eq1.m) imports with its span and
  initial values as gaps; --call "[t,y] = ode23(@eq1, [0 pi], 2)" supplies the call. --set k=2 pins a
  workspace value (also where the script assigns it); --workspace params.m runs a script first."""

_SOLVER_CALL = re.compile(r"\bode(?:45|23|113|78|89|15s|23s|23t|23tb)\s*\(")


def is_experiment(path: Path) -> bool:
    """A MATLAB file that calls a solver (a driver), or a script; not a function file that a driver calls."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(1_000_001)
    except OSError:
        return True  # reading it says what is wrong
    text = raw.decode("utf-8", errors="replace")
    code = "\n".join(line.split("%")[0] for line in text.splitlines())
    if _SOLVER_CALL.search(code):
        return True
    first = next((line.strip() for line in code.splitlines() if line.strip()), "")
    return not first.startswith("function")


def read(path: Path, options: ImportOptions | None = None) -> Document:
    """The :mod:`odelab.formats` reader of ``.m`` files (see :mod:`.translate`).

    Raises
    ------
    ExperimentError
        A file odelab cannot read at all, or one that would run commands (``system``, ``eval``, ``!``):
        one message naming the file and the line.
    """
    from odelab.formats.matlab.source import read_source
    from odelab.formats.matlab.translate import translate

    raw = read_source(Path(path))
    try:
        return translate(Path(path), raw, options or ImportOptions())
    except ExperimentError:
        raise
    except (RecursionError, MemoryError):
        raise ExperimentError("is beyond what odelab's MATLAB reader can read (nested or large beyond its budgets); "
                              "write the experiment file by hand.", source=str(path)) from None
    except Exception as exc:  # a construct the reader does not expect: one message, never a traceback
        raise ExperimentError(f"could not be read by odelab's MATLAB reader (an internal error, {type(exc).__name__}: "
                              f"{exc}); please report it with the file, and write the experiment file by hand "
                              "meanwhile.", source=str(path)) from None


def plain_value(value: Any) -> Any:
    """A workspace value as plain Python: a float, a numpy array, a str, a dict (struct), a list (cell);
    None for what is not a constant (a function handle, a value odelab cannot know)."""
    from odelab.formats.matlab.values import Arr, Cell, Str, Struct

    if isinstance(value, Arr):
        numbers = value.numbers()
        if numbers is None:
            return None
        if value.is_char:
            return "".join(chr(int(c)) for c in numbers.reshape(-1))
        return float(numbers[0, 0]) if value.size == 1 else np.array(numbers)
    if isinstance(value, Str):
        return value.text
    if isinstance(value, Struct):
        out = {k: plain_value(v) for k, v in value.fields.items()}
        return {k: v for k, v in out.items() if v is not None}
    if isinstance(value, Cell):
        return [plain_value(v) for v in value.items]
    return None


def workspace(paths: list[Path], sets=()) -> tuple[dict[str, Any], list[Note]]:
    """The variables that MATLAB scripts assign, evaluated without running them.

    Parameters
    ----------
    paths
        ``.m`` scripts, read in order in one workspace (a later assignment wins).
    sets
        ``(name, text)`` pairs (``--set k=5``): each text read as a MATLAB expression; the name keeps
        that value even where a script assigns it.

    Returns
    -------
    values, notes
        ``name -> value`` (a float, a numpy array, a str, a dict for a struct, a list for a cell array)
        for every variable with a constant value, and the notes: what was not read (a plot, a
        ``load`` of a file odelab does not read, ``rand``) and which variables were left unknown.

    Raises
    ------
    ExperimentError
        A script odelab refuses (it calls ``system``, ``eval``...), or cannot read at all.
    """
    from odelab.formats.matlab.machine import make_interpreter
    from odelab.formats.matlab.parser import parse_text
    from odelab.formats.matlab.scope import Notes, Scope
    from odelab.formats.matlab.source import decode, read_source
    from odelab.formats.matlab.translate import Siblings, parse_sets
    from odelab.formats.matlab.values import Unknown

    paths = [Path(p) for p in paths]
    notes = Notes(main="")
    values: dict[str, Any] = {}
    if not paths and not sets:
        return values, []
    first = parse_text(decode(read_source(paths[0]), str(paths[0])), str(paths[0])) if paths else \
        parse_text("x = 0;", "--set")
    interp = make_interpreter(first, notes, loader=Siblings(paths[0].parent, first, paths[0]) if paths else None)
    interp.pinned = parse_sets(tuple(sets), interp)
    scope = Scope(str(paths[0]) if paths else "--set", mode="script")
    for k, path in enumerate(paths):
        source = first if k == 0 else parse_text(decode(read_source(path), str(path)), str(path))
        interp.source = source
        scope.file = str(path)
        if source.script is None:
            notes.add(0, path.name, IGNORED, "a function file, not a script: it assigns no workspace variable",
                      path.name)
            continue
        interp.run_block(source.script, scope)
    for name, value in interp.pinned.items():
        scope.vars.setdefault(name, value)
    for name, value in scope.vars.items():
        plain = plain_value(value)
        if plain is None:
            why = value.reason if isinstance(value, Unknown) else "not a constant (a function handle or a solver's output)"
            notes.add(getattr(value, "line", 0), name, IGNORED, f"left unknown: {why}",
                      Path(getattr(value, "file", "") or "").name)
            continue
        values[name] = plain
    for name in scope.globals:
        if name in interp.globals and name not in values:
            plain = plain_value(interp.globals[name])
            if plain is not None:
                values[name] = plain
    return values, list(notes.rows)
