"""Names, constants and parameters of experiment files: :func:`check_identifier`,
:func:`evaluate_constant`, :func:`evaluate_parameters` and the dependency-cycle error."""

from __future__ import annotations

import keyword
import math
import numbers
from collections.abc import Mapping

import numpy as np

from odelab.exceptions import ExpressionError, InputError
from odelab.expressions.compile import _unknown_name_error, compile_expression
from odelab.expressions.functions import CONSTANTS, FUNCTIONS
from odelab.expressions.parse import ParsedExpression, parse_expression

# --------------------------------------------------------------------------------------------
# Names, constants and parameters of experiment files
# --------------------------------------------------------------------------------------------


def check_identifier(
    name: str, *, key: str | None = None, source: str | None = None, what: str = "name"
) -> str:
    """Check a name declared in a file (a state, input, parameter or output).

    Parameters
    ----------
    name
        The declared name.
    key, source
        Where it was declared (TOML key path and file), for the error message.
    what
        What the name is for ("state", "parameter"...), used in the message.

    Returns
    -------
    str
        ``name`` itself.

    Raises
    ------
    InputError
        If ``name`` is not an ASCII identifier, is a Python keyword, starts with ``_``, or is
        reserved (``t``, a function of the expression language, or a constant unless ``what``
        is "parameter": a parameter ``e`` shadows the constant, as a MATLAB variable does).
    """
    where = f"`{key}`: " if key else ""
    if not isinstance(name, str):
        raise InputError(
            f"{where}a {what} name must be a string; got {name!r}", key=key, source=source
        )
    if not name:
        raise InputError(f"{where}a {what} name must not be empty", key=key, source=source)
    if not name.isascii() or not name.isidentifier():
        shown = f"`{name}`" if name.isprintable() else repr(name)  # a newline in a name stays on one line
        raise InputError(
            f"{where}{shown} is not a valid {what} name; use ASCII letters, digits and `_`, "
            "starting with a letter (e.g. `x1`, `omega`)",
            key=key,
            source=source,
        )
    reason = ""
    if keyword.iskeyword(name):
        reason = f"`{name}` is a Python keyword"
    elif name.startswith("_"):
        reason = f"`{name}` starts with `_`, which is reserved"
    elif name == "t":
        reason = "`t` is the time variable"
    elif name in CONSTANTS and what != "parameter":  # a parameter shadows it: shadowed_constants
        reason = f"`{name}` is a constant ({CONSTANTS[name]!r})"
    elif name in FUNCTIONS:
        reason = f"`{name}` is a function of the expression language"
    if reason:
        raise InputError(
            f"{where}{reason}; choose another name for this {what}", key=key, source=source
        )
    return name


def evaluate_constant(
    text: str | int | float | ParsedExpression,
    *,
    values: Mapping[str, float] | None = None,
    key: str | None = None,
    source: str | None = None,
) -> float:
    """Evaluate an expression to one finite real number (time values, parameters...).

    Parameters
    ----------
    text
        The expression, e.g. ``"2*pi/omega"``, or a number.
    values
        Values of the names it may use.
    key, source
        Where the text came from, for error messages.

    Returns
    -------
    float
        The value, as a Python float.

    Raises
    ------
    ExpressionError
        If the text is invalid, uses an unknown name, or evaluates to inf, NaN or an array.
    """
    values = {} if values is None else values
    compiled = compile_expression(text, names=values, key=key, source=source)
    result = compiled(**values)
    what = f"`{key}` = `{compiled.text}`" if key else f"`{compiled.text}`"
    if np.ndim(result) != 0:
        raise ExpressionError(
            f"{what} must evaluate to one number; got an array of shape {np.shape(result)}",
            expression=compiled.text,
            column=None,
            source=source,
            key=key,
        )
    number = float(result)
    if not math.isfinite(number):
        raise ExpressionError(
            f"{what} evaluates to {number}; it must be a finite number (check for a division "
            "by zero, an overflow, or a log or square root of a negative number)",
            expression=compiled.text,
            column=None,
            source=source,
            key=key,
        )
    return number


def evaluate_parameters(
    params: Mapping[str, float | int | str],
    *,
    source: str | None = None,
    key_prefix: str = "parameters",
) -> dict[str, float]:
    """Evaluate a file's parameters; each is a number or an expression of other parameters.

    Parameters
    ----------
    params
        Parameter names and values, in any order: ``{"k": "m*w^2", "m": 2, "w": 3}``.
    source
        The file they came from, for error messages.
    key_prefix
        The TOML table holding them; error keys are ``f"{key_prefix}.{name}"``.

    Returns
    -------
    dict
        Parameter values as floats, in the order of ``params``.

    Raises
    ------
    InputError
        If a name is not allowed (see :func:`check_identifier`), a value is neither a number
        nor a string (booleans are rejected), parameters depend on each other in a cycle, or
        a value is not finite.
    ExpressionError
        If an expression is invalid or uses an unknown name.
    """
    try:  # a sweep's cases evaluate the same [parameters] again and again: once per process
        memo = (tuple((k, type(v), v) for k, v in params.items()), source, key_prefix)
        return dict(_EVALUATED[memo])
    except (KeyError, TypeError):  # TypeError: an unhashable value, rejected below
        pass
    values = _evaluate_parameters(params, source, key_prefix)
    try:
        if len(_EVALUATED) < 1024:
            _EVALUATED[memo] = dict(values)
    except TypeError:
        pass
    return values


_EVALUATED: dict[tuple, dict[str, float]] = {}


def _evaluate_parameters(params: Mapping[str, float | int | str], source: str | None,
                         key_prefix: str) -> dict[str, float]:
    names = list(params)

    def key_of(name: str) -> str:
        return f"{key_prefix}.{name}"

    for name in names:
        check_identifier(name, key=key_of(name), source=source, what="parameter")
    parsed: dict[str, ParsedExpression] = {}
    for name, value in params.items():
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (str, numbers.Real)):
            raise InputError(
                f"`{key_of(name)}` must be a number or an expression string; got "
                f"{type(value).__name__} {value!r}",
                key=key_of(name),
                source=source,
            )
        parsed[name] = parse_expression(value, key=key_of(name), source=source, names=names)
        error = _unknown_name_error(parsed[name], names, key_of(name), source)
        if error is not None:
            raise error

    # Kahn's topological order: evaluate a parameter once everything it uses is known
    dependents: dict[str, list[str]] = {name: [] for name in names}
    waiting = {name: len(parsed[name].names) for name in names}
    for name in names:
        for used in parsed[name].names:
            dependents[used].append(name)
    ready = [name for name in names if waiting[name] == 0]
    values: dict[str, float] = {}
    while ready:
        name = ready.pop()
        uses = {used: values[used] for used in parsed[name].names}
        values[name] = evaluate_constant(parsed[name], values=uses, key=key_of(name), source=source)
        for dependent in dependents[name]:
            waiting[dependent] -= 1
            if waiting[dependent] == 0:
                ready.append(dependent)

    if len(values) < len(names):
        raise _cycle_error(parsed, [n for n in names if n not in values], key_of, source)
    return {name: values[name] for name in names}


_CYCLE_SHOWN = 6  # a cycle of more parameters is shown by its first three and last two


def _cycle_error(parsed, unresolved: list[str], key_of, source) -> InputError:
    """Follow unresolved dependencies from the first unresolved parameter until one repeats."""
    pending = set(unresolved)
    path = [unresolved[0]]
    position = {unresolved[0]: 0}
    while True:
        name = path[-1]
        following = next(used for used, _ in parsed[name]._occurrences if used in pending)
        if following in position:
            cycle = path[position[following] :]
            break
        position[following] = len(path)
        path.append(following)
    keys = [f"`{key_of(n)}`" for n in cycle]
    if len(cycle) == 1:
        message = f"{keys[0]} depends on itself"
    elif len(cycle) == 2:
        message = f"{keys[0]} and {keys[1]} depend on each other"
    elif len(cycle) <= _CYCLE_SHOWN:
        message = (
            f"{', '.join(keys[:-1])} and {keys[-1]} depend on each other in a cycle "
            f"({' -> '.join([*cycle, cycle[0]])})"
        )
    else:  # a long cycle: its first and last few names, so the message stays one readable line
        left = len(cycle) - 5
        message = (
            f"{', '.join(keys[:3])}, ... ({left} more) ..., {keys[-2]} and {keys[-1]} depend on each other in a "
            f"cycle of {len(cycle)} parameters ({' -> '.join(cycle[:3])} -> ... -> {' -> '.join(cycle[-2:])} -> "
            f"{cycle[0]})"
        )
    fix = "give it a number" if len(cycle) == 1 else "give one of them a number"
    return InputError(f"{message}; {fix}", key=key_of(cycle[0]), source=source)
