"""A diagram as Graphviz DOT text (the report lays it out with Graphviz's ``dot``).

Each block says how it is drawn (:meth:`~odelab.systems.diagram.blocks.Block.node`: its label,
shape and node attributes; :meth:`~odelab.systems.diagram.blocks.Block.input_mark`: the mark at
an input's arrow head, a sum's sign); this module only lays the nodes and edges out.

Every name and label is escaped for a DOT double-quoted string (backslashes, quotes and line
breaks), so a block name or a source's expression cannot change the drawing's structure; the
drawing is rendered to PNG, so nothing from the file reaches the HTML as markup.
"""

from __future__ import annotations

from odelab.systems.diagram.graph import Wiring

__all__ = ["LABEL_WIDTH", "to_dot", "dot_string", "dot_problem", "wrap_label"]

def dot_string(text: str) -> str:
    """``text`` as a DOT double-quoted string; a newline becomes a centred line break."""
    out = str(text).replace("\\", "\\\\").replace('"', '\\"')
    out = out.replace("\r\n", "\n").replace("\r", "\n").replace("\n", "\\n")
    return f'"{out}"'


#: A label line longer than this is wrapped (at ", ", " / " or a space nearest its middle): a
#: drawing of long one-line labels (a PID's gains, a transfer function) grows past a printed
#: page's width, and Graphviz's text would be scaled below reading size.
LABEL_WIDTH = 24


def wrap_label(text: str, width: int = LABEL_WIDTH) -> str:
    """``text`` with every line longer than ``width`` broken in two (again, while too long)."""
    out = []
    for line in str(text).split("\n"):
        pending = [line]
        while pending:
            part = pending.pop(0)
            if len(part) <= width:
                out.append(part)
                continue
            cuts = []
            for sep in (", ", " / ", " "):  # the first kind of break the line has, nearest its middle
                cuts = [i + len(sep) for i in range(1, len(part) - len(sep)) if part.startswith(sep, i)]
                if cuts:
                    break
            if not cuts:
                out.append(part)
                continue
            cut = min(cuts, key=lambda c: abs(c - len(part) / 2))
            pending[:0] = [part[:cut].rstrip(), part[cut:].lstrip()]
    return "\n".join(out)


def to_dot(wiring: Wiring, *, title: str | None = None) -> str:
    """DOT text for the diagram: one node per block, one edge per connection (labelled with the
    port and, into a sum, the sign), and a plain node per named output."""
    # ratio: at least 0.4 high per unit wide, so a long chain is not a thin strip on a phone;
    # ranksep 0.3 in: the thermostat's seven ranks fit a printed page with its text at 7 pt or more
    lines = ["digraph diagram {", "  rankdir=LR; ratio=0.4; ranksep=0.3;", '  node [fontname="Helvetica", fontsize=11];',
             '  edge [fontname="Helvetica", fontsize=10, arrowsize=0.7];']
    if title:
        lines.append(f"  label={dot_string(title)}; labelloc=t;")
    for name, block in wiring.blocks.items():
        label, shape, extra = block.node(name)
        style = ', style="rounded,filled", fillcolor="#eef3fb"' if block.SOURCE else ""
        extra = "".join(f", {k}={dot_string(v) if isinstance(v, str) else str(v).lower()}" for k, v in extra.items())
        lines.append(f"  {dot_string('b:' + name)} [label={dot_string(wrap_label(label))}, shape={shape}{style}{extra}];")
    for name, feeds in wiring.sources.items():
        block = wiring.blocks[name]
        for i, (src, port) in enumerate(feeds):
            attrs = []
            ports = wiring.blocks[src].ports()
            if len(ports) > 1:
                attrs.append(f"taillabel={dot_string(ports[port])}")
            mark = block.input_mark(i)
            if mark:
                attrs.append(f"headlabel={dot_string(mark)}")
            attr = f" [{', '.join(attrs)}]" if attrs else ""
            lines.append(f"  {dot_string('b:' + src)} -> {dot_string('b:' + name)}{attr};")
    for out, (src, port) in wiring.outputs.items():
        lines.append(f"  {dot_string('o:' + out)} [label={dot_string(out)}, shape=plaintext];")
        ports = wiring.blocks[src].ports()
        attr = f" [taillabel={dot_string(ports[port])}]" if len(ports) > 1 else ""
        lines.append(f"  {dot_string('b:' + src)} -> {dot_string('o:' + out)}{attr};")
    lines.append("}")
    return "\n".join(lines) + "\n"


# --- checking DOT text read back from a results folder ---------------------------------------
#
# A stored run's drawing is DOT text in result.json, which anyone can edit; Graphviz reads
# attributes that embed local files (image=, shapefile=, fontpath=) or write them. The report
# draws only DOT of the shape to_dot writes: its fixed header lines, nodes and edges between
# quoted names, and attributes from this list with quoted or plain values.

import re as _re

_Q = r'"(?:[^"\\\n]|\\.)*"'
_ATTRS = {"label", "shape", "style", "fillcolor", "width", "height", "fixedsize", "xlabel", "orientation", "margin",
          "taillabel", "headlabel", "dir", "arrowhead", "arrowsize", "fontsize"}
_PLAIN = _re.compile(r"[A-Za-z0-9.#]{1,40}")
_ATTR = _re.compile(rf"\s*([a-z]+)=({_Q}|[A-Za-z0-9.#]{{1,40}})\s*")
_NODE = _re.compile(rf"  ({_Q})(?: (?:->|--) ({_Q}))?(?: \[(.*)\])?;")
# the fixed lines of the two drawings odelab writes: block diagrams (to_dot) and networks
# (odelab.systems.network.draw.network_dot)
_HEADERS = ("digraph diagram {", "graph network {")
_FIXED = {"}", "  rankdir=LR; ratio=0.4;", "  rankdir=LR; ratio=0.4; ranksep=0.3;",
          "  rankdir=LR; nodesep=0.3; ranksep=0.45;", '  node [fontname="Helvetica", fontsize=11];',
          '  edge [fontname="Helvetica", fontsize=10, arrowsize=0.7];', "  rankdir=LR; nodesep=0.3; ranksep=1.2;",
          '  edge [fontname="Helvetica", fontsize=10];'}
_TITLE = _re.compile(rf"  label={_Q}; labelloc=t;")
MAX_DOT_CHARS = 2_000_000


def _attributes(text: str) -> str | None:
    """Why a bracketed attribute list is not one to_dot writes (None if it is)."""
    rest = text
    while rest:
        m = _ATTR.match(rest)
        if m is None:
            return f"attribute list {text[:60]!r}"
        if m.group(1) not in _ATTRS:
            return f"attribute `{m.group(1)}`"
        rest = rest[m.end():]
        if rest.startswith(","):
            rest = rest[1:]
        elif rest:
            return f"attribute list {text[:60]!r}"
    return None


def dot_problem(text) -> str | None:
    """Why stored DOT text is not a drawing :func:`to_dot` writes (None if it is).

    Anything else (an ``image="/path.png"`` added by hand, an HTML label, a subgraph) makes
    the report leave the drawing out, with this reason, rather than hand it to Graphviz."""
    if not isinstance(text, str):
        return "it is not text"
    if len(text) > MAX_DOT_CHARS:
        return f"it is {len(text):,} characters long"
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    if not lines or lines[0] not in _HEADERS or lines[-1] != "}":
        return "it does not start and end as odelab's drawings do"
    for number, line in enumerate(lines[1:-1], start=2):
        if line in _FIXED or _TITLE.fullmatch(line):
            continue
        m = _NODE.fullmatch(line)
        if m is None:
            return f"line {number} is not a node or an edge as odelab writes them"
        if m.group(3) is not None:
            why = _attributes(m.group(3))
            if why:
                return f"line {number} has {why}, which odelab does not write"
    return None
