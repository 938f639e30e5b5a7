"""The experiment file's JSON Schema, for editors: keys completed and explained as a student types.

Generated from the key reference (:func:`odelab.experiment.keyref.entries`, itself read from the
pydantic schema and the registries of methods, options, signals, blocks, elements and study kinds),
so the editor's help is `odelab explain`'s, word for word, and cannot drift from what the loader
takes. A TOML editor reads it through a ``#:schema`` line (Taplo, VS Code's Even Better TOML):
``odelab new`` writes one pointing at the copy shipped in the package
(``odelab/schemas/experiment.schema.json``, checked against this generator by the tests), and
``odelab schema`` prints it.

The schema helps; it does not judge. A table's keys are listed for completion, and unknown keys
are flagged only in the tables whose keys the reference lists completely; what a file means is
still decided by the loader, whose messages say what to write instead.
"""

from __future__ import annotations

import json
from importlib import resources
from typing import Any

__all__ = ["experiment_schema", "schema_text", "SHIPPED", "shipped_path"]

SHIPPED = "experiment.schema.json"

_VALUE = {"type": ["number", "string"]}
_TYPES: dict[str, dict[str, Any]] = {
    "number": {"type": "number"},
    "integer": {"type": "integer"},
    "count": {"type": "integer"},
    "string": {"type": "string"},
    "text": {"type": "string"},
    "expression": {"type": "string"},
    "bool": {"type": "boolean"},
    "boolean": {"type": "boolean"},
    "number or expression": _VALUE,
    "boolean or string": {"type": ["boolean", "string"]},
    "boolean or table": {"type": ["boolean", "object"]},
    "list of strings": {"type": "array", "items": {"type": "string"}},
    "names": {"type": "array", "items": {"type": "string"}},
    "numbers": {"type": ["array", "string"], "items": {"type": "number"}},
    "list of numbers": {"type": ["array", "string"], "items": {"type": "number"}},
    "number or list of numbers": {"type": ["number", "array"], "items": {"type": "number"}},
}


def _leaf(type_text: str) -> dict[str, Any]:
    if type_text in _TYPES:
        return dict(_TYPES[type_text])
    if type_text.startswith("table") and " or list" in type_text:  # outputs: a table of expressions, or names
        return {"type": ["object", "array"]}
    if type_text.startswith("list or range"):  # a sweep's values: a list, a range table, a MATLAB range
        return {"type": ["array", "object", "string"]}
    if type_text.startswith("matrix"):
        return {"type": ["array", "string", "number"]}
    if type_text.startswith("list") or type_text.startswith("number or expression each) or list"):
        return {"type": ["array", "string", "number"]}
    if type_text.startswith("table") or type_text in ("signal type", "block type", "element type", "method"):
        return {"type": "object"}
    return {}


def _description(e) -> str:
    parts = [e.text]
    if e.default not in (None, "None", "required", "none", "''", "()"):
        parts.append(f"Default: {e.default}.")
    if e.default == "required":
        parts.append("Required.")
    if e.matlab:
        parts.append(f"MATLAB's name{'s' if len(e.matlab) > 1 else ''}: {', '.join(e.matlab)}.")
    return " ".join(p for p in parts if p)


def _node(e) -> dict[str, Any]:
    node = _leaf(e.type)
    if e.choices:
        exact = node.get("type") == "string" and not e.path.startswith("solver.")
        if exact:  # a pydantic Literal: the loader takes these words exactly
            node = {"type": "string", "enum": list(e.choices)}
        else:  # offered for completion; the loader also takes MATLAB's forms (ODE45, -1, 'on')
            node = {"anyOf": [{"enum": list(e.choices)}, {"type": ["string", "number", "boolean"]}]}
    node["description"] = _description(e)
    return node


def experiment_schema() -> dict[str, Any]:
    """The JSON Schema (draft-07) of an experiment file, from the key reference."""
    from odelab.experiment.keyref import entries

    table = {e.path: e for e in entries()}
    root: dict[str, Any] = {"type": "object", "properties": {}}
    nodes: dict[str, dict[str, Any]] = {"": root}
    typed = ("inputs", "blocks", "elements", "solver.method")  # keys of one kind of thing each: merged below
    for path, e in table.items():
        parts = path.split(".")
        if parts[0] in ("inputs", "blocks", "elements") and len(parts) >= 2 and parts[1] != "<name>":
            continue  # a signal, block or element type's entry: merged into <name> below
        if path.startswith("solver.method."):
            continue
        parent = nodes.get(".".join(parts[:-1]))
        if parent is None:
            continue
        node = _node(e)
        nodes[path] = node
        if parts[-1] in ("<name>", "<key>"):
            parent["additionalProperties"] = node
            parent.setdefault("type", "object")
        else:
            parent.setdefault("properties", {})[parts[-1]] = node
            for alias in e.matlab:  # odeset's spellings are keys too
                parent["properties"].setdefault(alias, {**node, "description": f"MATLAB's name for `{parts[-1]}`. "
                                                        + node["description"]})
    for section in typed[:3]:
        _typed_tables(section, table, nodes)
    _closed(nodes, table)
    for key in ("case", "problem"):  # each [[case]] / [[problem]] overrides the file's own tables
        node = root["properties"].get(key)
        if node is not None:
            node.update({"type": "array", "items": {"$ref": "#"}})
    return {"$schema": "http://json-schema.org/draft-07/schema#", "title": "odelab experiment file",
            "description": "An odelab experiment (TOML): the system, its initial state, the time span, the solver. "
                           "`odelab explain KEY` prints each key's entry.", **root}


def _typed_tables(section: str, table: dict, nodes: dict) -> None:
    """[inputs.<name>], [blocks.<name>], [elements.<name>]: the keys of every type, each saying which types take it."""
    holder = nodes.get(f"{section}.<name>")
    if holder is None:
        return
    holder.setdefault("properties", {})
    users: dict[str, list[str]] = {}
    texts: dict[str, Any] = {}
    kinds = [p.split(".")[1] for p, e in table.items() if p.count(".") == 1 and p.startswith(section + ".")
             and p.split(".")[1] != "<name>"]
    for kind in kinds:
        for p, e in table.items():
            if p.startswith(f"{section}.{kind}.") and p.count(".") == 2:
                key = p.split(".")[2]
                users.setdefault(key, []).append(kind)
                texts.setdefault(key, e)
    for key, kinds_of in users.items():
        node = _node(texts[key])
        node["description"] = f"({', '.join(kinds_of)}) {node['description']}"
        leaves = {json.dumps(_leaf(e.type), sort_keys=True) for p, e in table.items()
                  if p.startswith(f"{section}.") and p.count(".") == 2 and p.split(".")[2] == key}
        if len(leaves) > 1 or section != "inputs":
            # a key of several types with several shapes, or a block's or element's value (a number, an
            # expression of the parameters, a matrix of either): the loader checks it, the editor only helps
            node.pop("type", None)
            node.pop("items", None)
        holder["properties"].setdefault(key, node)


def _closed(nodes: dict, table: dict) -> None:
    """Tables whose keys the reference lists completely (a pydantic model's): other keys are flagged."""
    for path, node in nodes.items():
        e = table.get(path)
        if e is None or not e.children or "<name>" in e.children or "<key>" in e.children:
            continue
        if path.split(".")[0] in ("inputs", "blocks", "elements", "solver", "sweep", "events", "system"):
            continue  # typed tables, options from a registry, a [system] of every kind: keys vary
        if set(node.get("properties", {})) >= set(e.children):
            node["additionalProperties"] = False


def schema_text() -> str:
    """The schema as the package ships it: JSON, sorted keys, two-space indent, a final newline."""
    return json.dumps(experiment_schema(), indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def shipped_path():
    """The schema file shipped in the package (what ``odelab new``'s ``#:schema`` line points at)."""
    return resources.files("odelab") / "schemas" / SHIPPED
