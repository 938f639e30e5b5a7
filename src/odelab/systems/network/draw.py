"""A network as Graphviz DOT text: its nodes as small circles, each element as a box joined to
its nodes, the ground of each domain as a ground symbol. The report lays it out with ``dot``
exactly as it lays out block diagrams (:mod:`odelab.systems.diagram.draw`), and every name
and label goes through that module's escaping, so no text of the file changes the drawing's
structure."""

from __future__ import annotations

from odelab.systems.diagram.draw import dot_string, wrap_label
from odelab.systems.network.graph import GROUND

__all__ = ["network_dot"]

_FILL = {"translational": "#eef3fb", "rotational": "#eef8ee", "electrical": "#fdf3e6", "fluid": "#e9f6f8",
         "thermal": "#fbecec"}


def _label(name, el) -> str:
    parts = [name if name == el.TYPE else f"{name} ({el.TYPE})"]
    coefficients = [f"{el.LAW} = {el.law}"] if el.law is not None else []
    coefficients += [f"{key} = {value}" for key, value in el.values.items()]
    if coefficients:
        parts.append(", ".join(coefficients))
    return wrap_label("\n".join(str(p) if len(str(p)) <= 48 else str(p)[:45] + "..." for p in parts), 28)


def network_dot(elements: dict, *, title: str | None = None) -> str:
    """DOT text for the network: its nodes as circles, each two-terminal element as a labelled
    edge from its second node to its first (the arrow points at the + side, where its across
    variable is measured to), each coupling as a box joined to its four nodes, and a ground
    symbol at every connection to ground (as a circuit diagram draws them)."""
    lines = ["graph network {", "  rankdir=LR; nodesep=0.3; ranksep=0.45;",  # the DC motor fits a printed page
             '  node [fontname="Helvetica", fontsize=11];', '  edge [fontname="Helvetica", fontsize=10];']
    if title:
        lines.append(f"  label={dot_string(title)}; labelloc=t;")
    seen: set[tuple[str, str]] = set()
    grounds = 0

    def node(domain, n):
        nonlocal grounds
        if n == GROUND:
            grounds += 1
            ident = dot_string(f"g:{grounds}")
            lines.append(f"  {ident} [label=\"\", shape=invtriangle, width=0.25, height=0.2, fixedsize=true, "
                         f"style=filled, fillcolor=\"#888888\", xlabel={dot_string('ground')}, fontsize=10];")
            return ident
        ident = dot_string(f"n:{domain}:{n}")
        if (domain, n) not in seen:
            seen.add((domain, n))
            lines.append(f"  {ident} [label={dot_string(n)}, shape=circle, margin=0.02, style=filled, "
                         f"fillcolor={dot_string(_FILL.get(domain, '#ffffff'))}];")
        return ident

    for name, el in elements.items():
        if el.DOMAIN2 is None:
            a, b = el.nodes
            head, tail = node(el.DOMAIN, a), node(el.DOMAIN, b)
            style = ", style=dashed" if el.ROLE.endswith("source") else ""
            lines.append(f"  {tail} -- {head} [label={dot_string(_label(name, el))}, dir=forward, "
                         f"arrowhead=vee, arrowsize=0.6{style}];")
            continue
        box = dot_string(f"e:{name}")
        lines.append(f"  {box} [label={dot_string(_label(name, el))}, shape=box, style=filled, "
                     f"fillcolor=\"#f4f4f4\"];")
        for domain, (a, b), mark in ((el.DOMAIN, el.nodes, "1"), (el.DOMAIN2, el.nodes2, "2")):
            lines.append(f"  {node(domain, a)} -- {box} [taillabel={dot_string('+' + mark)}];")
            lines.append(f"  {node(domain, b)} -- {box} [taillabel={dot_string('-' + mark)}];")
    lines.append("}")
    return "\n".join(lines) + "\n"
