"""Pydantic's validation errors as the file's key paths: one message, one line per key, most useful first."""

from __future__ import annotations

import difflib
import re
from typing import Any

from pydantic import ValidationError

from odelab.exceptions import ExperimentError, InputError

__all__ = ["describe_value", "schema_error"]


_TOML_TYPE = {bool: "a boolean", int: "a number", float: "a number", str: "a string", list: "an array",
              dict: "a table"}
_EXPECTED = {
    "int_type": "a whole number",
    "float_type": "a number",
    "string_type": "a string",
    "bool_type": "true or false",
    "list_type": "an array",
    "dict_type": "a table",
    "model_type": "a table",
    "model_attributes_type": "a table",
}


def _is_union_tag(seg) -> bool:
    return isinstance(seg, str) and (
        "[" in seg or seg in {"int", "float", "str", "bool", "none"} or seg.startswith("function-")
    )


def _key_path(loc, data) -> tuple:
    """The segments of pydantic's error location that are keys of the file (not union-member tags).

    A segment is looked up in the file's data first, so a user's key that looks like a tag
    (``"rtol[1]"``, ``"int"``) is still reported under its own name.
    """
    path = []
    node = data
    for seg in loc:
        if isinstance(node, dict) and isinstance(seg, str) and seg in node:
            node = node[seg]
        elif isinstance(node, list) and isinstance(seg, int) and 0 <= seg < len(node):
            node = node[seg]
        elif _is_union_tag(seg):
            continue
        else:  # a required key that is missing, or below a value of the wrong type
            node = None
        path.append(seg)
    return tuple(path)


def _key(loc) -> str:
    parts: list[str] = []
    for seg in loc:
        if isinstance(seg, int):
            parts[-1 if parts else 0:] = [f"{parts[-1] if parts else ''}[{seg}]"]
        else:
            parts.append(str(seg))
    return ".".join(parts)


def _node_at(data: Any, loc) -> Any:
    """The table of ``data`` at ``loc`` (as the file wrote it), or None."""
    node = data
    for seg in loc:
        if isinstance(node, dict) and seg in node:
            node = node[seg]
        elif isinstance(node, list) and isinstance(seg, int) and 0 <= seg < len(node):
            node = node[seg]
        else:
            return None
    return node


def describe_value(value) -> str:
    kind = _TOML_TYPE.get(type(value), type(value).__name__)
    text = repr(value) if not isinstance(value, bool) else str(value).lower()
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{text} ({kind})"


_REQUIRED_HINT = {
    "system": "add a [system] table with `states` and [system.equations] (or `function`, or kind = \"state-space\")",
    "time": "add a [time] table with at least `stop`",
    "time.stop": "add `stop = 10` (or an expression such as \"2*pi\") under [time]",
}


def _required_hint(key: str) -> str:
    if key.rsplit(".", 1)[-1] == "type" and key not in _REQUIRED_HINT:
        from odelab.experiment.build import signal_type_list

        return f"give the signal's `type`: {signal_type_list(' or ')}"
    return _REQUIRED_HINT.get(key) or _REQUIRED_HINT.get(key.rsplit(".", 1)[-1], "")


def _unit_hint(text: str, key: str) -> str:
    """A value with a unit where a plain number is read: the number it is in SI, converted by pint, so the
    fix never drops a unit (a student told to write 100 for "100 cm" makes the model 100 times wrong)."""
    from odelab.expressions.units import convert

    try:
        si = convert(key.rsplit(".", 1)[-1], text, None, f"`{key}`")
    except InputError as exc:
        return f"a value with a unit, which this key does not read ({exc.message})"
    return (f"a value with a unit, which this key does not read: it takes a plain number in SI units, here "
            f"{si.value:.10g} ({text} is {si.value:.10g} {si.unit}); units are read in [parameters], [initial] and "
            "[time]")


def schema_error(exc: ValidationError, *, source: str, case: str | None, data: Any = None) -> ExperimentError:
    """Turn pydantic's errors into one message, one line per key, most useful first.

    ``data`` is what was validated: with it, keys are named as the file spells them.
    """
    by_key: dict[str, list[dict]] = {}
    for err in exc.errors():
        err = {**err, "loc": _key_path(err["loc"], data)}
        by_key.setdefault(_key(err["loc"]), []).append(err)
    lines = []
    first_key = None
    for key, errs in by_key.items():
        first_key = first_key or key
        kinds = {e["type"] for e in errs}
        err = errs[0]
        if "extra_forbidden" in kinds:
            from odelab.experiment.keyref import unknown_key_message

            lines.append(unknown_key_message(key, _node_at(data, err["loc"][:-1])))
        elif "missing" in kinds:
            hint = _required_hint(key)
            lines.append(f"`{key}` is required" + (f": {hint}." if hint else "."))
        elif "literal_error" in kinds:
            expected = err.get("ctx", {}).get("expected", "")
            choices = re.findall(r"'([^']*)'", expected)
            given = err["input"]
            # MATLAB names (sin for sine) and typos: the closest allowed word, or the one it starts
            close = difflib.get_close_matches(given, choices, n=1, cutoff=0.6) if isinstance(given, str) else []
            close = close or ([c for c in choices if c.startswith(given)][:1] if isinstance(given, str) and given
                              else [])
            hint = f" Did you mean {close[0]!r}?" if close else ""
            lines.append(f"`{key}` is {describe_value(given)}; it must be one of {expected}.{hint}")
        else:
            expected = sorted({_EXPECTED.get(e["type"], e["msg"]) for e in errs})
            if "a number" in expected and "a whole number" in expected:
                expected.remove("a whole number")
            if expected == ["a number", "a string"]:
                expected = ["a number or an expression string"]
            line = f"`{key}` must be {' or '.join(expected)}; got {describe_value(err['input'])}."
            if "a number" in expected:
                from odelab.expressions.units import split_unit_value

                if split_unit_value(err["input"]) is not None:  # "2 N": never "drop the unit", say what it is
                    line = line[:-1] + ": " + _unit_hint(str(err["input"]), key) + "."
            lines.append(line)
    where = f" (in case {case!r})" if case else ""
    message = lines[0] + where if len(lines) == 1 else "\n  ".join([f"{len(lines)} problems{where}:", *lines])
    return ExperimentError(message, source=source, key=first_key)
