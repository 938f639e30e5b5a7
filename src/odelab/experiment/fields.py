"""Checks shared by the loader and the system builders: names, key sets and constants."""

from __future__ import annotations

import difflib
import math

from odelab.exceptions import ExperimentError

__all__ = ["check_keys", "check_names", "constant", "expr"]


def expr():
    """The expression language, imported when first needed."""
    from odelab import expressions

    return expressions


def check_names(values: list[str], key: str, what: str) -> tuple[str, ...]:
    ex = expr()
    out = []
    for i, name in enumerate(values):
        out.append(ex.check_identifier(name, key=f"{key}[{i}]", what=what))
    dupes = sorted({n for n in out if out.count(n) > 1})
    if dupes:
        raise ExperimentError(f"`{key}` names {dupes[0]!r} twice; {what} names must be unique.", key=key)
    return tuple(out)


def check_keys(given: dict, expected: tuple[str, ...], key: str, what: str, *, require_all: bool) -> None:
    for name in given:
        if name not in expected:
            close = difflib.get_close_matches(name, expected, n=1)
            hint = f" Did you mean `{close[0]}`?" if close else ""
            raise ExperimentError(f"`{key}.{name}`: {name!r} is not one of the {what} ({', '.join(expected)}).{hint}",
                                  key=f"{key}.{name}")
    if require_all:
        missing = [n for n in expected if n not in given]
        if missing:
            raise ExperimentError(
                f"`{key}` has no value for {', '.join(repr(m) for m in missing)}: give one for every "
                f"{what[:-1] if what.endswith('s') else what} ({', '.join(expected)}).", key=key)


def constant(value, key: str, params: dict[str, float]) -> float:
    """A number, or an expression of the parameters, evaluated to one finite float.

    Plain finite numbers skip the expression compiler, and an expression already evaluated
    with the same parameter values is not compiled again: a file's cases share their matrices
    and time settings, so loading stays linear in the file's size, not cases x entries.
    """
    if type(value) in (int, float) and math.isfinite(value):
        return float(value)
    if isinstance(value, str):
        cache_key = (value, tuple(sorted(params.items())))
        cached = _CONSTANTS.get(cache_key)
        if cached is None:
            cached = expr().evaluate_constant(value, values=params, key=key)
            if len(_CONSTANTS) >= _CONSTANTS_MAX:
                _CONSTANTS.clear()
            _CONSTANTS[cache_key] = cached
        return cached
    return expr().evaluate_constant(value, values=params, key=key)


_CONSTANTS: dict[tuple, float] = {}  # successful evaluations only: errors are raised afresh, with their key
_CONSTANTS_MAX = 100_000
