"""A new diagram block is one class in one file: a toy one registered here is used from TOML.

The toy is ``power`` (y = scale u^n with a whole exponent n, default 2). Registered with
``@register`` inside the test, it is validated and built by the loader from an experiment
file (its keys, defaults and parameter expressions), run and stored by ``odelab run``, drawn in
the diagram's DOT text, written out by the compiled backend's code generator, listed by
``odelab explain`` and offered by the did-you-mean of a misspelt type: nothing else names it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.systems.diagram.base import BLOCKS, Block, BlockError, Key, register


class Power(Block):
    """y = scale u^n: a static power law (a square-law sensor, a drag force)."""

    TYPE = "power"
    LINEAR = False
    KEYS = {"scale": Key("number", 1.0, "the factor in front"),
            "n": Key("count", 2, "the whole exponent (>= 1)")}
    DOC = "y = scale * u^n"

    def check(self):
        self.scale = float(self.params["scale"])
        n = self.params["n"]
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise BlockError(f"`n` must be a whole number >= 1; got {n!r}.", key="n")
        self.n = n

    def setup(self, widths):
        return [widths[0]]

    def outputs(self, t, x, u, cplx=False):
        return [self.scale * u[0] ** self.n]

    def generate_outputs(self, g, name, ins):
        return [g.var(f"{g.number(self.scale)} * {ins[0]} ** {self.n}")]

    def label(self, name):
        return f"{name}\n{self.scale:g} u^{self.n}"


FILE = """
name = "toy_power"
[parameters]
k = 0.5
[system]
kind = "diagram"
outputs = { y = "acc" }
[blocks]
drive = { type = "ramp", slope = 1 }
law = { type = "power", scale = "3*k", input = "drive" }
acc = { type = "integrator", input = "law" }
[time]
stop = 2
[exact]
y = "0.5*t^3"   # y' = 3 k t^2 with k = 0.5, y(0) = 0
[solver]
method = "ode45"
rtol = 1e-8
atol = 1e-10
"""


@pytest.fixture
def power():
    register(Power)
    try:
        yield Power
    finally:
        BLOCKS.pop("power", None)


def test_a_registered_block_runs_from_toml(power, tmp_path):
    (tmp_path / "toy.toml").write_text(FILE)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "toy.toml"), "--runs", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    record = json.loads((tmp_path / "runs" / "toy_power" / "ode45" / "result.json").read_text())
    assert record["config"]["blocks"]["law"]["type"] == "power"
    assert record["errors"]["y"]["max_abs"] / 4.0 < 1e-6  # y(2) = 4; the toy's value 3k = 1.5 reached it


def test_the_registered_block_is_drawn_and_generated(power):
    from odelab import diagram as dg
    from odelab.signals import Ramp
    from odelab.solvers.compiled import CompiledSystem
    from odelab.systems.diagram.codegen import diagram_source, why_not
    from odelab.systems.diagram.draw import to_dot

    d = dg.Diagram({"drive": Ramp(slope=1.0), "law": Power(scale=1.5, n=3, input="drive"),
                    "acc": dg.Integrator(input="law")}, {"y": "acc"}).compile(zero_crossing=False)
    assert "law\\n1.5 u^3" in to_dot(d.wiring)
    assert why_not(d) is None
    data: list[float] = []
    system = CompiledSystem.generated(d.states, d.inputs, diagram_source(d, data, 2), data).with_signals(d.signals)
    rhs, out = system.module().rhs, np.empty(1)
    for t in (0.0, 0.7, 1.9):
        rhs(t, np.array([0.3]), system.parameter_vector(), out)
        assert out[0] == pytest.approx(1.5 * t ** 3, rel=1e-15, abs=1e-300)


def test_explain_and_messages_know_the_registered_block(power, tmp_path):
    from odelab.exceptions import InputError
    from odelab.experiment.keyref import explain
    from odelab.experiment.loader import load_experiment

    text = explain("blocks.power")
    assert "y = scale u^n" in text and "keys: scale, n" in text  # its docstring, its KEYS
    assert "default: 2" in explain("blocks.power.n")
    (tmp_path / "typo.toml").write_text(FILE.replace('type = "power"', 'type = "powr"'))
    with pytest.raises(InputError) as info:
        load_experiment(tmp_path / "typo.toml")
    assert info.value.key == "blocks.law.type" and "Did you mean 'power'?" in info.value.message
    (tmp_path / "bad.toml").write_text(FILE.replace('input = "drive"', 'n = 0, input = "drive"'))
    with pytest.raises(InputError) as info:  # the file, the key, the value, the rule
        load_experiment(tmp_path / "bad.toml")
    assert info.value.key == "blocks.law.n"
    assert str(info.value).endswith("bad.toml: `blocks.law.n` must be a whole number >= 1; got 0.")


def test_a_block_class_without_a_type_is_refused():
    class Nameless(Block):
        pass

    with pytest.raises(TypeError, match="Nameless needs a TYPE"):
        register(Nameless)
    assert "" not in BLOCKS
