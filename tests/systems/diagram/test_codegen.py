"""A diagram's generated right-hand side (the compiled backend) computes what its blocks compute."""

import numpy as np
import pytest

from odelab import diagram as dg
from odelab.signals import Ramp, Sine, Step
from odelab.solvers.compiled import CompiledSystem
from odelab.systems.diagram.codegen import diagram_source, why_not


def every_block():
    """A nonlinear loop with each block type the generator writes out, and a Clock."""
    return dg.Diagram({
        "ref": Step(time=0.5, initial=-1.0, final=2.0),
        "wind": Sine(amplitude=0.3, frequency=2.0),
        "clock": dg.Clock(),
        "err": dg.Sum(signs="+-+", inputs=["ref", "plant.y", "wind"]),
        "pi": dg.TransferFcn(num=[2.0, 1.5], den=[1.0, 0.0], input="err"),
        "lim": dg.Saturation(lower=-1.5, upper=1.2, input="pi"),
        "dz": dg.DeadZone(lower=-0.1, upper=0.2, input="lim"),
        "scale": dg.Gain(gain=0.7, input="dz"),
        "mult": dg.Product(ops="*/", inputs=["scale", "growth"]),
        "growth": dg.Sum(signs="++", inputs=["clock", "one"]),
        "one": Step(time=-1.0),
        "plant": dg.StateSpace(A=[[0, 1], [-3, -4]], B=[[0], [1]], C=[[10, 0]], input="mult", outputs=["y"]),
        "meter": dg.StateSpace(A=[[-1.0]], B=[[1.0, 2.0]], C=[[2.0]], D=[[0.5, -1.0]], inputs=["plant.y", "wind"],
                               outputs=["m"]),
        "store": dg.Integrator(input="plant.y", lower=-2.0, upper=2.0, initial=0.5),
        "free": dg.Integrator(input="err"),
    }, {"y": "plant.y", "s": "store", "f": "free", "m": "meter.m"}).compile(zero_crossing=False)


def rhs_of(diagram):
    data: list[float] = []
    body = diagram_source(diagram, data, 2)
    system = CompiledSystem.generated(diagram.states, diagram.inputs, body, data).with_signals(diagram.signals)
    return system.module().rhs, system


def test_the_generated_rhs_is_the_blocks_evaluation():
    d = every_block()
    assert why_not(d) is None and not d.linear
    rhs, system = rhs_of(d)
    rng = np.random.default_rng(3)
    out = np.empty(len(d.states))
    for t in [0.0, 0.5, 1.3, *rng.uniform(-1, 5, 200)]:
        x = rng.uniform(-3, 3, len(d.states))
        x[list(d.states).index("store")] = rng.choice([-2.0, 2.0, 0.3])  # at the limits too
        u = np.array([s(t) for s in d.signals])
        rhs(float(t), x, system.parameter_vector(), out)
        np.testing.assert_allclose(out, d.dynamics(t, x, u), rtol=1e-14, atol=1e-14)


def test_a_piece_reads_its_sources_inside_it():
    d = every_block()
    rhs, system = rhs_of(d)
    x = np.full(len(d.states), 0.1)
    a, b = np.empty(len(d.states)), np.empty(len(d.states))
    rhs(0.5, x, system.parameter_vector(0.0, np.nextafter(0.5, 0.0)), a)  # the step not yet taken
    lo = np.nextafter(0.5, 0.0)
    rhs(0.5, x, system.parameter_vector(), b)
    u_before = np.array([s(lo) for s in d.signals])
    np.testing.assert_allclose(a, d.dynamics(0.5, x, u_before), rtol=1e-14, atol=1e-14)
    assert not np.allclose(a, b)


@pytest.mark.parametrize("block, reason", [
    (dg.Fcn(expression="u^2", input="ref"), "its block `extra` (fcn) is evaluated in Python only"),
    (dg.Gain(gain=[2.0], input="ref"), "its block `extra` (gain) is evaluated in Python only"),
])
def test_blocks_the_generator_does_not_write_are_named(block, reason):
    d = dg.Diagram({"ref": Ramp(), "extra": block, "x": dg.Integrator(input="ref"),
                    "sq": dg.Saturation(input="x")}, {"y": "sq", "e": "extra"}).compile(zero_crossing=False)
    assert why_not(d) == reason
