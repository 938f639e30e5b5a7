"""A diagram as Graphviz DOT text (the report lays it out with Graphviz's ``dot``).

Every name and label is escaped for a DOT double-quoted string (backslashes, quotes and line
breaks), so a block name or a source's expression cannot change the drawing's structure; the
drawing is rendered to PNG, so nothing from the file reaches the HTML as markup.
"""

from __future__ import annotations

from odelab.systems.diagram.graph import Wiring

__all__ = ["to_dot", "dot_string"]

_SHAPES = {"sum": "circle", "gain": "triangle", "integrator": "box", "saturation": "box", "dead-zone": "box",
           "product": "circle", "mux": "box", "demux": "box", "fcn": "box", "state-space": "box",
           "transfer-fcn": "box", "clock": "box"}


def dot_string(text: str) -> str:
    """``text`` as a DOT double-quoted string; a newline becomes a centred line break."""
    out = str(text).replace("\\", "\\\\").replace('"', '\\"')
    out = out.replace("\r\n", "\n").replace("\r", "\n").replace("\n", "\\n")
    return f'"{out}"'


def to_dot(wiring: Wiring, *, title: str | None = None) -> str:
    """DOT text for the diagram: one node per block, one edge per connection (labelled with the
    port and, into a sum, the sign), and a plain node per named output."""
    # ratio: at least 0.4 high per unit wide, so a long chain is not a thin strip on a phone
    lines = ["digraph diagram {", "  rankdir=LR; ratio=0.4;", '  node [fontname="Helvetica", fontsize=11];',
             '  edge [fontname="Helvetica", fontsize=10, arrowsize=0.7];']
    if title:
        lines.append(f"  label={dot_string(title)}; labelloc=t;")
    for name, block in wiring.blocks.items():
        shape = "box" if block.SOURCE and getattr(block, "TYPE", "") != "clock" else _SHAPES.get(block.TYPE, "box")
        style = ', style="rounded,filled", fillcolor="#eef3fb"' if block.SOURCE else ""
        if block.TYPE == "sum":
            label = "Σ"
            extra = ', width=0.45, fixedsize=true, xlabel=' + dot_string(name)
        elif block.TYPE == "gain":
            extra = ", orientation=270, margin=0, xlabel=" + dot_string(name)
            label = _block_label(name, block)
        else:
            extra = ""
            label = _block_label(name, block)
        lines.append(f"  {dot_string('b:' + name)} [label={dot_string(label)}, shape={shape}{style}{extra}];")
    for name, feeds in wiring.sources.items():
        block = wiring.blocks[name]
        for i, (src, port) in enumerate(feeds):
            attrs = []
            ports = wiring.blocks[src].ports()
            if len(ports) > 1:
                attrs.append(f"taillabel={dot_string(ports[port])}")
            if block.TYPE == "sum":
                attrs.append(f"headlabel={dot_string('+' if block.signs[i] > 0 else '−')}")
            if block.TYPE == "product" and block.ops[i] == "/":
                attrs.append(f"headlabel={dot_string('÷')}")
            attr = f" [{', '.join(attrs)}]" if attrs else ""
            lines.append(f"  {dot_string('b:' + src)} -> {dot_string('b:' + name)}{attr};")
    for out, (src, port) in wiring.outputs.items():
        lines.append(f"  {dot_string('o:' + out)} [label={dot_string(out)}, shape=plaintext];")
        ports = wiring.blocks[src].ports()
        attr = f" [taillabel={dot_string(ports[port])}]" if len(ports) > 1 else ""
        lines.append(f"  {dot_string('b:' + src)} -> {dot_string('o:' + out)}{attr};")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _block_label(name: str, block) -> str:
    texts = getattr(block, "texts", {})
    kind = block.TYPE
    if block.SOURCE:
        return f"{name}\n{block.describe()}"
    if kind == "gain":
        k = texts.get("gain", block.params["gain"])
        return f"{k}" if not isinstance(k, list) else "K"
    if kind == "integrator":
        return f"{name}\n1/s" + (f"\n[{block.lo:g}, {block.hi:g}]" if block.limited else "")
    if kind == "transfer-fcn":
        num = " ".join(f"{c:g}" for c in block.num)
        den = " ".join(f"{c:g}" for c in block.den)
        return f"{name}\n[{num}] / [{den}]"
    if kind == "state-space":
        return f"{name}\nx' = Ax + Bu\ny = Cx + Du"
    if kind == "saturation":
        return f"{name}\nsat [{block.lo:g}, {block.hi:g}]"
    if kind == "dead-zone":
        return f"{name}\ndead zone [{block.lo:g}, {block.hi:g}]"
    if kind == "fcn":
        return f"{name}\n{block.params['expression']}"
    return f"{name}\n{block.describe()}"
