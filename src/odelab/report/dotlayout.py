"""Drawing odelab's own DOT text without Graphviz: a layered layout drawn with matplotlib.

The report draws block diagrams (and networks) with Graphviz's ``dot`` where it is installed.
On a machine without it, the report still shows every drawing: this module reads the small
subset of DOT that odelab writes itself (nodes with ``label``, ``shape``, ``xlabel``; edges
with ``taillabel`` and ``headlabel``; a graph ``label``), lays the graph out left to right in
layers as Sugiyama's method does (cycles broken at the edges a depth-first search finds going
back, each node one layer right of its furthest predecessor, the order within layers improved
by barycentres), and draws boxes, circles and triangles with straight arrows forward and
arcs for the feedback edges. It is a fallback, not a DOT implementation: anything else in the
text is ignored, and nothing in it is ever executed or opened.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass, field

__all__ = ["Graph", "draw_png", "layout", "parse_dot"]

_ID = r'"(?:[^"\\]|\\.)*"|[A-Za-z_][\w.]*'
_ATTRS = r"(?:\[(?P<attrs>.*)\])?"
_EDGE = re.compile(rf"^\s*(?P<a>{_ID})\s*->\s*(?P<b>{_ID})\s*{_ATTRS}\s*;?\s*$")
_NODE = re.compile(rf"^\s*(?P<a>{_ID})\s*{_ATTRS}\s*;?\s*$")
_PAIR = re.compile(rf"(?P<k>[A-Za-z_]\w*)\s*=\s*(?P<v>{_ID}|[-\w.#]+)")
_GRAPH_LABEL = re.compile(rf"^\s*label\s*=\s*(?P<v>{_ID})\s*;")


def _unquote(text: str) -> str:
    if not (text.startswith('"') and text.endswith('"')):
        return text
    out, i, body = [], 0, text[1:-1]
    while i < len(body):
        ch = body[i]
        if ch == "\\" and i + 1 < len(body):
            nxt = body[i + 1]
            out.append("\n" if nxt in "nlr" else nxt)
            i += 2
            continue
        out.append(ch)
        i += 1
    return "".join(out)


def _attrs(text: str | None) -> dict[str, str]:
    return {m["k"]: _unquote(m["v"]) for m in _PAIR.finditer(text or "")}


@dataclass
class Graph:
    nodes: dict[str, dict[str, str]] = field(default_factory=dict)  # id -> attributes, in order
    edges: list[tuple[str, str, dict[str, str]]] = field(default_factory=list)
    label: str = ""


def parse_dot(text: str) -> Graph:
    """The nodes, edges and title of DOT text as odelab writes it (one statement a line)."""
    g = Graph()
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped or stripped.startswith(("digraph", "graph", "}", "//", "node ", "node[", "edge ", "edge[",
                                                "rankdir", "ratio")):
            if stripped.startswith("rankdir") or stripped.startswith("ratio"):
                label = _GRAPH_LABEL.search(stripped)
                if label:
                    g.label = _unquote(label["v"])
            continue
        if (label := _GRAPH_LABEL.match(stripped)) is not None:
            g.label = _unquote(label["v"])
            continue
        if (m := _EDGE.match(stripped)) is not None:
            a, b = _unquote(m["a"]), _unquote(m["b"])
            for n in (a, b):
                g.nodes.setdefault(n, {})
            g.edges.append((a, b, _attrs(m["attrs"])))
        elif (m := _NODE.match(stripped)) is not None:
            g.nodes.setdefault(_unquote(m["a"]), {}).update(_attrs(m["attrs"]))
    return g


def layout(g: Graph) -> tuple[dict[str, tuple[int, int]], set[int]]:
    """Layer and position of each node, and the indices of the edges drawn as feedback arcs."""
    order = list(g.nodes)
    succ: dict[str, list[tuple[str, int]]] = {n: [] for n in order}
    indegree = {n: 0 for n in order}
    for k, (a, b, _) in enumerate(g.edges):
        succ[a].append((b, k))
        indegree[b] += 1
    back: set[int] = set()
    state: dict[str, int] = {}  # 1 on the stack, 2 done
    roots = [n for n in order if indegree[n] == 0] + order
    for root in roots:
        if root in state:
            continue
        stack = [(root, iter(succ[root]))]
        state[root] = 1
        while stack:
            node, it = stack[-1]
            for nxt, k in it:
                if state.get(nxt) == 1:
                    back.add(k)
                elif nxt not in state:
                    state[nxt] = 1
                    stack.append((nxt, iter(succ[nxt])))
                    break
            else:
                state[node] = 2
                stack.pop()
    layer = {n: 0 for n in order}
    forward = [(a, b) for k, (a, b, _) in enumerate(g.edges) if k not in back and a != b]
    for _ in range(len(order)):  # longest path: at most n relaxations of a DAG
        changed = False
        for a, b in forward:
            if layer[b] < layer[a] + 1:
                layer[b] = layer[a] + 1
                changed = True
        if not changed:
            break
    layers: dict[int, list[str]] = {}
    for n in order:
        layers.setdefault(layer[n], []).append(n)
    preds: dict[str, list[str]] = {n: [] for n in order}
    for a, b in forward:
        preds[b].append(a)
    for _ in range(4):  # barycentre sweeps, left to right
        pos = {n: i for nodes in layers.values() for i, n in enumerate(nodes)}
        for depth in sorted(layers)[1:]:
            nodes = layers[depth]
            key = {n: (sum(pos[p] for p in preds[n]) / len(preds[n]) if preds[n] else pos[n]) for n in nodes}
            layers[depth] = sorted(nodes, key=lambda n: (key[n], nodes.index(n)))
            pos.update({n: i for i, n in enumerate(layers[depth])})
    where = {n: (depth, i) for depth, nodes in layers.items() for i, n in enumerate(nodes)}
    return where, back


def draw_png(text: str, *, dpi: int = 96) -> bytes:
    """A PNG of DOT text as odelab writes it, laid out and drawn without Graphviz."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, FancyArrowPatch, FancyBboxPatch, Polygon

    g = parse_dot(text)
    where, back = layout(g)
    dx, dy = 2.2, 1.25  # inches between layers and between rows
    widths = {}
    for n, attrs in g.nodes.items():
        lines = (attrs.get("label") or n).split("\n")
        widths[n] = max(0.5, 0.085 * max(len(s) for s in lines) + 0.25), 0.2 * len(lines) + 0.2
    rows = {}
    for n, (depth, i) in where.items():
        rows.setdefault(depth, []).append(n)
    centre = {n: (depth * dx, -(i - (len(rows[depth]) - 1) / 2) * dy) for n, (depth, i) in where.items()}
    lanes = [k for k, (a, b, _) in enumerate(g.edges) if k in back or centre[b][0] <= centre[a][0]]
    x0 = min((centre[n][0] - widths[n][0] / 2 for n in centre), default=0.0) - 0.3
    x1 = max((centre[n][0] + widths[n][0] / 2 for n in centre), default=0.0) + 0.3
    bottom = min((centre[n][1] - widths[n][1] / 2 for n in centre), default=0.0)
    y0 = bottom - 0.3 - 0.3 * len(lanes)  # one lane under the drawing per feedback edge
    y1 = max((centre[n][1] + widths[n][1] / 2 for n in centre), default=0.0) + 0.5 + (0.3 if g.label else 0)
    xs = [c[0] for c in centre.values()] or [0.0]
    ys = [c[1] for c in centre.values()] or [0.0]
    fig = Figure(figsize=(x1 - x0, y1 - y0), dpi=dpi)  # one unit an inch: circles stay round
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_axis_off()
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    for n, attrs in g.nodes.items():
        x, y = centre[n]
        w, h = widths[n]
        shape = attrs.get("shape", "box")
        label = attrs.get("label") or n
        fill = attrs.get("fillcolor", "white") if "filled" in attrs.get("style", "") else "white"
        if shape == "circle":
            ax.add_patch(Circle((x, y), 0.25, facecolor=fill, edgecolor="#333333", lw=1))
            w = h = 0.5
        elif shape == "triangle":
            ax.add_patch(Polygon([(x - w / 2, y - h / 2 - 0.1), (x - w / 2, y + h / 2 + 0.1), (x + w / 2, y)],
                                 closed=True, facecolor=fill, edgecolor="#333333", lw=1))
        elif shape != "plaintext":
            ax.add_patch(FancyBboxPatch((x - w / 2, y - h / 2), w, h, boxstyle="round,pad=0.02,rounding_size=0.08",
                                        facecolor=fill, edgecolor="#333333", lw=1))
        ax.text(x, y, label, ha="center", va="center", fontsize=9, family="DejaVu Sans")
        if attrs.get("xlabel"):
            ax.text(x, y + max(h, 0.5) / 2 + 0.12, attrs["xlabel"], ha="center", va="bottom", fontsize=8,
                    color="#555555")
        widths[n] = (w, h)
    for k, (a, b, attrs) in enumerate(g.edges):
        (xa, ya), (xb, yb) = centre[a], centre[b]
        wa, wb = widths[a][0], widths[b][0]
        if k in lanes:  # feedback: down from the tail to its lane under the drawing, back, up into the head
            lane = bottom - 0.3 * (lanes.index(k) + 1)
            start, end = (xa, ya - widths[a][1] / 2), (xb, yb - widths[b][1] / 2)
            ax.plot([start[0], start[0], end[0], end[0]], [start[1], lane, lane, lane], color="#333333", lw=1)
            ax.add_patch(FancyArrowPatch((end[0], lane), end, arrowstyle="-|>", mutation_scale=10, lw=1,
                                         color="#333333", shrinkA=0, shrinkB=2))
        else:
            start, end = (xa + wa / 2, ya), (xb - wb / 2, yb)
            ax.add_patch(FancyArrowPatch(start, end, arrowstyle="-|>", mutation_scale=10, lw=1, color="#333333",
                                         shrinkA=2, shrinkB=2))
        if attrs.get("headlabel"):
            ax.text(end[0] - 0.12, end[1] + 0.1, attrs["headlabel"], fontsize=8, ha="right", va="bottom")
        if attrs.get("taillabel"):
            ax.text(start[0] + 0.08, start[1] + 0.1, attrs["taillabel"], fontsize=8, ha="left", va="bottom",
                    color="#555555")
    if g.label:
        ax.text((min(xs) + max(xs)) / 2, max(ys) + 0.6, g.label, ha="center", va="bottom", fontsize=10)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})
    return buffer.getvalue()
