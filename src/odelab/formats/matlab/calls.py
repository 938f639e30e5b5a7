"""Each solver call of a script, recorded as it is read: a case of the experiment.

``[t, y] = ode45(@f, tspan, y0, options, p1, p2)`` is read with the workspace as it is at that
line (so a nested function sees its parent's variables, a global its value, an anonymous
function what it captured). The call's outputs are symbols that a restart loop may read back
(:mod:`.results`): when the next call of the same line starts from the last state of this one,
the loop is MATLAB's ``ballode`` pattern and becomes a reset event on this case.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.exceptions import ExperimentError
from odelab.formats.base import GAP, IGNORED, TRANSLATED
from odelab.formats.matlab import nodes as n
from odelab.formats.matlab.values import (
    Arr,
    Call,
    FuncValue,
    Op,
    ResultRef,
    SolverOutput,
    State,
    Str,
    Struct,
    Sym,
    Time,
    Unknown,
    Unsupported,
)

__all__ = ["SolverCall", "Recorder", "MAX_CASES"]

MAX_CASES = 200
"""The most solver calls one import turns into cases."""


@dataclass(eq=False)
class SolverCall:
    method: str
    line: int
    file: str
    text: str
    nargout: int
    fun: Any = None  # FuncValue or Unknown
    tspan: Any = None
    y0: Any = None
    options: Any = None  # Struct, None or Unknown
    extras: list = field(default_factory=list)
    states: int = 0
    flag: bool = False  # MATLAB 5's ODE-file protocol
    loop: str = ""  # "k=2" for a call inside a loop
    reset: dict[int, Sym] | None = None  # a restart loop: the state after each terminal event
    max_events: int | None = None
    restart_line: int = 0
    restart_notes: list[str] = field(default_factory=list)
    gap: Unknown | None = None
    yp0: Any = None  # ode15i's initial slopes


class Recorder:
    """The interpreter's ``on_solver``: records each call and gives back its outputs as symbols."""

    def __init__(self):
        self.calls: list[SolverCall] = []

    def __call__(self, interp, method: str, args: list, nargout: int, node: n.Expr, scope) -> list:
        text = _statement_text(interp, scope, node.line)
        call = SolverCall(method, node.line, scope.file, text, nargout)
        try:
            self._arguments(interp, call, args, scope)
        except Unsupported as exc:
            call.gap = Unknown(str(exc), node.line, scope.file, text)
        if call.gap is None:
            previous = self._restart_of(interp, call, scope)
            if previous is not None:
                return _outputs(previous, nargout)
        if len(self.calls) >= MAX_CASES:
            raise ExperimentError(f"line {node.line}: the file calls a solver more than {MAX_CASES} times (loops "
                                  "unrolled); a parameter study is an experiment file's [sweep].", source=scope.file)
        if interp.loops:
            context = interp.loops[-1]
            context["restartable"] = True
            value = context.get("value")
            if context.get("var") and isinstance(value, Arr) and value.size == 1 and value.item(0).num is not None:
                call.loop = f"{context['var']}={value.item(0).num:g}"
        self.calls.append(call)
        interp.solved = len(self.calls)
        interp.note(node.line, text, TRANSLATED, f"a case ({method})", scope.file)
        return _outputs(call, nargout)

    @staticmethod
    def _arguments(interp, call: SolverCall, args: list, scope) -> None:
        if not args:
            raise Unsupported(f"{call.method} needs at least the function")
        fun = args[0]
        if isinstance(fun, Str):
            fun = FuncValue(name=fun.text, file=scope.file, line=call.line, from_string=True)
        if isinstance(fun, Unknown):
            raise Unsupported(fun.reason)
        if not isinstance(fun, FuncValue):
            raise Unsupported(f"{call.method}'s first argument must be a function handle (@f or @(t, y) ...)")
        call.fun = fun
        from odelab.formats.matlab.system import uses_flag

        call.flag = uses_flag(interp, fun)
        rest = list(args[1:])
        if call.method == "ode15i":  # ode15i(f, tspan, y0, yp0, options, extras...)
            if len(rest) < 3 or not isinstance(rest[2], Arr):
                raise Unsupported("ode15i needs the initial slopes yp0 (ode15i(f, tspan, y0, yp0))")
            call.yp0 = rest.pop(2)
        tspan = rest[0] if rest else None
        y0 = rest[1] if len(rest) > 1 else None
        options = rest[2] if len(rest) > 2 else None
        call.extras = rest[3:]
        if _empty(tspan) or _empty(y0):
            if not call.flag:
                raise Unsupported(f"{call.method} is called without a time span or initial values")
            tspan, y0, options = _ode_file_init(interp, call, tspan, y0, options)
        call.tspan = tspan
        call.y0 = y0
        call.options = None if _empty(options) else options
        for value, what in ((tspan, "the time span"), (y0, "the initial values")):
            if isinstance(value, Unknown):
                raise Unsupported(f"{what}: {value.reason}")
            if not isinstance(value, Arr):
                raise Unsupported(f"{what}: {interp.why_not_number(value)}")
        if isinstance(call.options, Unknown):
            raise Unsupported(f"the options: {call.options.reason}")
        if call.options is not None and not isinstance(call.options, Struct):
            raise Unsupported("the fourth argument must be odeset's options (or [])")
        call.states = y0.size
        if call.states == 0:
            raise Unsupported("the initial values are empty")

    def _restart_of(self, interp, call: SolverCall, scope) -> SolverCall | None:
        """This call starts from the last state of an earlier call of the same line: a restart loop."""
        refs = [leaf for value in (call.y0, call.tspan) for item in value.all_items() for leaf in item.leaves()
                if isinstance(leaf, ResultRef)]
        if not refs:
            return None
        previous = refs[0].call
        if any(r.call is not previous for r in refs) or previous.line != call.line or previous.file != call.file \
                or not interp.loops or previous.reset is not None:
            call.gap = Unknown(f"it starts from the result of the solver call on line {previous.line}: odelab runs "
                               "each call as its own case (a restart at an event is an [events] reset)", call.line,
                               call.file, call.text)
            if interp.loops:
                interp.loops[-1]["stop"] = True  # one gap for the loop, not one per pass
            return None
        context = interp.loops[-1]
        problem = _reset_problem(previous, call)
        if problem is not None:
            call.gap = Unknown(f"a restart loop odelab cannot translate: {problem}", call.line, call.file, call.text)
            context["stop"] = True
            return None
        previous.reset = _reset_of(call)
        previous.max_events = context["count"]
        previous.restart_line = context["node"].line
        previous.restart_notes = _option_changes(previous, call)
        context["stop"] = True
        loop = context["node"]
        interp.note(loop.line, loop.text, TRANSLATED, "a restart loop around a terminal event: the event's `reset` "
                    f"and max_events = {previous.max_events if previous.max_events else 'odelab default (100)'}",
                    scope.file)
        return previous


def _statement_text(interp, scope, line: int) -> str:
    source = interp.file_of(scope.file)
    if source is not None and 0 < line <= len(source.lines):
        text = source.lines[line - 1].strip()
        return text if len(text) <= 72 else text[:69] + "..."
    return ""


def _empty(value) -> bool:
    return value is None or (isinstance(value, Arr) and value.size == 0) or (isinstance(value, Str) and not value.text)


def _ode_file_init(interp, call: SolverCall, tspan, y0, options):
    """``ode45('f')``: the ODE file's ``init`` flag gives tspan, y0 and the options."""
    from odelab.formats.matlab.system import read_function

    reading = read_function(interp, call.fun, 0, call.extras, 3, with_state=False, flag="init")
    if reading.gap is not None:
        raise Unsupported(f"the ODE file's 'init' flag: {reading.gap.reason}")
    got = reading.outputs + [None] * (3 - len(reading.outputs))
    tspan = got[0] if _empty(tspan) else tspan
    y0 = got[1] if _empty(y0) else y0
    options = got[2] if _empty(options) else options
    return tspan, y0, options


def _outputs(call: SolverCall, nargout: int) -> list:
    if nargout == 1:
        return [SolverOutput(call, "sol")]
    kinds = ["t", "y", "te", "ye", "ie"]
    return [SolverOutput(call, k) for k in kinds[:max(nargout, 1)]]


def _reset_problem(previous: SolverCall, call: SolverCall) -> str | None:
    if previous.gap is not None:
        return previous.gap.reason
    if _function_key(previous.fun) != _function_key(call.fun):
        return "the loop changes the function between calls"
    if call.states != previous.states:
        return "the loop changes the number of states"
    start = call.tspan.item(0)
    if not (isinstance(start, ResultRef) and start.kind == "t_end"):
        return "the next call does not start where the last one stopped (tspan(1) = t(end))"
    if call.tspan.size != previous.tspan.size or call.tspan.size != 2:
        return "the loop's calls have a time span other than [t0 tf]"
    if call.tspan.item(1).num != previous.tspan.item(1).num:
        return "the loop changes the final time"
    events = previous.options.fields.get("Events") if isinstance(previous.options, Struct) else None
    if events is None:
        return "the calls have no Events function, so nothing stops them early"
    for item in call.y0.all_items():
        for leaf in item.leaves():
            if isinstance(leaf, ResultRef) and leaf.kind != "y_end":
                return "the next initial state uses the result in another way than its last state"
    return None


def _function_key(fv) -> tuple:
    return (getattr(fv, "name", ""), getattr(fv, "text", ""), getattr(fv, "file", ""))


def _reset_of(call: SolverCall) -> dict[int, Sym]:
    """The next call's y0 with the last state's symbols as the states: the reset's expressions."""
    reset: dict[int, Sym] = {}
    for i, item in enumerate(call.y0.all_items()):
        mapped = _at_event(item)
        if isinstance(mapped, State) and mapped.index == i:
            continue  # unchanged
        reset[i] = mapped
    return reset


def _at_event(item: Sym) -> Sym:
    if isinstance(item, ResultRef):
        return State(item.index) if item.kind == "y_end" else Time()
    if isinstance(item, Op):
        return Op(item.op, _at_event(item.a), None if item.b is None else _at_event(item.b))
    if isinstance(item, Call):
        return Call(item.fn, tuple(_at_event(a) for a in item.args))
    return item


def _option_changes(previous: SolverCall, call: SolverCall) -> list[str]:
    """What the loop changes in the options between calls (odelab restarts as MATLAB's first call does)."""
    a = previous.options.fields if isinstance(previous.options, Struct) else {}
    b = call.options.fields if isinstance(call.options, Struct) else {}
    changed = sorted(k for k in set(a) | set(b) if a.get(k) is not b.get(k))
    return changed


__all__ += ["np", "IGNORED", "GAP"]
