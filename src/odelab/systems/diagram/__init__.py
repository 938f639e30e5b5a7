"""Block diagrams, Simulink-style: named blocks, each naming the blocks that feed it.

In Python (``odelab.diagram``)::

    from odelab import diagram as dg
    from odelab.signals import Step

    d = dg.Diagram({
        "force": Step(time=0),                       # any odelab.signals signal is a source
        "net": dg.Sum(signs="+--", inputs=["force", "damping", "spring"]),
        "accel": dg.Gain(gain=1.0, input="net"),
        "velocity": dg.Integrator(input="accel"),
        "position": dg.Integrator(input="velocity"),
        "damping": dg.Gain(gain=4.0, input="velocity"),
        "spring": dg.Gain(gain=3.0, input="position"),
    }, outputs={"x": "position"}, states=["position", "velocity"])
    c = d.compile()            # c.system is a StateSpace here (every block is linear)
    r = c.simulate([0, 10])

In experiment files the same diagram is a ``[blocks]`` table (see the README). The block types
are :data:`BLOCKS` (plus the signal sources).
"""

from __future__ import annotations

from collections.abc import Mapping

from odelab.signals import Signal
from odelab.systems.diagram.blocks import (
    BLOCKS, Block, BlockError, Clock, DeadZone, Demux, Fcn, Gain, Integrator, Mux, Product, Saturation, Source,
    StateSpaceBlock, Sum, TransferFcn,
)
from odelab.systems.diagram.compile import CompiledDiagram
from odelab.systems.diagram.graph import DiagramError, Wiring, wire

StateSpace = StateSpaceBlock  # the block, as Simulink names it (odelab.StateSpace is the system)

__all__ = ["BLOCKS", "Block", "BlockError", "Clock", "CompiledDiagram", "DeadZone", "Demux", "Diagram",
           "DiagramError", "Fcn", "Gain", "Integrator", "Mux", "Product", "Saturation", "Source", "StateSpace",
           "StateSpaceBlock", "Sum", "TransferFcn", "Wiring", "wire"]


class Diagram:
    """A block diagram: ``blocks`` (name -> block, or an odelab signal for a source),
    ``outputs`` (output name -> block or ``block.port``), and optionally the order of the
    blocks with state (``states``)."""

    def __init__(self, blocks: Mapping | None = None, outputs: Mapping[str, str] | None = None, *,
                 states: list[str] | None = None):
        self.blocks: dict[str, Block] = {}
        for name, block in (blocks or {}).items():
            self.add(name, block)
        self.outputs = dict(outputs or {})
        self.states = None if states is None else list(states)

    def add(self, name: str, block) -> "Diagram":
        """Add a block (or a signal, as a source block); returns the diagram."""
        if isinstance(block, Signal):
            block = Source(block, kind=type(block).__name__.lower())
        if not isinstance(block, Block):
            raise DiagramError(f"block {name!r} must be a diagram block or an odelab signal; got {block!r}.",
                               key=f"blocks.{name}")
        self.blocks[name] = block
        return self

    def compile(self, *, t0: float = 0.0, zero_crossing: bool = True,
                algebraic_loops: str = "warning") -> CompiledDiagram:
        """Check the wiring (raises DiagramError) and compile to a system; ``zero_crossing=False``
        turns zero-crossing detection off for every block (as ``[solver] zero_crossing``);
        ``algebraic_loops`` is ``"warning"`` (solve them, with a note), ``"none"`` (solve them
        quietly) or ``"error"`` (refuse them), as ``[system] algebraic_loops``."""
        return CompiledDiagram(wire(self.blocks, self.outputs, algebraic_loops), states=self.states, t0=t0,
                               zero_crossing=zero_crossing, loop_note=algebraic_loops != "none")
