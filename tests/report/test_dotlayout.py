"""Drawing odelab's DOT text without Graphviz (report/dotlayout.py): the layers follow the
signal flow, feedback edges are found, the drawing is deterministic and reads nothing else."""

from pathlib import Path

from odelab.experiment.loader import load_experiment
from odelab.run.runner import diagram_record
from odelab.report.dotlayout import draw_png, layout, parse_dot

ROOT = Path(__file__).resolve().parents[2]


def figure1_dot() -> str:
    case = load_experiment(ROOT / "experiments" / "figure1.toml").cases[0]
    return diagram_record(case.problem)["dot"]


def test_the_layers_follow_the_signal_flow_and_feedback_is_found():
    g = parse_dot(figure1_dot())
    where, back = layout(g)
    layer = {name.removeprefix("b:").removeprefix("o:"): depth for name, (depth, _) in where.items()}
    assert [layer[n] for n in ("force", "net", "accel", "velocity", "position")] == [0, 1, 2, 3, 4]
    assert layer["damping"] == layer["velocity"] + 1 and layer["spring"] == layer["position"] + 1
    fed_back = {(g.edges[k][0], g.edges[k][1]) for k in back}
    assert fed_back == {("b:damping", "b:net"), ("b:spring", "b:net")}
    labels = {n: a.get("label") for n, a in g.nodes.items()}
    assert labels["b:net"] == "Σ" and labels["b:velocity"] == "velocity\n1/s"
    signs = [a.get("headlabel") for _, b, a in g.edges if b == "b:net"]
    assert signs == ["+", "−", "−"]


def test_the_drawing_is_a_deterministic_png():
    dot = figure1_dot()
    first, second = draw_png(dot), draw_png(dot)
    assert first.startswith(b"\x89PNG") and first == second


def test_attributes_outside_the_subset_are_ignored(tmp_path):
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"\x89PNG not an image")
    dot = f'digraph d {{\n  "a" [label="a", image="{secret}", shape=box];\n  "a" -> "b";\n}}\n'
    png = draw_png(dot)
    assert png.startswith(b"\x89PNG") and b"not an image" not in png
    assert set(parse_dot(dot).nodes) == {"a", "b"}
