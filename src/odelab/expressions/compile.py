"""Turning parsed expressions into fast numpy functions: the emitter,
:func:`compile_expression`, :func:`compile_vector` and :class:`CompiledExpression`."""

from __future__ import annotations

import ast
import copy
import keyword
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from odelab.exceptions import ExpressionError, InputError
from odelab.expressions.functions import (
    _BINARY,
    _COMPARATORS,
    _FAST_ERRSTATE,
    _UNARY,
    CONSTANTS,
    FUNCTIONS,
    _namespace,
    constant_values,
    shadowed_constants,
)
from odelab.expressions.parse import (
    DER,
    LAG,
    ParsedExpression,
    _did_you_mean,
    _too_deep_message,
    is_dotted_name,
    parse_expression,
    python_name,
)

# --------------------------------------------------------------------------------------------
# Compilation
# --------------------------------------------------------------------------------------------


def _unknown_name_error(
    parsed: ParsedExpression, known: Sequence[str], key: str | None, source: str | None
) -> ExpressionError | None:
    known_set = set(known)
    for name, offset in parsed._occurrences:
        if name in known_set:
            continue
        if "." in name and not any("." in k for k in known):  # only networks have dotted names
            return ExpressionError("attribute access (`.`) is not allowed in expressions",
                                   expression=parsed.text, column=parsed.column(offset), source=source, key=key)
        constants = constant_values(known)
        hint = _did_you_mean(name, [*known, *constants])
        listed = [*known, *constants]
        if len(listed) > 40:
            listed = [*listed[:40], f"... ({len(listed) - 40} more)"]
        message = f"unknown name `{name}`; " + (f"{hint} " if hint else "")
        if known:
            message += f"{'K' if hint else 'k'}nown names: {', '.join(listed)}"
        else:
            message += "no names are available here, only the constants pi and e"
        return ExpressionError(
            message, expression=parsed.text, column=parsed.column(offset), source=source, key=key
        )
    return None


def _lag_error(parsed: ParsedExpression, key: str | None, source: str | None) -> ExpressionError | None:
    """``lag(x, tau)`` outside [system.equations] (which rewrites it before compiling: systems/delay.py),
    and ``der(x)`` outside [system.residuals] (systems/implicit.py rewrites it)."""
    for node in ast.walk(parsed.tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == DER:
            return ExpressionError(
                "`der(x)` (a state's derivative) is allowed in [system.residuals] of a system with kind = "
                "\"implicit\" only, where ode15i solves F(t, x, x') = 0; in [system.equations] the derivative is "
                "the equation's left side",
                expression=parsed.text, column=parsed.column(node.col_offset), source=source, key=key)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == LAG:
            return ExpressionError(
                "`lag(x, tau)` (a delayed state) is allowed in [system.equations] only, where dde23 solves the "
                "delay equations; elsewhere write the value itself",
                expression=parsed.text, column=parsed.column(node.col_offset), source=source, key=key)
    return None


class _Emitter:
    """Python source for validated trees; numbers become np.float64 globals of the namespace."""

    def __init__(self, namespace: dict[str, Any], complex_step: bool, shadowed: frozenset[str] = frozenset()):
        self.namespace = namespace
        self.complex_step = complex_step
        self.shadowed = shadowed  # constants that a bound name shadows: variables here
        self._pool: dict[str, str] = {}

    def literals(self) -> dict:
        """The numbers this emitter pooled into the namespace (``_k0``, ``_k1``...)."""
        return {name: self.namespace[name] for name in self._pool.values()}

    def number(self, value: float) -> str:
        # np.float64 objects, not Python literals: `1/0` or `9.0**9.0**9.0` on Python floats
        # raise instead of giving inf, and Python would try to fold them at compile time
        label = repr(value)
        if label not in self._pool:
            name = f"_k{len(self._pool)}"
            self._pool[label] = name
            self.namespace[name] = np.float64(value)
        return self._pool[label]

    def expression(self, tree: ast.Expression) -> str:
        code: dict[int, str] = {}
        stack: list[tuple[ast.AST, bool]] = [(tree.body, False)]
        while stack:  # post-order without recursion: trees may be MAX_DEPTH deep
            node, ready = stack.pop()
            if not ready:
                stack.append((node, True))
                stack.extend((child, False) for child in _operands(node))
                continue
            code[id(node)] = self._node(node, [code[id(c)] for c in _operands(node)])
        return code[id(tree.body)]

    def _node(self, node: ast.AST, parts: list[str]) -> str:
        if isinstance(node, ast.Constant):
            try:
                return self.number(float(node.value))
            except OverflowError:  # an integer literal beyond the float range
                return self.number(math.inf)
        if isinstance(node, ast.Name):
            if node.id in CONSTANTS and node.id not in self.shadowed:
                return self.number(CONSTANTS[node.id])
            return node.id
        if isinstance(node, ast.Attribute):  # a dotted name, validated by the parser
            return python_name(f"{node.value.id}.{node.attr}")
        if isinstance(node, ast.BinOp):
            left, right = parts
            if self.complex_step and isinstance(node.op, ast.Pow):
                return f"_pow({left}, {right})"
            return f"({left} {_BINARY[type(node.op)]} {right})"
        if isinstance(node, ast.UnaryOp):
            return f"({_UNARY[type(node.op)]}{parts[0]})"
        if isinstance(node, ast.Compare):
            if len(node.ops) == 1 and not self.complex_step:
                return f"(({parts[0]} {_COMPARATORS[type(node.ops[0])][0]} {parts[1]}) * 1.0)"
            chain = [parts[0]]
            for op, part in zip(node.ops, parts[1:]):
                chain += [_COMPARATORS[type(op)][1], part]
            return f"_compare({', '.join(chain)})"
        if isinstance(node, ast.Call):
            return f"_f_{node.func.id}({', '.join(parts)})"
        raise AssertionError(f"unvalidated node {type(node).__name__}")  # pragma: no cover


def _operands(node: ast.AST) -> list[ast.AST]:
    if isinstance(node, ast.BinOp):
        return [node.left, node.right]
    if isinstance(node, ast.UnaryOp):
        return [node.operand]
    if isinstance(node, ast.Compare):
        return [node.left, *node.comparators]
    if isinstance(node, ast.Call):
        return list(node.args)
    return []


def _function_source(name: str, params: Sequence[str], body: list[str]) -> str:
    """A function that coerces its arguments and runs ``body`` with FP errors ignored."""
    params = [python_name(p) for p in params]
    inner = [f"{p} = _coerce({p})" for p in params] + body
    if _FAST_ERRSTATE is not None:
        lines = ["_token = _fp_set(_FP_IGNORE)", "try:"]
        lines += [f"    {line}" for line in inner]
        lines += ["finally:", "    _fp_reset(_token)"]
    else:  # pragma: no cover - numpy < 2
        lines = ["with _errstate(all='ignore'):", *(f"    {line}" for line in inner)]
    return f"def {name}({', '.join(params)}):\n" + "".join(f"    {line}\n" for line in lines)


def _define(source_code: str, name: str, namespace: dict[str, Any], error: Callable[[], Exception]):
    code = _CODE.get((source_code, name))
    if code is None:
        try:
            code = compile(source_code, f"<odelab {name}>", "exec")
        except (RecursionError, MemoryError):
            raise error() from None
        if len(_CODE) < _CODE_MAX:
            _CODE[(source_code, name)] = code
    exec(code, namespace)  # the source holds validated names, numbers and helpers only
    return namespace[name]


# Compiled code by generated source. Numbers live in the namespace (``_k0``), not in the
# source, so ``sin(t) + 2`` and ``sin(t) + 3`` in two files of a batch share one code object:
# Python's compile() was a fifth of loading a small experiment file. Code objects are immutable.
_CODE: dict[tuple[str, str], Any] = {}
_CODE_MAX = 4096


class CompiledExpression:
    """An expression compiled into a numpy function of its free names.

    Call it with keyword arguments, one per name (extra ones are ignored):
    ``f(x=1.0, v=np.linspace(0, 1, 5))``. Values broadcast like numpy arrays; the result is a
    numpy float (or complex, for the complex-step variant) or an array. Create it with
    :func:`compile_expression`.

    Attributes
    ----------
    text
        The expression as the user wrote it.
    names
        The free names the expression uses.
    source
        The generated Python source, for debugging.
    """

    __slots__ = ("text", "names", "source", "_params", "_function", "_complex")

    def __init__(self, text: str, params: tuple[str, ...], source: str, function: Callable,
                 complex_step: bool = False):
        self.text = text
        self.names = frozenset(params)
        self.source = source
        self._params = params
        self._function = function
        self._complex = complex_step

    def __reduce__(self):
        """Pickled as its text and names, compiled again where it is unpickled (a Dask worker)."""
        return _compiled_again, (self.text, self._params, self._complex)

    def __call__(self, **values: Any):
        try:
            args = [values[name] for name in self._params]
        except KeyError as exc:
            raise TypeError(f"missing a value for `{exc.args[0]}` in `{self.text}`") from None
        result = self._function(*args)
        if type(result) is np.ndarray and result.ndim == 0:
            return result[()]
        return result

    def __repr__(self) -> str:
        return f"CompiledExpression({self.text!r})"


def compile_expression(
    text: str | int | float | ParsedExpression,
    *,
    names: Iterable[str],
    key: str | None = None,
    source: str | None = None,
    complex_step: bool = False,
) -> CompiledExpression:
    """Compile an expression into a function of the names it uses.

    Parameters
    ----------
    text
        The expression (or a number, or a :class:`ParsedExpression`).
    names
        The names the expression may use (states, inputs, parameters, ``t``...). The constants
        ``pi`` and ``e`` are available unless one of these names shadows them.
    key, source
        Where the text came from, for error messages.
    complex_step
        Compile the variant for complex-step differentiation: arguments are complex, and
        ``Im f(x + ih)/h`` is the derivative even through ``abs``, ``min``, ``where``... (whose
        decisions use real parts).

    Returns
    -------
    CompiledExpression
        Call it as ``f(**values)``.

    Raises
    ------
    ExpressionError
        If the text is invalid or uses a name not in ``names`` (with a did-you-mean hint).
    """
    names = tuple(names)
    memo = (text, type(text), names, key, source, complex_step) if isinstance(text, (str, int, float)) else None
    if memo is not None:
        try:
            return _COMPILED[memo]
        except (KeyError, TypeError):  # TypeError: a name that cannot be hashed, checked below
            pass
    compiled = _compile_expression(text, names, key, source, complex_step)
    if memo is not None and len(_COMPILED) < _COMPILED_MAX:
        try:
            _COMPILED[memo] = compiled
        except TypeError:
            pass
    return compiled


# The cases of a sweep compile the same texts (parameters, [exact], times) over and over; a
# CompiledExpression holds no state, so each (text, names) is compiled once per process.
_COMPILED: dict[tuple, CompiledExpression] = {}
_COMPILED_MAX = 4096


def _compile_expression(text, names: tuple, key, source, complex_step: bool) -> CompiledExpression:
    parsed = parse_expression(text, key=key, source=source, names=names)
    key = parsed.key if key is None else key
    source = parsed.source if source is None else source
    known = list(dict.fromkeys(names))
    error = _lag_error(parsed, key, source) or _unknown_name_error(parsed, known, key, source)
    if error is not None:
        raise error
    namespace = _namespace(complex_step)
    body = _Emitter(namespace, complex_step, shadowed_constants(names)).expression(parsed.tree)
    params = tuple(name for name, _ in parsed._occurrences)
    source_code = _function_source("_odelab_expression", params, [f"return {body}"])
    function = _define(
        source_code,
        "_odelab_expression",
        namespace,
        lambda: ExpressionError(
            _too_deep_message(), expression=parsed.text, column=0, source=source, key=key
        ),
    )
    return CompiledExpression(parsed.text, params, source_code, function, complex_step)


def _compiled_again(text: str, params: tuple[str, ...], complex_step: bool) -> CompiledExpression:
    return compile_expression(text, names=params, complex_step=complex_step)


def _check_argument_name(name: Any, what: str) -> None:
    if what == "an argument" and is_dotted_name(name):  # a network's `mass.x`
        return
    if (
        not isinstance(name, str)
        or not name.isascii()
        or not name.isidentifier()
        or keyword.iskeyword(name)
        or name.startswith("_")
        or name in FUNCTIONS
    ):
        raise InputError(
            f"`{name}` cannot be {what}: names must be ASCII identifiers, not keywords, not "
            "starting with `_`, and not a function of the expression language",
            key="constants" if what == "a constant" else "args",
        )


def compile_vector(
    texts: Sequence[str | int | float | ParsedExpression],
    *,
    args: Sequence[str],
    constants: Mapping[str, float] | None = None,
    keys: Sequence[str | None] | None = None,
    source: str | None = None,
    complex_step: bool = False,
) -> Callable[..., np.ndarray]:
    """Compile several expressions into one function returning them as an array.

    This is the hot path of a simulation: the returned ``F(*args)`` evaluates every expression
    in one generated Python function (e.g. ``F(t, y1, y2, y3)`` runs
    ``array((y2*y3, -y1*y3, a*y1*y2))``), costing a few microseconds for small systems.

    Parameters
    ----------
    texts
        The expressions (strings, numbers or :class:`ParsedExpression`).
    args
        The positional arguments of ``F``, by name (e.g. ``["t", "x", "v"]``).
    constants
        Values bound by name at compile time (e.g. parameter values).
    keys
        The TOML key path of each text, for error messages.
    source
        The file the texts came from, for error messages.
    complex_step
        Compile the complex-step variant (see :func:`compile_expression`).

    Returns
    -------
    callable
        ``F(*args) -> ndarray`` of shape ``(len(texts),)`` for scalar arguments, or
        ``(len(texts), *shape)`` where ``shape`` is the broadcast shape of the arguments;
        constant rows are broadcast. ``F.source`` holds the generated Python source.

    Raises
    ------
    ExpressionError
        If a text is invalid or uses a name that is neither an argument nor a constant.
    InputError
        If ``args``/``constants`` names are not usable identifiers, repeat, or overlap, or if
        ``keys`` does not match ``texts``.
    """
    constants = {} if constants is None else dict(constants)
    args = list(args)
    for name in args:
        _check_argument_name(name, "an argument")
    for name in constants:
        _check_argument_name(name, "a constant")
    repeated = sorted({a for a in args if args.count(a) > 1} | (set(args) & set(constants)))
    if repeated:
        raise InputError(
            f"`{repeated[0]}` appears twice among the arguments and constants", key="args"
        )
    if keys is None:
        keys = [None] * len(texts)
    elif len(keys) != len(texts):
        raise InputError(f"got {len(keys)} keys for {len(texts)} expressions", key="keys")

    known = [*args, *constants]
    plan_key = None
    if all(isinstance(t, (str, int, float)) for t in texts):
        plan_key = (tuple(map(str, texts)), tuple(map(type, texts)), tuple(args), tuple(constants), complex_step)
        plan = _PLANS.get(plan_key)
        if plan is not None:  # these texts over these names compiled before: only the constants' values differ
            source_code, literals = plan
            namespace = _namespace(complex_step)
            namespace.update(literals)
            _bind_constants(namespace, constants)
            function = _define(source_code, "_odelab_vector", namespace, _too_deep_unreachable)
            function.source = source_code
            function.recipe = (tuple(texts), tuple(args), tuple(constants.items()), complex_step)
            return function
    parsed = [parse_expression(text, key=k, source=source, names=known) for text, k in zip(texts, keys)]
    for p, k in zip(parsed, keys):
        error = (_lag_error(p, k if k is not None else p.key, source)
                 or _unknown_name_error(p, known, k if k is not None else p.key, source))
        if error is not None:
            raise error

    namespace = _namespace(complex_step)
    _bind_constants(namespace, constants)
    emitter = _Emitter(namespace, complex_step, shadowed_constants(known))
    rows = [emitter.expression(p.tree) for p in parsed]
    used = set().union(*(p.names for p in parsed))
    unused_args = [python_name(a) for a in args if a not in used]

    # np.array stacks rows of equal shape fast; rows of different shapes (a constant next to an
    # array) make it raise ValueError, and arguments no row uses can still set the shape
    dtype = ", dtype=_dtype" if complex_step else ""
    body = [f"_rows = ({''.join(row + ', ' for row in rows)})"]
    pack = [
        "try:",
        f"    _out = _array(_rows{dtype})",
        "except _ValueError:",
        f"    return _broadcast_rows(_rows, ({''.join(python_name(a) + ', ' for a in args)}), _dtype)",
    ]
    if unused_args:
        pack += [
            f"if {' or '.join(a + '.ndim' for a in unused_args)}:",
            f"    return _broadcast_rows(_rows, ({''.join(python_name(a) + ', ' for a in args)}), _dtype)",
        ]
    pack.append("return _out")
    source_code = _function_source("_odelab_vector", args, body)
    source_code += "".join(f"    {line}\n" for line in pack)

    def too_deep() -> ExpressionError:
        deepest = max(range(len(parsed)), key=lambda i: parsed[i]._depth)
        return ExpressionError(
            _too_deep_message(),
            expression=parsed[deepest].text,
            column=0,
            source=source,
            key=keys[deepest],
        )

    function = _define(source_code, "_odelab_vector", namespace, too_deep)
    function.source = source_code
    if plan_key is not None:  # what compiles it again (see Portable)
        function.recipe = (tuple(texts), tuple(args), tuple(constants.items()), complex_step)
        if len(_PLANS) < _PLANS_MAX:
            _PLANS[plan_key] = (source_code, dict(emitter.literals()))
    return function


# The generated source of texts over argument and constant names, and the numbers it pools: the cases of
# a sweep (and a built case unpickled in a Dask worker) compile the same texts with other constant values,
# which are bound in the namespace, never written into the source; parsing and checking them again was
# most of the cost (0.5 ms a case of a two-state sweep).
_PLANS: dict[tuple, tuple[str, dict]] = {}
_PLANS_MAX = 4096


def _bind_constants(namespace: dict, constants: Mapping[str, float]) -> None:
    for name, value in constants.items():
        try:
            namespace[name] = np.float64(float(value))
        except (TypeError, ValueError):
            raise InputError(
                f"constant `{name}` must be a real number; got {value!r}", key=f"constants.{name}"
            ) from None


def _too_deep_unreachable() -> ExpressionError:  # pragma: no cover - a planned source compiled before
    return ExpressionError(_too_deep_message(), expression="", column=0)


def _vector_again(texts: tuple, args: tuple, constants: tuple, complex_step: bool) -> Callable[..., np.ndarray]:
    return compile_vector(list(texts), args=args, constants=dict(constants), complex_step=complex_step)


class _CompiledAgain:
    """Stands in for a :func:`compile_vector` function in a pickle: unpickled, it is that function compiled
    again from its texts (Python's compile() of the same source is cached, :data:`_CODE`)."""

    __slots__ = ("recipe",)

    def __init__(self, recipe: tuple):
        self.recipe = recipe

    def __reduce__(self):
        return _vector_again, self.recipe


def portable(value: Any) -> Any:
    """``value`` as it can be pickled: a :func:`compile_vector` function becomes what compiles it again."""
    recipe = getattr(value, "recipe", None)
    if recipe is not None and callable(value):
        return _CompiledAgain(recipe)
    return value


class PortableState:
    """A base for objects that hold compiled functions among their attributes (a diagram block, a delay or
    implicit system): pickled with each :func:`compile_vector` function as its texts. ``copy.copy`` and
    ``copy.deepcopy`` keep the functions themselves (they would otherwise go through the pickled state)."""

    def __getstate__(self):
        return {name: portable(value) for name, value in self.__dict__.items()}

    def __copy__(self):
        other = object.__new__(type(self))
        other.__dict__.update(self.__dict__)
        return other

    def __deepcopy__(self, memo):
        other = object.__new__(type(self))
        memo[id(self)] = other
        other.__dict__.update(copy.deepcopy(self.__dict__, memo))  # functions are copied as themselves
        return other


class Portable:
    """A base for the small objects that hold compiled functions (a right-hand side, outputs, event
    functions), each a class with ``__slots__`` naming its constructor's arguments in order: pickled slot by
    slot, each :func:`compile_vector` function as its texts, so that a built case travels to another process
    (a Dask worker) and is compiled there, not loaded again."""

    __slots__ = ()

    def __reduce__(self):
        return type(self), tuple(portable(getattr(self, name)) for name in type(self).__slots__)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{n}={getattr(self, n)!r}' for n in type(self).__slots__)})"
