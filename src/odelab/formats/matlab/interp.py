"""Reading a MATLAB file's meaning without running it: statements and expressions evaluated on symbolic values.

The interpreter walks the syntax tree as MATLAB would run it, but every value is a
:mod:`~.values` value: numbers it can know (a script's constants, ``linspace``, a data table
odelab can read), and expressions of the time and the states when it reads a right-hand side.
Nothing is executed: a call is either a function of the file (or of a file beside it), read
the same way, or one of the built-ins of :mod:`.builtins`, each of which computes on these values or
says why it cannot. ``eval``, ``system`` and their kind are refused outright.

- Constants assigned to a name once become parameters (``k = 3`` -> ``[parameters] k = 3``);
- an ``if`` whose condition depends on the state is read both ways and joined with ``where``;
- a ``for`` loop with constant bounds is unrolled (within :data:`~.scope.MAX_ITERATIONS`);
- a value odelab cannot know (a file it cannot read, ``rand``, a solver's output) is an
  :class:`~.values.Unknown` carrying its line and reason: a gap only where a case needs it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from odelab.exceptions import ExperimentError
from odelab.formats.base import GAP, IGNORED
from odelab.formats.matlab import nodes as n
from odelab.formats.matlab import ops
from odelab.formats.matlab.flow import BreakLoop, ContinueLoop, ErrorCalled, Failure, ReturnNow, assigned_names
from odelab.formats.matlab.scope import MAX_CALL_DEPTH, Budget, Notes, Scope
from odelab.formats.matlab.values import (Arr, Cell, Const, FuncValue, Named, Op, Param, ParamDef, ResultRef,
                                          SolverOutput, State, Str, Struct, StructArray, Sym, TooBig, Unknown,
                                          Unsupported)

__all__ = ["Interpreter", "Hooks", "Failure", "ErrorCalled", "BreakLoop", "ContinueLoop", "ReturnNow", "assigned_names"]

MAX_PARAMETER_VECTOR = 12
"""A vector of at most this many constants assigned to a name gives each element a parameter (``p_1``...)."""


@dataclass(frozen=True)
class Hooks:
    """What the interpreter calls but does not import (:mod:`.machine` assembles them): the built-in
    functions, command syntax, the control-flow statements, the expression nodes, a solver's outputs."""

    builtins: dict
    command: Callable
    run_if: Callable
    run_switch: Callable
    run_for: Callable
    run_while: Callable
    expressions: dict
    index_result: Callable
    result_numbers: Callable


class Interpreter:
    """Evaluates one file (and the files beside it that it calls) on symbolic values.

    ``on_solver(interp, method, args, nargout, node, scope)`` is called for each ode45-family call
    (the translator records it as a case and returns its outputs).
    """

    def __init__(self, source: n.SourceFile, notes: Notes, hooks: "Hooks", *, loader=None, on_solver=None,
                 pinned: dict[str, Any] | None = None):
        self.hooks = hooks
        self.source = source
        self.notes = notes
        self.loader = loader  # loader(name) -> SourceFile of `name.m` beside the file, or None
        self.on_solver = on_solver
        self.pinned = dict(pinned or {})
        self.globals: dict[str, Any] = {}
        self.budget = Budget()
        self.stack: list[n.Function] = []
        self.loops: list[dict] = []  # the loops being unrolled, innermost last
        self.inputs: dict[str, Any] = {}  # interp1 tables as inputs, by name
        self.state_vector: Arr | None = None  # the symbolic y while a right-hand side is read
        self.state_names: dict[int, tuple[str, int]] = {}  # state index -> (name, line): `S = y(1)`
        self.state_base = ""  # the function's own name for the state vector
        self.state_base_from_function = False
        self.decic_calls: list = []  # (function, fixed_y0, fixed_yp0, line) of each decic call
        self.assign_log: list = []  # while a right-hand side is read: (function, name, position or None, line)
        self.builtins = hooks.builtins
        self.solved = 0

    @property
    def src(self) -> str:
        return self.source.path

    # --- notes and failures -------------------------------------------------------------------
    def note(self, line: int, construct: str, outcome: str, detail: str, file: str = "") -> None:
        self.notes.add(line, construct, outcome, detail, Path(file or self.src).name)

    def unknown_from(self, exc: Exception, line: int, scope: Scope, construct: str = "") -> Unknown:
        reason = str(exc) if str(exc) else type(exc).__name__
        return Unknown(reason, line, scope.file, construct)

    # --- statements -------------------------------------------------------------------------------
    def run_block(self, body: list[n.Stmt], scope: Scope) -> None:
        for stmt in body:
            self.budget.statement(stmt.line, scope.file)
            self.run_statement(stmt, scope)

    def run_statement(self, stmt: n.Stmt, scope: Scope) -> None:
        handler = _STATEMENTS.get(type(stmt))
        try:
            handler(self, stmt, scope)
        except (Unsupported, TooBig, Failure) as exc:
            self.fail_statement(stmt, scope, exc)

    def fail_statement(self, stmt: n.Stmt, scope: Scope, exc: Exception) -> None:
        unknown = self.unknown_from(exc, stmt.line, scope, stmt.text)
        for name in assigned_names([stmt]):
            scope.set(name, unknown, self.globals)
        if scope.mode == "script" and not assigned_names([stmt]):
            self.note(stmt.line, stmt.text, IGNORED, f"not read: {unknown.reason}", scope.file)

    def stmt_assign(self, stmt: n.Assign, scope: Scope) -> None:
        if stmt.multi:
            slots = [self.brace_positions(t, scope) for t in stmt.targets]
            nargout = sum(len(p) if p is not None else 1 for p in slots)
            values = self.eval_multi(stmt.value, scope, nargout)
        else:
            slots = [None]
            values = [self.eval(stmt.value, scope)]
        k = 0
        for target, positions in zip(stmt.targets, slots):
            if positions is not None:  # [varargout{1:3}] = ...: one output per cell
                for position in positions:
                    if k < len(values):
                        self.assign_cell_at(target, position, values[k], scope, stmt.line)
                    k += 1
                continue
            if k >= len(values):
                break
            if not isinstance(target, n.Tilde):
                self.assign(target, values[k], scope, stmt.line)
            k += 1

    def brace_positions(self, target: n.Expr, scope: Scope) -> list[int] | None:
        """The cells ``c{1:3}`` names as outputs of a multiple assignment (None: not a brace target)."""
        if not (isinstance(target, n.Index) and target.brace and isinstance(target.target, n.Id)):
            return None
        current = scope.get(target.target.name, self.globals)
        size = len(current.items) if isinstance(current, Cell) else 0
        specs = self.index_specs(target.args, Arr(1, size, data=np.zeros((1, size))), scope)
        if len(specs) != 1 or specs[0] is ops.COLON or specs[0].numbers() is None:
            raise Unsupported("only c{k} and c{1:n} are translated as outputs")
        return [int(v) for v in specs[0].numbers().reshape(-1)]

    def assign_cell_at(self, target: n.Index, position: int, value: Any, scope: Scope, line: int) -> None:
        name = target.target.name
        current = scope.get(name, self.globals)
        items = list(current.items) if isinstance(current, Cell) else []
        if position < 1:
            raise Unsupported("a cell index must be 1 or more")
        items += [Arr(0, 0, data=np.zeros((0, 0)))] * max(0, position - len(items))
        items[position - 1] = value
        scope.set(name, Cell(1, len(items), items), self.globals)
        scope.assigned.add(name)

    def stmt_expr(self, stmt: n.ExprStmt, scope: Scope) -> None:
        expr = stmt.expr
        if isinstance(expr, (n.Id, n.Index)) and self._is_call(expr, scope):
            self.eval_multi(expr, scope, 0)
            return
        self.eval(expr, scope)  # a value shown in the Command Window: nothing to translate

    def stmt_command(self, stmt: n.Command, scope: Scope) -> None:
        self.hooks.command(self, stmt, scope)

    def stmt_global(self, stmt: n.Global, scope: Scope) -> None:
        if stmt.persistent:
            for name in stmt.names:
                if not scope.has(name, self.globals):
                    scope.set(name, Arr(0, 0, data=np.zeros((0, 0))), self.globals)
            return
        for name in stmt.names:
            scope.globals.add(name)
            if name not in self.globals:
                self.globals[name] = Arr(0, 0, data=np.zeros((0, 0)))  # MATLAB's new global is []

    def stmt_if(self, stmt: n.If, scope: Scope) -> None:
        self.hooks.run_if(self, stmt, scope)

    def stmt_switch(self, stmt: n.Switch, scope: Scope) -> None:
        self.hooks.run_switch(self, stmt, scope)

    def stmt_for(self, stmt: n.For, scope: Scope) -> None:
        self.hooks.run_for(self, stmt, scope)

    def stmt_while(self, stmt: n.While, scope: Scope) -> None:
        self.hooks.run_while(self, stmt, scope)

    def stmt_arguments(self, stmt: n.Arguments, scope: Scope) -> None:
        """An arguments block: each default where the caller gave no value (``options.Vm0 = NaN``)."""
        for target, default in stmt.entries:
            if default is None:
                continue
            base = target
            while isinstance(base, (n.Field, n.Index)):
                base = base.target
            if not isinstance(base, n.Id):
                continue
            current = scope.get(base.name, self.globals) if scope.has(base.name, self.globals) else None
            if isinstance(current, Unknown):  # not passed by the caller: the default applies
                scope.vars.pop(base.name, None)
                current = None
            if isinstance(target, n.Id) and current is not None:
                continue
            if isinstance(target, n.Field) and isinstance(current, Struct) and target.name in current.fields:
                continue
            self.assign(target, self.eval(default, scope), scope, stmt.line)

    def stmt_try(self, stmt: n.TryCatch, scope: Scope) -> None:
        self.run_block(stmt.body, scope)

    def stmt_break(self, stmt, scope):
        raise BreakLoop()

    def stmt_continue(self, stmt, scope):
        raise ContinueLoop()

    def stmt_return(self, stmt, scope):
        raise ReturnNow()

    # --- assignment ---------------------------------------------------------------------------------
    def assign(self, target: n.Expr, value: Any, scope: Scope, line: int) -> None:
        if isinstance(target, n.Id):
            self.bind(target.name, value, scope, line)
            return
        base_node = target.target
        current = self.lvalue(base_node, scope)
        if isinstance(current, Unknown):
            return  # `fig.UserData = ...` on a figure odelab does not draw
        if isinstance(target, n.Field) or isinstance(target, n.DynField):
            name = target.name if isinstance(target, n.Field) else self.field_name(target.name, scope)
            if current is None or (isinstance(current, Arr) and current.size == 0):
                current = Struct(origin=self.path_name(base_node))
            if not isinstance(current, Struct):
                raise Unsupported(f"`{self.path_name(base_node)}` is not a struct; its field `{name}` cannot be set")
            fields = dict(current.fields)
            fields[name] = self.named_value(f"{current.origin or self.path_name(base_node)}_{name}", value, scope,
                                            line, first=name not in current.fields)
            new = Struct(fields, origin=current.origin or self.path_name(base_node), odeset=current.odeset)
        elif target.brace:
            new = self.assign_cell(current, target, value, scope)
        elif isinstance(value, Struct) or isinstance(current, StructArray):
            new = self.assign_struct_element(current, target, value, scope, base_node)
        else:
            if isinstance(current, Cell):
                raise Unsupported("assigning to a cell array with () is not translated; use {}")
            if current is not None and not isinstance(current, Arr):
                raise Unsupported(f"`{self.path_name(base_node)}` cannot be indexed")
            if not isinstance(value, Arr):
                raise Unsupported(self.why_not_number(value))
            specs = self.index_specs(target.args, current if current is not None else
                                     Arr(0, 0, data=np.zeros((0, 0))), scope)
            new = ops.assign_index(current, specs, value)
            if self.state_vector is not None and isinstance(base_node, n.Id):
                self.assign_log.append((scope.function, base_node.name, _position(specs), line))
        self.assign(base_node, new, scope, line) if not isinstance(base_node, n.Id) else \
            scope.set(base_node.name, new, self.globals)
        if isinstance(base_node, n.Id):
            scope.assigned.add(base_node.name)

    def assign_struct_element(self, current, target: n.Index, value: Any, scope: Scope, base_node) -> StructArray:
        """``pars(2) = s`` and ``pars(2).beta = 0.5``: an element of a struct array (grown with empty structs)."""
        if not isinstance(value, Struct):
            raise Unsupported("a struct array's element must be a struct")
        if isinstance(current, Struct):
            current = StructArray([current], origin=current.origin)
        elif current is None or (isinstance(current, Arr) and current.size == 0):
            current = StructArray([], origin=self.path_name(base_node))
        if not isinstance(current, StructArray):
            raise Unsupported(f"`{self.path_name(base_node)}` is not a struct array")
        k = self.struct_position(target, len(current.items), scope)
        items = list(current.items) + [Struct(origin=current.origin) for _ in range(max(0, k + 1 - len(current.items)))]
        items[k] = value
        return StructArray(items, origin=current.origin)

    def struct_position(self, node: n.Index, size: int, scope: Scope) -> int:
        specs = self.index_specs(node.args, Arr(1, size, data=np.zeros((1, size))), scope)
        numbers = [s.numbers() for s in specs if s is not ops.COLON]
        if len(numbers) != len(specs) or any(v is None or v.size != 1 for v in numbers) or \
                (len(numbers) == 2 and numbers[0][0, 0] != 1):
            raise Unsupported("a struct array is translated with one constant index (pars(2).beta)")
        k = int(numbers[-1][0, 0])
        if k < 1:
            raise Unsupported("a struct array's index must be 1 or more")
        return k - 1

    def assign_cell(self, current, target: n.Index, value: Any, scope: Scope) -> Cell:
        """``c{k} = value``: a new cell array."""
        if current is not None and not isinstance(current, Cell) and not (isinstance(current, Arr) and current.size == 0):
            raise Unsupported("`{}` assigns to a cell array")
        items = list(current.items) if isinstance(current, Cell) else []
        specs = self.index_specs(target.args, Arr(1, len(items), data=np.zeros((1, len(items)))), scope)
        if len(specs) != 1 or specs[0] is ops.COLON or specs[0].size != 1 or specs[0].numbers() is None:
            raise Unsupported("only `c{k} = value` is translated for cell arrays")
        k = int(specs[0].numbers()[0, 0])
        if k < 1:
            raise Unsupported("a cell index must be 1 or more")
        items += [Arr(0, 0, data=np.zeros((0, 0)))] * max(0, k - len(items))
        items[k - 1] = value
        return Cell(1, len(items), items)

    def bind(self, name: str, value: Any, scope: Scope, line: int) -> None:
        """``name = value``: a constant's first assignment outside loops and branches names a parameter."""
        if scope.mode == "script" and scope.parent is None and name in self.pinned and scope.function is None:
            self.note(line, f"{name} = ...", IGNORED, f"set by --set {name}=...", scope.file)
            value = self.pinned[name]
        else:
            first = name not in scope.assigned and not scope.has(name, self.globals)
            value = self.named_value(name, value, scope, line, first=first)
        scope.set(name, value, self.globals)
        scope.assigned.add(name)
        if self.state_vector is not None:
            self.assign_log.append((scope.function, name, None, line))
        if isinstance(value, Arr) and value.size == 1 and scope.mode == "rhs" and value.items is not None:
            item = value.items[0]
            if isinstance(item, State) and item.index not in self.state_names:
                self.state_names[item.index] = (name, line)

    def named_value(self, name: str, value: Any, scope: Scope, line: int, *, first: bool) -> Any:
        if isinstance(value, Struct) and not value.origin:
            return Struct(value.fields, origin=name, odeset=value.odeset)
        if not isinstance(value, Arr) or value.size == 0:
            return value
        fresh = first and scope.loop_depth == 0 and scope.branch_depth == 0
        # in a script, a constant a loop (or a later line) assigns again is a parameter too: the cases that use
        # each value differ in that parameter only (a [[case]] each)
        in_script_loop = scope.mode == "script" and (scope.loop_depth > 0 or not first) and scope.branch_depth == 0
        if value.size == 1:
            item = value.item(0)
            if item.num is None or any(isinstance(leaf, ResultRef) for leaf in item.leaves()):
                return value
            if in_script_loop:  # a value each pass of a loop changes (a parameter study): a parameter of its own
                return Arr.scalar(Param(ParamDef(name, Const(item.num), line, scope.file)))
            if isinstance(item, (Param, Named)):
                return value
            if fresh:
                out = Arr.scalar(Param(ParamDef(name, item, line, scope.file)))
                out.logical = value.logical
                return out
            if item.size > 24:
                return Arr.scalar(Const(item.num))  # a constant recomputed in a loop: its value, not its history
            return value
        if fresh and value.size <= MAX_PARAMETER_VECTOR and (value.rows == 1 or value.cols == 1) \
                and not value.is_char and value.source is None and value.data is not None:
            items = [Param(ParamDef(f"{name}_{k + 1}", item, line, scope.file))
                     for k, item in enumerate(value.all_items())]
            return Arr(value.rows, value.cols, items=items, colon=value.colon)
        return value

    def lvalue(self, node: n.Expr, scope: Scope) -> Any:
        """The current value of an assignment target's base, or None when it does not exist yet."""
        if isinstance(node, n.Id):
            return scope.get(node.name, self.globals)
        if isinstance(node, n.Field):
            base = self.lvalue(node.target, scope)
            if isinstance(base, Unknown):
                return base
            if isinstance(base, Struct):
                return base.fields.get(node.name)
            return None
        if isinstance(node, n.Index):
            base = self.lvalue(node.target, scope)
            if base is None or isinstance(base, Unknown):
                return base
            if isinstance(base, (Struct, StructArray)) and not node.brace:  # an element not there yet is new
                items = base.items if isinstance(base, StructArray) else [base]
                k = self.struct_position(node, len(items), scope)
                return items[k] if k < len(items) else None
            return self.index_value(base, node, scope)
        raise Unsupported("an assignment to this kind of target is not translated")

    def path_name(self, node: n.Expr) -> str:
        if isinstance(node, n.Id):
            return node.name
        if isinstance(node, n.Field):
            return f"{self.path_name(node.target)}_{node.name}"
        if isinstance(node, (n.Index, n.DynField)):
            return self.path_name(node.target)
        return "value"

    def field_name(self, node: n.Expr, scope: Scope) -> str:
        value = self.eval(node, scope)
        if not isinstance(value, Str):
            raise Unsupported("a dynamic field name that is not a constant string")
        return value.text

    # --- expressions --------------------------------------------------------------------------------
    def eval(self, node: n.Expr, scope: Scope) -> Any:
        """One value (a call's first output)."""
        if isinstance(node, (n.Id, n.Index)) and not (isinstance(node, n.Index) and node.brace):
            values = self.eval_multi(node, scope, 1)
            if not values:
                raise Unsupported(f"`{_shown(node)}` returns no value")
            return values[0]
        method = self.hooks.expressions.get(type(node))
        if method is None:
            raise Unsupported(f"{type(node).__name__} is not translated")
        return method(self, node, scope)

    def eval_multi(self, node: n.Expr, scope: Scope, nargout: int) -> list:
        """A call's outputs (``nargout`` of them; 0 for a statement), or an indexed variable's value."""
        if isinstance(node, n.Id):
            name = node.name
            if scope.has(name, self.globals):
                return [scope.get(name, self.globals)]
            return self.call_named(name, [], nargout, node, scope)
        if isinstance(node, n.Index):
            if isinstance(node.target, n.Id) and not scope.has(node.target.name, self.globals):
                args = self.eval_args(node.args, scope)
                return self.call_named(node.target.name, args, nargout, node, scope)
            base = self.eval(node.target, scope)
            if isinstance(base, FuncValue) and not node.brace:
                return self.call_value(base, self.eval_args(node.args, scope), nargout, node.line)
            return self.index_value(base, node, scope, multi=True)
        return [self.eval(node, scope)]

    def _is_call(self, node: n.Expr, scope: Scope) -> bool:
        target = node.target if isinstance(node, n.Index) else node
        return isinstance(target, n.Id) and not scope.has(target.name, self.globals)

    def eval_args(self, args: list[n.Expr], scope: Scope) -> list:
        out = []
        for arg in args:
            if isinstance(arg, n.Index) and arg.brace:  # c{:} expands to a list of arguments
                out.extend(self.index_value(self.eval(arg.target, scope), arg, scope, multi=True))
            else:
                out.append(self.eval(arg, scope))
        return out

    def index_value(self, base: Any, node: n.Index, scope: Scope, multi: bool = False) -> Any:
        if isinstance(base, Unknown):
            return [base] if multi else base
        if isinstance(base, SolverOutput):
            value = self.hooks.index_result(self, base, node, scope)
            return [value] if multi else value
        if isinstance(base, Cell):
            shape = Arr(base.rows, base.cols, data=np.zeros((base.rows, base.cols)))
            specs = self.index_specs(node.args, shape, scope)
            positions = ops.index(Arr(base.rows, base.cols, data=np.arange(len(base.items), dtype=float)
                                      .reshape(base.cols, base.rows).T), specs)
            picked = [base.items[int(k)] for k in positions.numbers().T.reshape(-1)]
            if node.brace:
                return picked if multi else (picked[0] if len(picked) == 1 else Cell(1, len(picked), picked))
            value = Cell(positions.rows, positions.cols, picked)
            return [value] if multi else value
        if isinstance(base, Str):
            base = _char_array(base)
        if isinstance(base, Struct):
            base = StructArray([base], origin=base.origin)
        if isinstance(base, StructArray):
            k = self.struct_position(node, len(base.items), scope)
            if k >= len(base.items):
                raise Unsupported(f"index {k + 1} is beyond the {len(base.items)} elements of the struct array")
            return [base.items[k]] if multi else base.items[k]
        if not isinstance(base, Arr):
            raise Unsupported(self.why_not_number(base))
        if node.brace:
            raise Unsupported("`{}` indexes a cell array; this is a number array")
        specs = self.index_specs(node.args, base, scope)
        value = ops.index(base, specs)
        if base.source is not None and len(specs) == 2 and specs[0] is ops.COLON and isinstance(specs[1], Arr) \
                and specs[1].size == 1:
            value.source = (base.source[0], int(specs[1].scalar_value()) - 1, base.source[2], base.source[3])
        return [value] if multi else value

    def index_specs(self, args: list[n.Expr], base: Arr, scope: Scope) -> list:
        specs = []
        for k, arg in enumerate(args):
            if isinstance(arg, n.Colon):
                specs.append(ops.COLON)
                continue
            extent = base.size if len(args) == 1 else (base.rows if k == 0 else base.cols if k == 1 else 1)
            scope.end_stack.append(extent)
            try:
                value = self.eval(arg, scope)
            finally:
                scope.end_stack.pop()
            if isinstance(value, Str) and value.text == ":":
                specs.append(ops.COLON)
                continue
            if not isinstance(value, Arr):
                raise Unsupported(self.why_not_number(value, "an index"))
            specs.append(value)
        return specs

    def why_not_number(self, value: Any, what: str = "a number") -> str:
        if isinstance(value, Unknown):
            return value.reason
        if isinstance(value, SolverOutput):
            return "a solver's output is used as " + what + " (odelab stores and plots it instead)"
        if isinstance(value, FuncValue):
            return f"a function handle is used as {what}"
        if isinstance(value, Str):
            return f"the text {value.text!r} is used as {what}"
        if isinstance(value, Struct):
            return f"a struct is used as {what}"
        if isinstance(value, Cell):
            return f"a cell array is used as {what}"
        return f"this value cannot be used as {what}"

    def numeric(self, value: Any, what: str = "a number") -> Arr:
        if isinstance(value, Str):
            return _char_array(value)
        if isinstance(value, SolverOutput):
            numbers = self.hooks.result_numbers(value)
            if numbers is not None:
                return numbers
        if not isinstance(value, Arr):
            raise Unsupported(self.why_not_number(value, what))
        return value

    # --- calls ------------------------------------------------------------------------------------------
    def find_function(self, name: str, scope: Scope):
        """A function the caller can see: nested in the current function or its parents, local to its file,
        or the main function of ``name.m`` beside the file. Returns (Function or SourceFile script, file)."""
        fn = scope.function
        while fn is not None:
            for nested in fn.nested:
                if nested.name == name:
                    return nested
            if fn.name == name and fn.parent is not None:
                return fn
            fn = fn.parent
        source = self.file_of(scope.file)
        if source is not None:
            for local in source.functions:
                if local.name == name:
                    return local
                for nested in local.nested:
                    if nested.name == name and scope.function is not None and _within(scope.function, local):
                        return nested
        if self.loader is not None and name not in self.builtins:
            other = self.loader(name)
            if other is not None:
                return other.main if other.script is None else other
        return None

    def file_of(self, path: str):
        if path == self.src:
            return self.source
        if self.loader is not None:
            return self.loader(Path(path).stem)
        return None

    def call_named(self, name: str, args: list, nargout: int, node: n.Expr, scope: Scope) -> list:
        found = self.find_function(name, scope)
        if found is not None:
            if isinstance(found, n.SourceFile):
                return self.run_script_file(found, scope, node.line)
            return self.call_function(found, args, nargout, node.line, scope)
        handler = self.builtins.get(name)
        if handler is None:
            return self.unknown_function(name, node, scope)
        return self.call_builtin(handler, name, args, nargout, node, scope)

    def call_builtin(self, handler, name: str, args: list, nargout: int, node: n.Expr, scope: Scope) -> list:
        """A built-in's outputs; a built-in that fails on arguments it was not written for is a gap, not a crash."""
        try:
            return handler(self, args, nargout, node, scope)
        except (Unsupported, TooBig, ExperimentError, ErrorCalled, Failure):
            raise
        except (TypeError, ValueError, IndexError, KeyError, AttributeError, ArithmeticError,
                np.linalg.LinAlgError) as exc:
            raise Unsupported(f"`{name}` with these arguments is not translated ({type(exc).__name__})") from None

    def unknown_function(self, name: str, node: n.Expr, scope: Scope) -> list:
        reason = (f"`{name}` is neither a MATLAB function odelab translates nor a function of this file or of a "
                  f"file beside it ({name}.m)")
        if scope.mode == "script":
            self.note(node.line, _shown(node), IGNORED, f"not run: {reason}", scope.file)
        return [Unknown(reason, node.line, scope.file, _shown(node))]

    def run_script_file(self, script: n.SourceFile, scope: Scope, line: int) -> list:
        """A script called by name runs in the caller's workspace (MATLAB's rule)."""
        if len(self.stack) >= MAX_CALL_DEPTH:
            raise ExperimentError(f"line {line}: scripts and functions call each other more than {MAX_CALL_DEPTH} "
                                  "deep.", source=scope.file)
        if any(getattr(f, "file", None) == script.path and f.name == "<script>" for f in self.stack):
            raise ExperimentError(f"line {line}: the script {Path(script.path).name} runs itself; odelab does not "
                                  "translate recursion.", source=scope.file)
        marker = n.Function(name="<script>", inputs=[], outputs=[], body=[], line=line, file=script.path)
        self.stack.append(marker)
        saved = scope.file
        scope.file = script.path
        try:
            self.run_block(script.script or [], scope)
        finally:
            scope.file = saved
            self.stack.pop()
        return []

    def call_function(self, fn: n.Function, args: list, nargout: int, line: int, caller: Scope,
                      parent: Scope | None = None, mode: str | None = None) -> list:
        if any(f is fn for f in self.stack):
            raise ExperimentError(f"line {line}: function `{fn.name}` calls itself (recursion); odelab reads ODE "
                                  "code without running it and does not translate recursive functions. Write the "
                                  "experiment file by hand.", source=caller.file)
        if len(self.stack) >= MAX_CALL_DEPTH:
            raise ExperimentError(f"line {line}: functions call each other more than {MAX_CALL_DEPTH} deep.",
                                  source=caller.file)
        if len(args) > len(fn.inputs) and not (fn.inputs and fn.inputs[-1] == "varargin"):
            raise Unsupported(f"`{fn.name}` takes {len(fn.inputs)} inputs; it is called with {len(args)}")
        if parent is None and fn.parent is not None:
            parent = self._parent_scope(fn, caller)
        scope = Scope(fn.file or caller.file, function=fn, parent=parent, mode=mode or caller.mode,
                      nargin=len(args), nargout=nargout)
        self.note_state_vector(fn.inputs, args, True)
        for k, name in enumerate(fn.inputs):
            if name == "varargin" and k == len(fn.inputs) - 1:
                rest = args[k:]
                scope.vars[name] = Cell(1, len(rest), list(rest))
                break
            if k < len(args) and name != "~":
                scope.vars[name] = args[k]
                scope.assigned.add(name)
        self.stack.append(fn)
        try:
            self.run_block(fn.body, scope)
        except ReturnNow:
            pass
        finally:
            self.stack.pop()
        self.last_scope = scope
        return self.outputs(fn, scope, nargout, line)

    def run_driver_function(self, fn: n.Function, caller: Scope) -> list:
        """A driver function file (``function msd_demo(m)``) run as MATLAB runs it with no arguments; an input the
        file does not give a default is --set's value, else unknown (a gap where a case needs it)."""
        scope = Scope(fn.file or caller.file, function=fn, mode="script", nargin=0, nargout=0)
        for name in fn.inputs:
            if name in self.pinned:
                scope.vars[name] = self.pinned[name]
                scope.assigned.add(name)
        self.stack.append(fn)
        missing = [name for name in fn.inputs if name not in scope.vars and name not in ("~", "varargin")]
        for name in missing:
            scope.vars[name] = Unknown(f"`{name}` is an input of {fn.name}({', '.join(fn.inputs)}) that the file does "
                                       f"not set when called with none: give it with --set {name}=VALUE", fn.line,
                                       scope.file)
        try:
            self.run_block(fn.body, scope)
        except ReturnNow:
            pass
        finally:
            self.stack.pop()
        return []

    def note_state_vector(self, names: list[str], args: list, named_function: bool) -> None:
        """The first function that receives the state vector names it (`function dx = f(t, x)`: x1, x2...)."""
        if self.state_vector is None or (self.state_base and (self.state_base_from_function or not named_function)):
            return
        for name, arg in zip(names, args):
            if arg is self.state_vector and name not in ("~", "varargin"):
                self.state_base = name
                self.state_base_from_function = named_function
                return

    def _parent_scope(self, fn: n.Function, caller: Scope) -> Scope | None:
        scope: Scope | None = caller
        while scope is not None:
            if scope.function is fn.parent:
                return scope
            scope = scope.parent
        return None

    def outputs(self, fn: n.Function, scope: Scope, nargout: int, line: int) -> list:
        out = []
        for name in fn.outputs:
            if len(out) >= max(nargout, 1):
                break
            if name == "varargout":
                value = scope.vars.get(name)
                if isinstance(value, Cell):
                    out.extend(value.items[:max(nargout, 1) - len(out)])
                continue
            if name in scope.vars or name in scope.globals:
                out.append(scope.get(name, self.globals))
            else:
                out.append(Unknown(f"`{fn.name}` does not set its output `{name}`", fn.line, scope.file))
        return out

    def call_value(self, fv: FuncValue, args: list, nargout: int, line: int, mode: str | None = None) -> list:
        """Call a function handle with these arguments."""
        if fv.params is not None:
            return self.call_anonymous(fv, args, nargout, line, mode)
        owner = fv.closure if isinstance(fv.closure, Scope) else Scope(fv.file or self.src, mode=mode or "rhs")
        found = self.find_function(fv.name, owner)
        if found is not None and not isinstance(found, n.SourceFile):
            parent = fv.closure if (found.parent is not None and isinstance(fv.closure, Scope)) else None
            return self.call_function(found, args, nargout, line, owner, parent=parent, mode=mode)
        handler = self.builtins.get(fv.name)
        if handler is None:
            raise Unsupported(f"the function `{fv.name}` is not in this file nor beside it ({fv.name}.m)")
        node = n.Id(line, fv.name)
        return self.call_builtin(handler, fv.name, args, nargout, node, owner)

    def call_anonymous(self, fv: FuncValue, args: list, nargout: int, line: int, mode: str | None) -> list:
        if len(self.stack) >= MAX_CALL_DEPTH:
            raise ExperimentError(f"line {line}: functions call each other more than {MAX_CALL_DEPTH} deep.",
                                  source=fv.file or self.src)
        captured: Scope = fv.closure
        scope = Scope(captured.file, function=captured.function, parent=None, mode=mode or captured.mode,
                      nargin=len(args), nargout=nargout)
        scope.vars = dict(captured.vars)
        scope.assigned = set(scope.vars)
        if len(args) > len(fv.params) and not (fv.params and fv.params[-1] == "varargin"):
            raise Unsupported(f"the anonymous function `{fv.text}` takes {len(fv.params)} inputs; it is called "
                              f"with {len(args)}")
        self.note_state_vector(fv.params, args, False)
        for k, name in enumerate(fv.params):
            if name == "varargin":
                scope.vars[name] = Cell(1, len(args[k:]), list(args[k:]))
                break
            if k < len(args) and name != "~":
                scope.vars[name] = args[k]
        marker = n.Function(name=f"@({', '.join(fv.params)})", inputs=fv.params, outputs=[], body=[],
                            line=fv.line, file=captured.file)
        self.stack.append(marker)
        try:
            return self.eval_multi(fv.body, scope, nargout)
        finally:
            self.stack.pop()


def _position(specs: list) -> int | None:
    """The 0-based element an index names, when it names one of a vector (``dy(2)``, ``dy(2,1)``, ``dy(2,:)``)."""
    numbers = [s.numbers() if s is not ops.COLON else None for s in specs]
    if len(specs) == 1 and numbers[0] is not None and numbers[0].size == 1:
        return int(numbers[0][0, 0]) - 1
    if len(specs) == 2 and numbers[0] is not None and numbers[0].size == 1 and (
            specs[1] is ops.COLON or (numbers[1] is not None and numbers[1].size == 1 and numbers[1][0, 0] == 1)):
        return int(numbers[0][0, 0]) - 1
    return None


def _within(fn: n.Function, outer: n.Function) -> bool:
    while fn is not None:
        if fn is outer:
            return True
        fn = fn.parent
    return False


def _shown(node: n.Expr) -> str:
    if isinstance(node, n.Index) and isinstance(node.target, n.Id):
        return f"{node.target.name}(...)"
    if isinstance(node, n.Id):
        return node.name
    return type(node).__name__


def _char_array(value: Str) -> Arr:
    out = Arr.numeric([[float(ord(c)) for c in value.text]] if value.text else np.zeros((1, 0)))
    out.is_char = True
    return out


_STATEMENTS = {
    n.Assign: Interpreter.stmt_assign, n.ExprStmt: Interpreter.stmt_expr, n.Command: Interpreter.stmt_command,
    n.Global: Interpreter.stmt_global, n.If: Interpreter.stmt_if, n.Switch: Interpreter.stmt_switch,
    n.For: Interpreter.stmt_for, n.While: Interpreter.stmt_while, n.TryCatch: Interpreter.stmt_try,
    n.Arguments: Interpreter.stmt_arguments,
    n.Break: Interpreter.stmt_break, n.Continue: Interpreter.stmt_continue, n.Return: Interpreter.stmt_return,
}
