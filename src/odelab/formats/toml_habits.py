"""MATLAB habits in an experiment file's TOML, recognised: one message saying what to write instead.

TOML's own messages ("Invalid value", "Invalid statement", "Unclosed array") name a line and
column but not the cause. For the lines a MATLAB user writes by habit the cause is plain:

- an equation or expression not in quotes: ``y = r*P*(1 - P/K)`` -> ``y = "r*P*(1 - P/K)"``;
- a ``%`` comment -> ``#``;
- a range as a TOML array: ``output = [0:0.1:15]`` -> ``output = "0:0.1:15"`` (which runs);
- a MATLAB matrix unquoted: ``A = [0 1; -3 -4]`` -> ``A = "[0 1; -3 -4]"`` (which runs);
- a unit written after a number: ``stop = 10 s`` -> ``stop = 10`` and ``[units]``.
"""

from __future__ import annotations

import re

__all__ = ["toml_error_message"]

_WHERE = re.compile(r"\(at line (\d+), column (\d+)\)")
_ASSIGNMENT = re.compile(r"^\s*([A-Za-z0-9_.\"'-]+)\s*=\s*(.*?)\s*$")
_NUMBER_UNIT = re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*([A-Za-zµ°][A-Za-z/*^0-9µ°]*)$")


def _strip_comment(value: str) -> str:
    """The value without a trailing # or % comment (outside quotes)."""
    quote = None
    for i, c in enumerate(value):
        if quote:
            if c == quote:
                quote = None
        elif c in "\"'":
            quote = c
        elif c in "#%":
            return value[:i].rstrip()
    return value


def _hint(line: str) -> str | None:
    stripped = line.strip()
    if stripped.startswith("%"):
        return "`%` starts a comment in MATLAB; in TOML comments start with `#`: write `#" + stripped[1:] + "`"
    m = _ASSIGNMENT.match(line)
    if m is None:
        return None
    key, value = m.group(1), _strip_comment(m.group(2))
    if not value or value[0] in "\"'{":
        return None
    if value.startswith("["):
        inner = value[1:-1] if value.endswith("]") else value[1:]
        if ":" in inner and "," not in inner:
            return (f"`{value}` is a MATLAB range; in TOML write it as a string, `{key} = \"{inner.strip()}\"`, "
                    "and odelab expands it as MATLAB does")
        if ";" in inner or re.search(r"[\w.)]\s+[-\w(.]", inner):
            return (f"`{value}` is a MATLAB matrix; in TOML write it as a string, `{key} = \"{value}\"` (odelab "
                    "reads MATLAB's rows and spaces), or as rows: [[0, 1], [-3, -4]]")
        return None
    unit = _NUMBER_UNIT.match(value)
    if unit is not None:
        return (f"`{value}` has a unit in it: write it in quotes, `{key} = \"{value}\"`, and odelab converts it "
                "with pint (in [parameters], [initial] and [time]: to the unit [units] declares for the name, else "
                "to SI)")
    if re.search(r"[A-Za-z_(*/^]", value):
        return (f"an equation or expression must be in quotes: write `{key} = \"{value}\"` (TOML has no "
                "formulas; odelab reads the string)")
    return None


def toml_error_message(text: str, exc: Exception) -> str:
    """TOML's syntax error, replaced by what to write instead when the line is a MATLAB habit."""
    message = str(exc)
    where = _WHERE.search(message)
    if where is not None:
        lineno = int(where.group(1))
        lines = text.splitlines()
        if 1 <= lineno <= len(lines):
            hint = _hint(lines[lineno - 1])
            if hint is not None:
                return f"line {lineno}: {hint}."
    return f"TOML syntax error: {message}."
