"""Wiring: references, algebraic loops (found and printed in order, or broken by state), order."""

import pytest

from odelab import diagram as dg
from odelab.signals import Step


def fig1(**override):
    blocks = {
        "force": Step(time=0),
        "net": dg.Sum(signs="+--", inputs=["force", "damping", "spring"]),
        "accel": dg.Gain(gain=1.0, input="net"),
        "velocity": dg.Integrator(input="accel"),
        "position": dg.Integrator(input="velocity"),
        "damping": dg.Gain(gain=4.0, input="velocity"),
        "spring": dg.Gain(gain=3.0, input="position"),
    }
    blocks.update(override)
    return dg.Diagram(blocks, {"x": "position"})


def test_order_puts_every_feedthrough_input_first():
    w = fig1().compile().wiring
    pos = {n: i for i, n in enumerate(w.order)}
    for name, feeds in w.sources.items():
        if w.blocks[name].feedthrough:
            assert all(pos[src] < pos[name] for src, _ in feeds), name
    assert w.order.index("net") < w.order.index("accel")


def test_algebraic_loop_is_printed_in_signal_flow_order():
    d = fig1(net=dg.Sum(signs="+--+", inputs=["force", "damping", "spring", "accel"]))
    with pytest.raises(dg.DiagramError, match=r"^algebraic loop: net -> accel -> net; break it with an integrator"):
        d.compile(algebraic_loops="error")
    # a three-block loop, started at the block declared first
    d = fig1(damping=dg.Gain(gain=4.0, input="net"))
    with pytest.raises(dg.DiagramError, match=r"^algebraic loop: net -> damping -> net;"):
        d.compile(algebraic_loops="error")
    with pytest.raises(dg.DiagramError, match=r"^algebraic loop: g -> g;"):
        dg.Diagram({"g": dg.Gain(gain=2.0, input="g"), "i": dg.Integrator(input="g")}, {"i": "i"}).compile(
            algebraic_loops="error")


def test_loops_broken_by_state_are_accepted():
    # Figure 1 itself has two loops, each through an integrator.
    assert fig1().compile().states == ("velocity", "position")
    # a loop through a strictly proper transfer-fcn and one through a state-space block with D = 0
    for plant in (dg.TransferFcn(num=[1], den=[1, 1], input="e"),
                  dg.StateSpace(A=-1, B=1, C=1, input="e")):
        c = dg.Diagram({"r": Step(time=0), "e": dg.Sum(signs="+-", inputs=["r", "p"]), "p": plant},
                       {"y": "p"}).compile()
        assert c.linear and c.matrices()[0].tolist() == [[-2.0]]
    # ... but a biproper transfer-fcn has direct feedthrough: the loop is algebraic
    with pytest.raises(dg.DiagramError, match=r"^algebraic loop: e -> p -> e;"):
        dg.Diagram({"r": Step(time=0), "e": dg.Sum(signs="+-", inputs=["r", "p"]),
                    "p": dg.TransferFcn(num=[1, 2], den=[1, 1], input="e")}, {"y": "p"}).compile(
            algebraic_loops="error")


def test_reference_errors():
    with pytest.raises(dg.DiagramError, match=r"`blocks.position.input`: 'velocty' is not a block of the diagram\. "
                                              r"Did you mean `velocity`\?"):
        fig1(position=dg.Integrator(input="velocty")).compile()
    ss = dg.StateSpace(A=-1, B=1, C=[[1], [2]], outputs=["y", "z"], input="force")
    with pytest.raises(dg.DiagramError, match=r"`blocks.g.input`: block 'p' has 2 outputs; name one: p.y, p.z\."):
        dg.Diagram({"force": Step(), "p": ss, "g": dg.Gain(gain=1, input="p")}, {"g": "g"}).compile()
    with pytest.raises(dg.DiagramError, match=r"block 'spare' is not connected"):
        fig1(spare=dg.Gain(gain=1.0, input="position")).compile()
    with pytest.raises(dg.DiagramError, match=r"`blocks.k.gain` is 2x2 but its input has width 1"):
        dg.Diagram({"f": Step(), "k": dg.Gain(gain=[[1, 2], [3, 4]], input="f"), "i": dg.Integrator(input="k")},
                   {"i": "i"}).compile()
    stateless = dg.Diagram({"f": Step(), "k": dg.Gain(gain=2, input="f")}, {"k": "k"}).compile()
    assert stateless.states == () and not stateless.linear  # evaluated at its output times (issue 41), not refused
