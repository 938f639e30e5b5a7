"""Control flow read without running: ``if``/``switch`` (constant conditions pick a branch, conditions on the
state become ``where``), ``for`` loops unrolled within budget, ``while`` loops with constant conditions.

In a right-hand side, ``if y(1) > 0, a = ...; else a = ...; end`` is read both ways and each
variable the branches set differently becomes ``where(y1 > 0, ..., ...)``. A branch that calls
``error`` is left out (odelab integrates on where MATLAB would stop: noted). In a script, a
condition on something odelab cannot know (a solver's output, a figure's state) skips the
branches, and what they set becomes unknown, a gap only where a case needs it.
"""

from __future__ import annotations

import math

import numpy as np

from odelab.exceptions import ExperimentError
from odelab.formats.base import IGNORED
from odelab.formats.matlab import nodes as n
from odelab.formats.matlab import ops
from odelab.formats.matlab.flow import (BreakLoop, ContinueLoop, ErrorCalled, Failure, ReturnNow, assigned_names)
from odelab.formats.matlab.values import (
    Arr,
    Call,
    Cell,
    Const,
    Op,
    Param,
    ParamDef,
    ResultRef,
    Str,
    Struct,
    Sym,
    Unknown,
    Unsupported,
)

__all__ = ["run_if", "run_switch", "run_for", "run_while", "condition"]


def condition(interp, expr: n.Expr, scope):
    """A condition's truth: True/False when constant, a 0/1 Sym when it depends on the state, or an Unknown."""
    value = interp.eval(expr, scope)
    if isinstance(value, Unknown):
        return value
    if isinstance(value, Str):
        return bool(value.text)
    if not isinstance(value, Arr):
        return Unknown(interp.why_not_number(value, "a condition"), expr.line, scope.file)
    if value.size == 0:
        return False
    numbers = value.numbers()
    if numbers is not None:
        return bool(np.all(numbers != 0))
    if any(isinstance(leaf, ResultRef) for item in value.all_items() for leaf in item.leaves()):
        return Unknown("the condition depends on a solver's result", expr.line, scope.file)
    items = [ops.truth(i) for i in value.all_items()]
    combined = items[0]
    for item in items[1:]:
        combined = Op("*", combined, item)
    return combined


def _skip(interp, stmt: n.Stmt, bodies: list[list[n.Stmt]], scope, why: Unknown) -> None:
    """Branches odelab cannot choose between in a script: what they set is unknown."""
    names = set()
    for body in bodies:
        names |= assigned_names(body)
    for name in names:
        scope.set(name, Unknown(f"set under the condition of line {stmt.line}, which depends on something odelab "
                                f"cannot know ({why.reason})", stmt.line, scope.file), interp.globals)
    if scope.mode == "script":
        calls = _solver_calls(bodies)
        if calls:
            interp.note(stmt.line, stmt.text, "gap", f"the solver call on line {calls[0]} runs only under a "
                        f"condition odelab cannot decide ({why.reason}); write the case out in the experiment file",
                        scope.file)
        else:
            interp.note(stmt.line, stmt.text, IGNORED, f"not read: its condition depends on something odelab cannot "
                        f"know ({why.reason})", scope.file)


def _solver_calls(bodies) -> list[int]:
    from odelab.formats.matlab.builtins import SOLVERS

    lines = []
    stack = [s for body in bodies for s in body]
    while stack:
        stmt = stack.pop()
        expr_nodes = []
        if isinstance(stmt, n.Assign):
            expr_nodes.append(stmt.value)
        elif isinstance(stmt, n.ExprStmt):
            expr_nodes.append(stmt.expr)
        for node in expr_nodes:
            if isinstance(node, n.Index) and isinstance(node.target, n.Id) and node.target.name in SOLVERS:
                lines.append(stmt.line)
        for attr in ("body", "orelse", "handler", "otherwise"):
            stack.extend(getattr(stmt, attr, None) or [])
        for _, block in getattr(stmt, "clauses", None) or getattr(stmt, "cases", None) or []:
            stack.extend(block)
    return sorted(lines)


def run_if(interp, stmt: n.If, scope) -> None:
    symbolic: list[tuple[Sym, list[n.Stmt]]] = []
    for cond_expr, body in stmt.clauses:
        truth = condition(interp, cond_expr, scope)
        if isinstance(truth, Unknown):
            if symbolic:
                raise Unsupported(f"the condition of line {cond_expr.line} cannot be decided: {truth.reason}")
            bodies = [b for _, b in stmt.clauses] + [stmt.orelse or []]
            _skip(interp, stmt, bodies, scope, truth)
            return
        if truth is True and not symbolic:
            interp.run_block(body, scope)
            return
        if truth is False:
            continue
        if truth is True:
            symbolic.append((None, body))
            break
        symbolic.append((truth, body))
    else:
        if not symbolic:
            interp.run_block(stmt.orelse or [], scope)
            return
        symbolic.append((None, stmt.orelse or []))
    _merge_branches(interp, stmt, symbolic, scope)


def _merge_branches(interp, stmt: n.Stmt, branches: list, scope) -> None:
    """Run each branch on its own copy of the workspace, then join what they set with `where`."""
    before = dict(scope.vars)
    results = []
    scope.branch_depth += 1
    try:
        for cond, body in branches:
            scope.vars = dict(before)
            try:
                interp.run_block(body, scope)
            except ErrorCalled as exc:
                interp.note(exc.line, "error(...)", IGNORED, "an error under a condition on the state: odelab "
                            "integrates on where MATLAB would stop", scope.file)
                continue
            except (ReturnNow, BreakLoop, ContinueLoop):
                raise Unsupported(f"`return`, `break` or `continue` under a condition on the state (line {stmt.line}) "
                                  "is not translated")
            results.append((cond, scope.vars))
    finally:
        scope.branch_depth -= 1
        scope.vars = before
    if not results:
        raise ErrorCalled("every branch calls error", stmt.line)
    merged = dict(results[-1][1])
    names = set().union(*[set(r[1]) for r in results])
    for name in names:
        values = [r[1].get(name) for r in results]
        if all(v is values[0] for v in values):
            merged[name] = values[0]
            continue
        if any(v is None for v in values):
            merged[name] = Unknown(f"`{name}` is set in only some branches of the if of line {stmt.line}", stmt.line,
                                   scope.file)
            continue
        value = values[-1]
        for (cond, _), other in zip(reversed(results[:-1]), reversed(values[:-1])):
            value = _where(cond, other, value, name, stmt.line, scope)
        merged[name] = value
    scope.vars = merged
    scope.assigned |= names


def _where(cond: Sym, a, b, name: str, line: int, scope):
    if a is b:
        return a
    if isinstance(a, Unknown):
        return a
    if isinstance(b, Unknown):
        return b
    if isinstance(a, Arr) and isinstance(b, Arr):
        rows, cols = max(a.rows, b.rows), max(a.cols, b.cols)
        if (a.size != 1 and a.shape != (rows, cols)) or (b.size != 1 and b.shape != (rows, cols)):
            return Unknown(f"`{name}` has different sizes in the branches of the if of line {line}", line, scope.file)
        items = []
        for k in range(rows * cols):
            x = a.item(0 if a.size == 1 else k)
            y = b.item(0 if b.size == 1 else k)
            items.append(x if x is y else Call("where", (cond, x, y)))
        return Arr.of_items(rows, cols, items)
    if isinstance(a, Struct) and isinstance(b, Struct) and set(a.fields) == set(b.fields):
        fields = {k: _where(cond, a.fields[k], b.fields[k], f"{name}.{k}", line, scope) for k in a.fields}
        return Struct(fields, origin=a.origin, odeset=a.odeset)
    return Unknown(f"`{name}` differs between the branches of the if of line {line} in a way odelab cannot join",
                   line, scope.file)


def run_switch(interp, stmt: n.Switch, scope) -> None:
    subject = interp.eval(stmt.subject, scope)
    if isinstance(subject, Unknown):
        _skip(interp, stmt, [b for _, b in stmt.cases] + [stmt.otherwise or []], scope, subject)
        return
    for value_expr, body in stmt.cases:
        candidates = interp.eval(value_expr, scope)
        options = candidates.items if isinstance(candidates, Cell) else [candidates]
        for option in options:
            matched = _matches(interp, subject, option)
            if matched is None:
                raise Unsupported(f"the switch of line {stmt.line} compares values that depend on the state")
            if matched:
                interp.run_block(body, scope)
                return
    interp.run_block(stmt.otherwise or [], scope)


def _matches(interp, subject, option) -> bool | None:
    if isinstance(subject, Str) or isinstance(option, Str):
        return isinstance(subject, Str) and isinstance(option, Str) and subject.text == option.text
    if isinstance(subject, Arr) and isinstance(option, Arr):
        a, b = subject.scalar_value(), option.scalar_value()
        if a is None or b is None:
            return None
        return a == b
    return False


def _loop_values(interp, stmt: n.For, scope) -> list:
    iterable = stmt.iterable
    if isinstance(iterable, n.Range):  # count before building: `for k = 1:1e9` stops here
        parts = []
        for p in (iterable.start, iterable.step, iterable.stop):
            value = interp.eval(p, scope) if p is not None else Arr.numeric(1.0)
            number = value.scalar_value() if isinstance(value, Arr) else None
            if number is None:
                raise Failure(f"the loop's range is not constant ({interp.why_not_number(value, 'a bound')})"
                              if not isinstance(value, Arr) else "the loop's range is not constant")
            parts.append(number)
        start, step, stop = parts
        if step != 0 and all(math.isfinite(v) for v in parts):
            count = math.floor((stop - start) / step) + 1
            if count > 0:
                interp.budget.loop(count, stmt.line, scope.file)
    value = interp.eval(iterable, scope)
    if isinstance(value, Unknown):
        raise Failure(f"the loop's range is not constant ({value.reason})")
    if isinstance(value, Cell):
        return [Cell(value.rows, 1, value.items[j * value.rows:(j + 1) * value.rows]) for j in range(value.cols)]
    value = interp.numeric(value, "a loop's range")
    if not isinstance(iterable, n.Range):
        interp.budget.loop(value.cols, stmt.line, scope.file)
    return [ops.index(value, [ops.COLON, Arr.numeric(j + 1.0)]) for j in range(value.cols)]


def run_for(interp, stmt: n.For, scope) -> None:
    try:
        values = _loop_values(interp, stmt, scope)
    except Failure as exc:
        if scope.mode == "script":
            _skip(interp, stmt, [stmt.body], scope, Unknown(str(exc), stmt.line, scope.file))
            return
        raise
    context = {"node": stmt, "count": len(values), "index": 0, "var": stmt.var.name}
    interp.loops.append(context)
    scope.loop_depth += 1
    try:
        for k, value in enumerate(values):
            context["index"] = k
            if scope.mode == "script" and value.size == 1 and value.is_constant() and value.data is not None:
                value = Arr.scalar(Param(ParamDef(stmt.var.name, Const(value.scalar_value()), stmt.line, scope.file)))
            context["value"] = value
            scope.set(stmt.var.name, value, interp.globals)
            scope.assigned.add(stmt.var.name)
            try:
                interp.run_block(stmt.body, scope)
            except ContinueLoop:
                continue
            except BreakLoop:
                break
            if context.get("stop"):
                break
    finally:
        scope.loop_depth -= 1
        interp.loops.pop()


def run_while(interp, stmt: n.While, scope) -> None:
    context = {"node": stmt, "count": None, "index": 0, "var": None}
    interp.loops.append(context)
    scope.loop_depth += 1
    try:
        while True:
            truth = condition(interp, stmt.cond, scope)
            if isinstance(truth, Unknown):
                if context["index"] > 0 and context.get("restartable"):
                    context["speculative"] = True  # read the body once more: a restart loop shows itself
                    truth = True
                else:
                    _while_gap(interp, stmt, scope, truth)
                    return
            elif not isinstance(truth, bool):
                raise Unsupported(f"a while loop whose condition depends on the state (line {stmt.line})")
            if not truth:
                return
            interp.budget.loop(1, stmt.line, scope.file)
            try:
                interp.run_block(stmt.body, scope)
            except ContinueLoop:
                pass
            except BreakLoop:
                return
            context["index"] += 1
            if context.get("stop") or context.get("speculative"):
                if not context.get("stop"):
                    _while_gap(interp, stmt, scope, truth if isinstance(truth, Unknown) else
                               Unknown("its condition depends on the solver's result", stmt.line, scope.file))
                return
    finally:
        scope.loop_depth -= 1
        interp.loops.pop()


def _while_gap(interp, stmt: n.While, scope, why: Unknown) -> None:
    for name in assigned_names(stmt.body):
        scope.set(name, Unknown(f"set in the while loop of line {stmt.line}, whose bound odelab cannot know",
                                stmt.line, scope.file), interp.globals)
    detail = (f"a while loop with a data-dependent bound ({why.reason}): odelab cannot unroll it; an [events] table "
              "with a `reset` and `max_events` expresses a restart loop")
    if scope.mode == "script" and not _solver_calls([stmt.body]):
        interp.note(stmt.line, stmt.text, IGNORED, f"not read: {detail}", scope.file)
    else:
        interp.note(stmt.line, stmt.text, "gap", detail, scope.file)


__all__ += ["ExperimentError"]
