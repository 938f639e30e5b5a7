"""The report's appendix: each case's resolved settings as compact TOML, the others as differences.

tomli_w writes one array item per line, which turned a 7-amplitude list into 9 printed lines;
here arrays and small tables are written inline, as a person writes them, and each case after
an experiment's first shows only the keys whose values differ (``solver.method = "ode23"``).
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

__all__ = ["settings_diff", "toml_text"]

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _key(key: Any) -> str:
    key = str(key)
    return key if _BARE_KEY.fullmatch(key) else json.dumps(key, ensure_ascii=False)


def _value(value: Any) -> str:
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items() if v is not None) + " }"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value if v is not None) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    return json.dumps(str(value), ensure_ascii=False)


def _table(data: dict, path: str, out: list[str]) -> None:
    for k, v in data.items():
        if v is not None and not isinstance(v, dict):
            out.append(f"{_key(k)} = {_value(v)}")
    for k, v in data.items():
        if isinstance(v, dict):
            name = f"{path}.{_key(k)}" if path else _key(k)
            if any(not isinstance(x, dict) and x is not None for x in v.values()):
                out.append("")
                out.append(f"[{name}]")
            _table(v, name, out)


def toml_text(config: dict) -> str:
    """``config`` as TOML with arrays and tables of arrays inline."""
    out: list[str] = []
    _table(config, "", out)
    return "\n".join(out).lstrip("\n") + "\n"


def _flat(data: dict, prefix: str = "") -> dict[str, Any]:
    out = {}
    for k, v in data.items():
        path = f"{prefix}.{_key(k)}" if prefix else _key(k)
        if isinstance(v, dict) and v:
            out.update(_flat(v, path))
        else:
            out[path] = v
    return out


def settings_diff(base: dict, other: dict, *, ignore: tuple[str, ...] = ("name", "case")) -> str:
    """The keys of ``other`` that differ from ``base`` as ``dotted.key = value`` lines."""
    a = {k: v for k, v in _flat(base).items() if k.split(".")[0] not in ignore}
    b = {k: v for k, v in _flat(other).items() if k.split(".")[0] not in ignore}
    lines = [f"{k} = {_value(v)}" for k, v in b.items() if k not in a or a[k] != v]
    lines += [f"# {k} not set" for k in a if k not in b]
    return "\n".join(lines) + "\n" if lines else "(the same settings)\n"
