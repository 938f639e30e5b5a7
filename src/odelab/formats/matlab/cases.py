"""One solver call as an experiment's tables: [system], [parameters], [initial], [time], [solver], [events].

Each value carries the MATLAB line it came from (the written file's comments) and each part
odelab cannot translate is a gap with what to write instead, at its key.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from odelab.formats.base import GAP, IGNORED, TRANSLATED
from odelab.formats.matlab.calls import SolverCall
from odelab.formats.matlab.exprtext import Namer, _reserved_words
from odelab.formats.matlab.system import Reading, definition_site, element_gap, read_function, state_names
from odelab.formats.matlab.values import (Arr, Const, FuncValue, Param, Str, Struct, TooBig, Unknown, Unsupported)

__all__ = ["CaseSpec", "build_case", "KEY_ORDER"]

KEY_ORDER = ("title", "description", "parameters", "system", "inputs", "initial", "time", "solver", "events")

_SWITCH_OPTIONS = {"NormControl": "norm_control", "BDF": "bdf", "Vectorized": "vectorized"}
_NUMBER_OPTIONS = {"RelTol": "rtol", "MaxStep": "max_step", "InitialStep": "initial_step"}
_INTEGER_OPTIONS = {"Refine": "refine", "MaxOrder": "max_order"}
_IGNORED_OPTIONS = {
    "OutputFcn": "plots or prints during the solve: odelab stores every step and the report plots them",
    "OutputSel": "selects what OutputFcn shows: odelab stores every state",
    "Stats": "odelab always prints and stores the step statistics",
    "JPattern": "odelab derives the exact Jacobian of the equations, so no sparsity pattern is needed",
    "JConstant": "odelab derives the exact Jacobian of the equations",
    "MvPattern": "odelab derives the mass matrix's dependence itself",
    "MassSingular": "odelab tells a singular mass matrix from its rank",
    "MinStep": "not an option of MATLAB's ODE suite",
}


@dataclass
class CaseSpec:
    """A case's tables (plain TOML values), the comments of their keys, and its gaps."""

    name: str
    call: SolverCall
    tables: dict[str, Any] = field(default_factory=dict)
    comments: dict[tuple, str] = field(default_factory=dict)  # key path -> comment
    gaps: dict[tuple, str] = field(default_factory=dict)  # key path -> what to write
    function: str = ""  # the right-hand side's name (a [[problem]]'s name)


class _Builder:
    def __init__(self, interp, call: SolverCall, name: str):
        self.interp = interp
        self.call = call
        self.spec = CaseSpec(name, call)
        self.file = Path(call.file).name
        self.where = f"{self.file} line {call.line}" if Path(call.file).name != Path(interp.src).name else \
            f"line {call.line}"

    def gap(self, path: tuple, why: str, line: int = 0, file: str = "", construct: str = "") -> None:
        self.spec.gaps[path] = why
        self.interp.note(line or self.call.line, construct or self.call.text, GAP, why, file or self.call.file)

    def comment(self, path: tuple, text: str) -> None:
        self.spec.comments[path] = text


def build_case(interp, call: SolverCall, name: str, inputs: dict) -> CaseSpec:
    """The tables of one solver call (its right-hand side read on symbols)."""
    b = _Builder(interp, call, name)
    spec = b.spec
    spec.function = call.fun.name if isinstance(call.fun, FuncValue) and call.fun.name else "anonymous"
    if call.gap is not None:
        b.gap(("system",), f"{call.gap.reason}", call.gap.line, call.gap.file, call.gap.construct or call.text)
        spec.tables["system"] = {}
        return spec
    implicit = call.method == "ode15i"
    reading = read_function(interp, call.fun, call.states, call.extras, 1, flag="" if call.flag else None,
                            derivatives=implicit)

    names = state_names(reading, call.states, _reserved_words())
    namer = Namer(names, list(interp.inputs))
    _system(b, reading, names, namer)
    _options(b, namer, names)
    _initial(b, namer, names)
    if implicit:
        _implicit(b, namer, names)
    _time(b, namer)
    spec.tables["solver"] = {"method": call.method, **spec.tables.get("solver", {})}
    b.comment(("solver",), f"{b.where}: {call.text}")
    if call.nargout == 1:
        spec.tables["solver"].setdefault("refine", 1)
        b.comment(("solver", "refine"), "sol = ode...(...) keeps the steps only (sol.x), as MATLAB's solution struct")
    _events_and_reset(b, namer, names)
    if namer.parameters:
        spec.tables["parameters"] = dict(namer.parameters)
        for pname, definition in namer.defs.items():
            where = Path(definition.file).name if definition.file else b.file
            shown = f"{where} line {definition.line}" if definition.line else where
            b.comment(("parameters", pname), f"{shown}{': ' + definition.note if definition.note else ''}")
            if definition.gap:
                spec.tables["parameters"].pop(pname, None)
                b.gap(("parameters", pname), definition.gap, definition.line, definition.file, pname)
    used_inputs = [i for i in interp.inputs if i in namer.inputs_used]
    if used_inputs:
        spec.tables["system"]["inputs"] = used_inputs
        spec.tables["inputs"] = {i: interp.inputs[i].spec for i in used_inputs}
        inputs.update({i: interp.inputs[i] for i in used_inputs})
    return spec


def _system(b: _Builder, reading: Reading, names: list[str], namer: Namer) -> None:
    call = b.call
    fn = call.fun

    file, line, fname = definition_site(b.interp, fn)
    system: dict[str, Any] = {"states": names}
    b.spec.tables["system"] = system
    b.comment(("system",), f"the right-hand side {fname} ({Path(file).name if file else b.file} line {line}), read "
                          "with t and y as symbols")
    if reading.gap is not None:
        b.gap(("system", "equations"), f"the right-hand side {fname} cannot be translated: {reading.gap.reason}",
              reading.gap.line or fn.line, reading.gap.file or fn.file, reading.gap.construct or fname)
        system["equations"] = {}
        return
    out = reading.outputs[0] if reading.outputs else None
    if not isinstance(out, Arr) or out.size != call.states:
        size = f"{out.size} values" if isinstance(out, Arr) else "no numbers"
        b.gap(("system", "equations"), f"the right-hand side {fname} returns {size} for {call.states} states",
              fn.line, fn.file, fname)
        system["equations"] = {}
        return
    equations = {}
    for i, item in enumerate(out.all_items()):
        why = element_gap(item)
        try:
            if why is not None:
                raise Unsupported(why)
            equations[names[i]] = namer.text(item)
        except (Unsupported, TooBig) as exc:
            b.gap(("system", "equations", names[i]), f"the derivative of {names[i]} cannot be written: {exc}",
                  fn.line, fn.file, fname)
    system["equations"] = equations
    b.interp.note(line, f"function {fname}" if fn.params is None else fname, TRANSLATED,
                  f"[system]: {len(equations)} equation{'s' if len(equations) != 1 else ''}", file)
    source = b.interp.file_of(file) if file else None
    for i, name in enumerate(names):
        parts = []
        at = reading.lines.get(i)
        if at and source is not None and 0 < at <= len(source.lines):
            text = source.lines[at - 1].strip()
            parts.append(f"{Path(file).name} line {at}: {text if len(text) <= 70 else text[:67] + '...'}")
        given = reading.names.get(i)
        if given and given[0] == name:
            parts.append(f"{name} = y({i + 1}) on line {given[1]}")
        if parts:
            b.comment(("system", "equations", name), "\n".join(parts))


def _implicit(b: _Builder, namer: Namer, names: list[str]) -> None:
    """ode15i: the function's value is the residuals of 0 = f(t, y, y'); yp0 the slopes' guesses; decic's fixed
    components the [initial.fixed] table."""
    system = b.spec.tables["system"]
    equations = system.pop("equations", {})
    system["kind"] = "implicit"
    system["residuals"] = {f"r{i + 1}": equations[name] for i, name in enumerate(names) if name in equations}
    for key in [k for k in b.spec.gaps if k[:2] == ("system", "equations")]:
        b.spec.gaps[("system", "residuals") + key[2:]] = b.spec.gaps.pop(key)
    initial = b.spec.tables["initial"]
    slopes = b.call.yp0.all_items() if isinstance(b.call.yp0, Arr) else []
    if len(slopes) != len(names):
        b.gap(("initial",), f"ode15i's yp0 has {len(slopes)} values for {len(names)} states")
        return
    for name, item in zip(names, slopes):
        try:
            initial[f"der({name})"] = namer.value(item)
        except (Unsupported, TooBig) as exc:
            b.gap(("initial", f"der({name})"), f"the initial slope of {name} cannot be written: {exc}")
    fixed = _decic_flags(b, names)
    if fixed:
        b.spec.tables["initial"]["fixed"] = fixed
        b.comment(("initial", "fixed"), "decic's fixed_y0 and fixed_yp0: what it may not change")


def _decic_flags(b: _Builder, names: list[str]) -> dict:
    fun = b.call.fun
    for called, fixed_y0, fixed_yp0, line in reversed(b.interp.decic_calls):
        if called is fun or (getattr(called, "name", None), getattr(called, "text", None)) == (fun.name, fun.text):
            out = {}
            for flags, form in ((fixed_y0, "{}"), (fixed_yp0, "der({})")):
                if flags is None:
                    continue
                for name, flag in zip(names, flags):
                    key = form.format(name)
                    if form == "{}" or flag:
                        out[key] = flag
            return out
    return {}


def _number(b: _Builder, value, what: str) -> float | list | None:
    if isinstance(value, Arr):
        numbers = value.numbers()
        if numbers is not None:
            flat = [float(v) for v in numbers.T.reshape(-1)]
            return flat[0] if len(flat) == 1 else flat
    reason = value.reason if isinstance(value, Unknown) else b.interp.why_not_number(value)
    b.gap(("solver", what), f"odeset's {what} is not a constant number: {reason}")
    return None


def _options(b: _Builder, namer: Namer, names: list[str]) -> None:
    options = b.call.options
    solver: dict[str, Any] = {}
    b.spec.tables["solver"] = solver
    if not isinstance(options, Struct):
        return
    for key, value in options.fields.items():
        if isinstance(value, Arr) and value.size == 0:
            continue  # odeset('Name', []): the default
        _option(b, namer, names, solver, key, value)


def _option(b: _Builder, namer: Namer, names: list[str], solver: dict, key: str, value) -> None:
    where = b.call.line
    if key in _NUMBER_OPTIONS:
        number = _number(b, value, key)
        if number is not None:
            solver[_NUMBER_OPTIONS[key]] = number if not isinstance(number, list) else number[0]
    elif key == "AbsTol":
        number = _number(b, value, key)
        if number is not None:
            solver["atol"] = number
    elif key in _INTEGER_OPTIONS:
        number = _number(b, value, key)
        if number is not None:
            solver[_INTEGER_OPTIONS[key]] = int(number if not isinstance(number, list) else number[0])
    elif key in _SWITCH_OPTIONS:
        solver[_SWITCH_OPTIONS[key]] = _switch(value)
    elif key == "MStateDependence" and isinstance(value, Str):
        solver["mstate_dependence"] = value.text.lower()
    elif key == "NonNegative":
        numbers = _number(b, value, key)
        if numbers is not None:
            picks = numbers if isinstance(numbers, list) else [numbers]
            solver["nonnegative"] = [names[int(k) - 1] for k in picks if 1 <= int(k) <= len(names)]
    elif key == "Mass":
        _mass(b, namer, solver, value)
    elif key == "Events":
        pass  # read with the reset in _events_and_reset
    elif key == "Jacobian":
        _jacobian(b, namer, value)
    elif key in _IGNORED_OPTIONS:
        b.interp.note(where, f"odeset('{key}', ...)", IGNORED, _IGNORED_OPTIONS[key], b.call.file)
    else:
        b.gap(("solver", key), f"odeset's {key} is not translated (odelab's [solver] keys: odelab explain solver)")


def _switch(value) -> bool:
    if isinstance(value, Str):
        return value.text.lower() == "on"
    if isinstance(value, Arr) and value.numbers() is not None and value.size == 1:
        return bool(value.numbers()[0, 0])
    return False


def _matrix_of(b: _Builder, namer: Namer, value, what: str, key: tuple) -> list | None:
    n = b.call.states
    if isinstance(value, FuncValue) or (isinstance(value, Str) and b.call.flag):
        if isinstance(value, Str):
            fv, flag, extras = b.call.fun, value.text.lower() if what == "mass" else "jacobian", b.call.extras
            flag = "mass" if what == "mass" else "jacobian"
        else:
            fv, flag, extras = value, None, b.call.extras
        time_only = what == "mass" and isinstance(value, FuncValue) and _arity(b.interp, value) == 1
        reading = read_function(b.interp, fv, n, extras, 1, time_only=time_only, flag=flag)
        if reading.gap is not None:
            b.gap(key, f"the {what} function cannot be translated: {reading.gap.reason}", reading.gap.line,
                  reading.gap.file)
            return None
        value = reading.outputs[0]
    if not isinstance(value, Arr) or value.rows != n or value.cols != n:
        b.gap(key, f"the {what} is not a {n}-by-{n} matrix odelab can read")
        return None
    try:
        return [[namer.value(value.item(j * n + i)) for j in range(n)] for i in range(n)]
    except (Unsupported, TooBig) as exc:
        b.gap(key, f"the {what} cannot be written: {exc}")
        return None


def _arity(interp, fv: FuncValue) -> int:
    if fv.params is not None:
        return len(fv.params)
    from odelab.formats.matlab.scope import Scope

    fn = interp.find_function(fv.name, Scope(fv.file or interp.src))
    return len(fn.inputs) if fn is not None and hasattr(fn, "inputs") else 2


def _mass(b: _Builder, namer: Namer, solver: dict, value) -> None:
    matrix = _matrix_of(b, namer, value, "mass", ("solver", "mass"))
    if matrix is not None:
        solver["mass"] = matrix
        b.comment(("solver", "mass"), "odeset's Mass: M y' = f")


def _jacobian(b: _Builder, namer: Namer, value) -> None:
    matrix = _matrix_of(b, namer, value, "Jacobian", ("system", "jacobian"))
    if matrix is not None:
        b.spec.tables["system"]["jacobian"] = matrix
        b.comment(("system", "jacobian"), "odeset's Jacobian, as the file gives it")


def _initial(b: _Builder, namer: Namer, names: list[str]) -> None:
    initial = {}
    for i, item in enumerate(b.call.y0.all_items()):
        try:
            initial[names[i]] = namer.value(item)
        except (Unsupported, TooBig) as exc:
            b.gap(("initial", names[i]), f"the initial value of {names[i]} cannot be written: {exc}")
    b.spec.tables["initial"] = initial
    b.comment(("initial",), f"{b.where}: y0")


def _time(b: _Builder, namer: Namer) -> None:
    tspan: Arr = b.call.tspan
    time: dict[str, Any] = {}
    b.spec.tables["time"] = time
    b.comment(("time",), f"{b.where}: tspan")
    items = tspan.all_items()
    if len(items) < 2:
        b.gap(("time", "stop"), "tspan has fewer than two values ([t0 tf])")
        return
    try:
        time["start"] = namer.value(items[0])
        time["stop"] = namer.value(items[-1])
    except (Unsupported, TooBig) as exc:
        b.gap(("time", "stop"), f"tspan cannot be written: {exc}")
        return
    if len(items) > 2 and b.call.nargout != 1:
        numbers = tspan.numbers()
        if numbers is None:
            b.gap(("time", "output"), "tspan's values are not constant")
            return
        colon = tspan.colon
        if colon is not None:
            time["output"] = ":".join(_range_text(v) for v in colon)
        else:
            time["output"] = [float(v) for v in numbers.T.reshape(-1)]


def _range_text(value: float) -> str:
    return str(int(value)) if value == int(value) and abs(value) < 1e15 else repr(value)


def _events_and_reset(b: _Builder, namer: Namer, names: list[str]) -> None:
    from odelab.formats.matlab.eventfns import build_events

    build_events(b, namer, names)


__all__ += ["np", "TRANSLATED", "Const", "Param"]
