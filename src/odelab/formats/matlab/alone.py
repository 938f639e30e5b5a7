"""A right-hand side alone (the lab's ``eq1.m``: no solver call): the system, with span and initial values as gaps.

The function is read with ``t`` and ``y`` as symbols; how many states it has is what it returns
(read once with a long ``y``, then again with that many states to check). Its arguments after
``t`` and ``y`` are parameters whose values the call would pass: gaps too. ``--call`` supplies
the call a student types at MATLAB's prompt, and the file is then read as that driver.
"""

from __future__ import annotations

from odelab.formats.base import GAP
from odelab.formats.matlab import nodes as n
from odelab.formats.matlab.cases import CaseSpec
from odelab.formats.matlab.calls import SolverCall
from odelab.formats.matlab.exprtext import Namer, _reserved_words
from odelab.formats.matlab.system import read_function, state_names
from odelab.formats.matlab.values import Arr, Const, FuncValue, Param, ParamDef, TooBig, Unsupported

__all__ = ["function_case", "PROBE_STATES"]

PROBE_STATES = 64
"""A right-hand side alone is first read with this many states, to learn how many it returns."""


def function_case(interp, fn: n.Function) -> CaseSpec:
    fv = FuncValue(name=fn.name, file=fn.file, line=fn.line)
    call_text = f"[t, y] = ode45(@{fn.name}, [t0 tf], y0)"
    spec = CaseSpec(fn.name, SolverCall("ode45", fn.line, fn.file, f"function {fn.name}", 2, fun=fv),
                    function=fn.name)
    extras = []
    for name in fn.inputs[2:]:
        if name in ("~", "varargin"):
            continue
        why = (f"{name} is an argument of {fn.name}: its value comes with the solver call (--call "
               f"\"{call_text[:-1]}, [], {name}_value)\"), or write it here")
        extras.append(Arr.scalar(Param(ParamDef(name, Const(1.0), fn.line, fn.file, note="an argument of the "
                                                f"function", gap=why))))
    if len(fn.inputs) < 2:
        return _gap(interp, spec, fn, f"{fn.name} takes {len(fn.inputs)} arguments; a right-hand side takes (t, y)")
    first = read_function(interp, fv, PROBE_STATES, extras, 1)
    if first.gap is not None:
        return _gap(interp, spec, fn, f"{fn.name} cannot be translated: {first.gap.reason}")
    out = first.outputs[0] if first.outputs else None
    if not isinstance(out, Arr) or out.size in (0, PROBE_STATES):
        return _gap(interp, spec, fn, f"how many states {fn.name} has cannot be told from it (it returns as many "
                                      "values as y has): give the call with --call")
    count = out.size
    reading = read_function(interp, fv, count, extras, 1)
    if reading.gap is not None or not isinstance(reading.outputs[0], Arr) or reading.outputs[0].size != count:
        return _gap(interp, spec, fn, f"{fn.name} reads more states than it returns: give the call with --call")
    names = state_names(reading, count, _reserved_words())
    namer = Namer(names, list(interp.inputs))
    equations = {}
    for i, item in enumerate(reading.outputs[0].all_items()):
        try:
            equations[names[i]] = namer.text(item)
        except (Unsupported, TooBig) as exc:
            spec.gaps[("system", "equations", names[i])] = f"the derivative of {names[i]} cannot be written: {exc}"
    spec.tables["system"] = {"states": names, "equations": equations}
    spec.comments[("system",)] = f"the right-hand side {fn.name} (line {fn.line}), read with t and y as symbols"
    if namer.parameters:
        spec.tables["parameters"] = dict(namer.parameters)
        for pname, definition in namer.defs.items():
            if definition.gap:
                spec.tables["parameters"].pop(pname)
                spec.gaps[("parameters", pname)] = definition.gap
                interp.note(fn.line, pname, GAP, definition.gap, fn.file)
            else:
                spec.comments[("parameters", pname)] = f"line {definition.line}"
    if interp.inputs:
        spec.tables["system"]["inputs"] = sorted(namer.inputs_used)
        spec.tables["inputs"] = {i: interp.inputs[i].spec for i in sorted(namer.inputs_used)}
    why = (f"{fn.name}.m has no solver call: the initial values come with it (y0 of {call_text}); give the call "
           f"with --call \"{call_text}\", or write them here")
    for name in names:
        spec.gaps[("initial", name)] = why
    spec.gaps[("time", "stop")] = (f"{fn.name}.m has no solver call: the time span comes with it (tspan of "
                                   f"{call_text}); give the call with --call, or write it here")
    interp.note(fn.line, f"function {fn.name}", "translated", f"[system]: {count} equation{'s' if count != 1 else ''}",
                fn.file)
    interp.note(fn.line, f"function {fn.name}", GAP, f"no solver call: the time span and initial values are not in "
                f"the file; give the call with --call \"{call_text}\"", fn.file)
    return spec


def _gap(interp, spec: CaseSpec, fn: n.Function, why: str) -> CaseSpec:
    spec.tables["system"] = {}
    spec.gaps[("system",)] = why
    interp.note(fn.line, f"function {fn.name}", GAP, why, fn.file)
    return spec
