"""Checks shared by the loader and the system builders: names, key sets and constants."""

from __future__ import annotations

import difflib
import math

from odelab.exceptions import ExperimentError, few

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
    seen: set[str] = set()
    dupes = sorted({n for n in out if n in seen or seen.add(n)})  # linear: 3,000 states took seconds
    if dupes:
        raise ExperimentError(f"`{key}` names {dupes[0]!r} twice; {what} names must be unique.", key=key)
    return tuple(out)


def check_keys(given: dict, expected: tuple[str, ...], key: str, what: str, *, require_all: bool) -> None:
    """Every key of ``given`` is one of ``expected`` (and, with ``require_all``, every one is given).

    Linear in both sizes, and the message names a few and the count (a system of 476,000
    states with no [initial] gave a 9,500-character message)."""
    known = set(expected)
    for name in given:
        if name not in known:
            close = difflib.get_close_matches(name, expected, n=1) if len(expected) <= 1000 else []
            hint = f" Did you mean `{close[0]}`?" if close else ""
            raise ExperimentError(f"`{key}.{name}`: {name!r} is not one of the {what} ({few(expected)}).{hint}",
                                  key=f"{key}.{name}")
    if require_all:
        missing = [n for n in expected if n not in given]
        if missing:
            one = what[:-1] if what.endswith('s') else what
            count = f" ({len(missing):,} of {len(expected):,} {what} have none)" if len(missing) > 8 else ""
            raise ExperimentError(
                f"`{key}` has no value for {few(missing, quote=True)}{count}: give one for every {one} "
                f"({few(expected)}).", key=key)


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


def mathtext_problem(text: str) -> str | None:
    """Why matplotlib cannot draw ``text`` (mathtext between ``$``: ``$\\hspace$``, ``$\\foo$``), or None.

    An axis label is drawn by matplotlib's mathtext parser when it holds two ``$``; one it cannot
    parse stops the whole report. matplotlib is imported only when the text holds a ``$``.
    """
    dollars = text.count("$") - text.count("\\$")
    if dollars == 0 or dollars % 2:  # matplotlib's rule: an odd number of $ is drawn as plain text
        return None
    from matplotlib.mathtext import MathTextParser

    try:
        MathTextParser("path").parse(text)
    except Exception as exc:  # pyparsing's ParseException, ValueError, KeyError...: any is "cannot draw it"
        first = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        return first[:160]
    return None
