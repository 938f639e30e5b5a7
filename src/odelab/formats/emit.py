"""Writing an importer's experiment file: TOML with a comment on every section and key saying where it came from.

An importer builds :class:`Section`\\ s of :class:`Entry`\\ s; :func:`write_toml` writes them as
TOML a student can read and edit: arrays and small tables inline, floats as Python's ``repr`` (the
shortest text that reads back as the same double, so the written file runs bit for bit as the
source did), and each comment on its own line above what it explains. A gap is written as a
commented-out key with a ``GAP:`` note saying what to write, so the file is valid TOML and the gap is
where a reader looks for it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Entry", "Section", "write_toml", "toml_value", "toml_key"]

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


@dataclass
class Entry:
    """``key = value``, with a comment above it; ``gap`` writes it commented out, with what to write."""

    key: str | tuple[str, ...]  # a tuple is a dotted key: ("solver", "method") writes solver.method
    value: Any = None
    comment: str = ""
    gap: str = ""  # not empty: the key is not known; this says what to write instead


@dataclass
class Section:
    """A ``[table]`` (or ``[[array]]`` when ``array``) with its comment and entries."""

    name: str  # "system", "system.equations", "events.floor"; "" for the top-level keys
    entries: list[Entry] = field(default_factory=list)
    comment: str = ""
    array: bool = False

    def add(self, key: str | tuple[str, ...], value: Any = None, comment: str = "", gap: str = "") -> Entry:
        entry = Entry(key, value, comment, gap)
        self.entries.append(entry)
        return entry


def toml_key(key: str | tuple[str, ...]) -> str:
    """A key as TOML writes it: bare when it can be, else a basic string; a tuple of parts as a dotted key."""
    if isinstance(key, tuple):
        return ".".join(toml_key(part) for part in key)
    return key if _BARE_KEY.match(key) else _string(key)


def _string(text: str) -> str:
    out = ['"']
    for ch in text:
        code = ord(ch)
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif code < 0x20 or code == 0x7F:
            out.append(f"\\u{code:04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def toml_value(value: Any) -> str:
    """A value as inline TOML: numbers exactly (floats by ``repr``), strings escaped, arrays and tables inline."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        text = repr(value)
        return text if any(c in text for c in ".eEn") else text + ".0"
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        if not value:
            return "{}"
        return "{ " + ", ".join(f"{toml_key(str(k))} = {toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"a TOML value cannot be a {type(value).__name__}: {value!r}")


def _comment(text: str, indent: str = "") -> list[str]:
    lines = []
    for line in text.splitlines() or [""]:
        line = line.replace("\r", " ")
        lines.append(f"{indent}# {line}".rstrip())
    return lines


def write_toml(sections: list[Section], header: str = "") -> str:
    """The experiment file: ``header`` as a comment at the top, then each section in order."""
    out: list[str] = []
    if header:
        out.extend(_comment(header))
    for section in sections:
        if not section.entries and not section.comment:
            continue
        if out:
            out.append("")
        if section.comment:
            out.extend(_comment(section.comment))
        if section.name:
            name = ".".join(toml_key(part) for part in _split_name(section.name))
            out.append(f"[[{name}]]" if section.array else f"[{name}]")
        for entry in section.entries:
            if entry.comment:
                out.extend(_comment(entry.comment))
            if entry.gap:
                out.extend(_comment(f"GAP: {entry.gap}"))
                shown = toml_value(entry.value) if entry.value is not None else "..."
                out.append(f"# {toml_key(entry.key)} = {shown}")
            else:
                out.append(f"{toml_key(entry.key)} = {toml_value(entry.value)}")
    return "\n".join(out) + "\n"


def _split_name(name: str) -> list[str]:
    """``events.floor`` -> [events, floor]; a part in quotes (``initial."der(y)"``) stays one part."""
    parts, current, quoted = [], [], False
    for ch in name:
        if ch == '"':
            quoted = not quoted
        elif ch == "." and not quoted:
            parts.append("".join(current))
            current = []
        else:
            current.append(ch)
    parts.append("".join(current))
    return parts
