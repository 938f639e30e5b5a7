"""Checks shared by the loader and the system builders: names, key sets and constants."""

from __future__ import annotations

import difflib

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
    return expr().evaluate_constant(value, values=params, key=key)
