"""A solver's outputs in a script: what odelab can say about them without solving.

``[t, y] = ode45(...)`` gives ``t`` and ``y`` as :class:`~.values.SolverOutput`. Plotting them
is ignored; what a restart loop reads from them is kept as a :class:`~.values.ResultRef`: the
last time (``t(end)``, ``t(nt)`` with ``nt = length(t)``, ``te``) and the last state
(``y(end, :)``, ``y(nt, 2)``, ``ye``), so that the next call's ``y0`` and ``tspan`` can be
recognised as a reset of the state at the event.
"""

from __future__ import annotations

from odelab.formats.matlab import nodes as n
from odelab.formats.matlab.values import Arr, ResultRef, SolverOutput, Unknown, Unsupported

__all__ = ["index_result", "solution_field", "result_count", "result_numbers"]


def _is_last(interp, arg: n.Expr, base: SolverOutput, scope) -> bool:
    if isinstance(arg, n.EndIndex):
        return True
    try:
        scope.end_stack.append(-1)
        value = interp.eval(arg, scope)
    except Unsupported:
        return False
    finally:
        scope.end_stack.pop()
    if isinstance(value, Arr) and value.size == 1:
        item = value.item(0)
        return isinstance(item, ResultRef) and item.kind == "count" and item.call is base.call
    return False


def _states(base: SolverOutput) -> int:
    return base.call.states


def _why(base: SolverOutput) -> Unknown:
    return Unknown(f"the solver's output of line {base.call.line} is used beyond its last time and state (odelab "
                   "stores and plots the whole trajectory)", base.call.line, base.call.file)


def index_result(interp, base: SolverOutput, node: n.Index, scope):
    """``t(end)``, ``y(end, :)``, ``y(nt, 2)``, ``sol.y(:, end)``: the last time or state; anything else unknown."""
    args = node.args
    kind = base.kind
    if kind in ("t", "te") and len(args) == 1 and _is_last(interp, args[0], base, scope):
        return Arr.scalar(ResultRef(base.call, "t_end"))
    if kind in ("y", "ye") and len(args) == 2 and _is_last(interp, args[0], base, scope):
        return _state_columns(interp, base, args[1], scope, row=True)
    if kind == "ysol" and len(args) == 2 and _is_last(interp, args[1], base, scope):
        return _state_columns(interp, base, args[0], scope, row=False)
    if kind in ("y", "ye", "ysol") and len(args) == 1 and isinstance(args[0], n.EndIndex):
        return Arr.scalar(ResultRef(base.call, "y_end", _states(base) - 1))
    if kind in ("ye", "yesol") and len(args) == 1:  # ye(2): a terminal event's state, one row
        return _state_columns(interp, base, args[0], scope, row=True)
    if kind == "te" and len(args) == 1 and isinstance(args[0], n.Num) and args[0].value == 1:
        return Arr.scalar(ResultRef(base.call, "t_end"))
    return _why(base)


def _state_columns(interp, base: SolverOutput, arg: n.Expr, scope, row: bool):
    count = _states(base)
    if isinstance(arg, n.Colon):
        picks = list(range(count))
    else:
        scope.end_stack.append(count)
        try:
            value = interp.eval(arg, scope)
        finally:
            scope.end_stack.pop()
        numbers = value.numbers() if isinstance(value, Arr) else None
        if numbers is None:
            return _why(base)
        picks = [int(v) - 1 for v in numbers.reshape(-1)]
        if any(p < 0 or p >= count for p in picks):
            return _why(base)
    refs = [ResultRef(base.call, "y_end", p) for p in picks]
    return Arr(1, len(refs), items=refs) if row else Arr(len(refs), 1, items=refs)


def solution_field(base: SolverOutput, name: str):
    """``sol.x``, ``sol.y``, ``sol.xe``, ``sol.ye``, ``sol.ie`` of MATLAB's solution struct."""
    if base.kind != "sol":
        return _why(base)
    kinds = {"x": "t", "y": "ysol", "xe": "te", "ye": "yesol", "ie": "ie"}
    if name in kinds:
        return SolverOutput(base.call, kinds[name])
    return _why(base)


def result_count(base: SolverOutput) -> Arr:
    """``length(t)``, ``numel(t)``, ``size(y, 1)``: the number of output points, unknown until solved."""
    return Arr.scalar(ResultRef(base.call, "count"))


def result_numbers(base: SolverOutput):
    """``te`` and ``ye`` used as numbers: a terminal event's time and state are the last ones."""
    if base.kind == "te":
        return Arr.scalar(ResultRef(base.call, "t_end"))
    if base.kind in ("ye", "yesol"):
        refs = [ResultRef(base.call, "y_end", p) for p in range(_states(base))]
        return Arr(1, len(refs), items=refs) if base.kind == "ye" else Arr(len(refs), 1, items=refs)
    return None
