"""MATLAB Function blocks whose code is straight-line scalar arithmetic, as ``fcn`` blocks.

A MATLAB Function block holds a MATLAB function (``function y = fcn(u)`` and its body), kept in the
model's Stateflow part. When the body is assignments of scalar expressions (``a = u1*u2; y = a + 1;``),
each output is an expression of the inputs, written as one odelab ``fcn`` block per output; anything
else (``if``, loops, calls to other functions, vectors) stays a gap with the reason. The code is parsed
by :mod:`~odelab.formats.simulink.mexpr`, never run.
"""

from __future__ import annotations

import re

import numpy as np

from odelab.formats.simulink.mexpr import MExprError, V, evaluate, text_of
from odelab.formats.simulink.tree import Node
from odelab.formats.simulink.workspace import _statements

__all__ = ["charts", "function_outputs"]

_HEADER = re.compile(r"^function\s+(?:\[([^\]]*)\]|([A-Za-z]\w*))\s*=\s*[A-Za-z]\w*\s*(?:\(([^)]*)\))?\s*$")
_ASSIGN = re.compile(r"^([A-Za-z]\w*)\s*=(?!=)\s*(.+)$", re.DOTALL)


def charts(nodes: list[Node]) -> dict[str, str]:
    """Chart name -> its MATLAB function's text, from an .slx's ``simulink/stateflow/chart_*.xml`` parts or a
    .mdl's ``Stateflow`` section (charts by id, states naming their chart)."""
    out: dict[str, str] = {}
    for top in nodes:
        names = {}
        for node in top.walk():
            if node.tag == "chart":
                names[node.get("id", "")] = node.get("name", "")
        for node in top.walk():
            if node.tag == "chart" and node.get("name"):
                for inner in node.walk():
                    if inner.tag == "eml" and inner.get("script"):
                        out.setdefault(node.get("name"), inner.get("script"))
            if node.tag == "state" and node.get("chart") in names:
                for inner in node.walk():
                    if inner.tag == "eml" and inner.get("script"):
                        out.setdefault(names[node.get("chart")], inner.get("script"))
    return out


def function_outputs(script: str, lookup) -> tuple[list[str], str]:
    """(each output's odelab expression of u1, u2..., "") or ([], why not)."""
    statements = [s for _, s in _statements(script)]
    if not statements:
        return [], "the function is empty"
    header = _HEADER.match(" ".join(statements[0].split()))
    if header is None:
        return [], f"its first line {statements[0][:60]!r} is not `function y = f(u)`"
    outs = [n for n in re.split(r"[\s,]+", header.group(1) or header.group(2) or "") if n]
    ins = [n for n in re.split(r"[\s,]+", header.group(3) or "") if n]
    env: dict[str, V] = {name: V(np.array([[1.0]]), np.array([[f"u{i + 1}"]], dtype=object))
                         for i, name in enumerate(ins)}
    for stmt in statements[1:]:
        if stmt == "end":
            continue
        m = _ASSIGN.match(stmt)
        if m is None:
            return [], f"`{stmt[:40]}` is not an assignment (if, for and calls are not translated)"
        missing: set[str] = set()
        try:
            value = evaluate(m.group(2), lambda n: env.get(n) or lookup(n), missing)
        except MExprError as exc:
            return [], f"`{stmt[:40]}`: {exc}"
        if missing:
            return [], f"`{stmt[:40]}` uses {', '.join(sorted(missing))}, which the function does not define"
        if value.num.size != 1:
            return [], f"`{stmt[:40]}` is not a scalar"
        env[m.group(1)] = value
    missing_out = [o for o in outs if o not in env]
    if missing_out:
        return [], f"its output {missing_out[0]} is never assigned"
    return [text_of(env[o]) for o in outs], ""
