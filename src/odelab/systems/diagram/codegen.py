"""A diagram's right-hand side as numba source, for the compiled backend.

:class:`~odelab.systems.diagram.compile.CompiledDiagram` evaluates a diagram block by block in
Python; this module writes the same evaluation out as straight-line code: each port a scalar
variable (``_v0, _v1, ...``) computed in the wiring's order, then each block's derivative into
``_out``, every operation in the order of the block's ``outputs``/``derivative`` (a sum adds its
inputs left to right with their signs, a saturation compares with ``>`` then ``<``, a
state-space block sums ``C x`` then adds ``D u``). The sources are the inputs ``_u0, _u1...``
of :mod:`odelab.solvers.compiled.inputs` (read at t clipped to the piece), and every number of a
block (gains, limits, matrices) is run-time data in the parameter vector, never pasted into the
text, so two cases with other gains share one build. Names of blocks never reach the source.

Each block writes its own lines (``Block.generate_outputs`` / ``generate_derivative``, with the
:class:`Writer` here); a block that does not (``generated`` False: ``fcn``, ``mux``, ``demux``,
a matrix gain, the switching and discrete blocks of the hybrid driver) is named by
:func:`why_not`, as is a vector signal.
"""

from __future__ import annotations

import numpy as np

__all__ = ["why_not", "diagram_source"]

class Writer:
    """What a block's :meth:`~odelab.systems.diagram.blocks.Block.generate` writes with: run-time
    numbers (``number``), fresh scalar variables (``var``), the state entries (``state``) and
    the lines of the function body (``lines``)."""

    def __init__(self, diagram, data: list[float], offset: int):
        self.diagram, self.data, self.offset = diagram, data, offset
        self.lines: list[str] = []
        self._fresh = iter(range(10 ** 9))

    def number(self, value: float) -> str:
        self.data.append(float(value))
        return f"_p[{self.offset + len(self.data) - 1}]"

    def var(self, text: str) -> str:
        name = f"_v{next(self._fresh)}"
        self.lines.append(f"    {name} = {text}")
        return name

    def state(self, name: str, i: int) -> str:
        return f"_y[{self.diagram.slices[name].start + i}]"

    def derivative(self, name: str, i: int, text: str) -> None:
        self.lines.append(f"    _out[{self.diagram.slices[name].start + i}] = {text}")

    def accumulate(self, first: str, terms) -> str:
        """``first``, then each ``(op, term)`` applied left to right, one statement per term:
        the order of numpy's sums, in flat code (a 5,000-input sum written as one nested
        expression is too deep for Python's compiler)."""
        acc = self.var(first)
        for op, term in terms:
            self.lines.append(f"    {acc} = {acc} {op} {term}")
        return acc

    def linear_part(self, M: np.ndarray, row: int, values: list[str]) -> str:
        """numpy's tensordot of one row: sum_j M[row, j] * values[j], left to right from 0.0."""
        return self.accumulate("0.0", (("+", f"{self.number(M[row, j])} * {v}") for j, v in enumerate(values)))


def why_not(diagram) -> str | None:
    """Why the compiled backend cannot generate this diagram (None if it can)."""
    w = diagram.wiring
    reason = diagram.hybrid_reason()
    if reason:
        return reason
    if w.torn:
        return f"its algebraic loop {w.loops[0]} is solved by Newton's method in Python"
    for name in w.order:
        b = w.blocks[name]
        if b.SOURCE:
            continue
        if not b.generated:
            return f"its block `{name}` ({b.TYPE}) is evaluated in Python only"
        if any(w.widths[port] != 1 for port in w.sources[name]) or b.nstates > 1 and b.TYPE == "integrator":
            return f"its block `{name}` carries a vector signal, which the compiled engine does not generate"
    return None


def diagram_source(diagram, data: list[float], offset: int) -> list[str]:
    """The body of ``rhs(t, _y, _p, _out)`` after the input lines; the blocks' numbers are
    appended to ``data``, which starts at ``_p[offset]``. Each block writes its own lines
    (:meth:`~odelab.systems.diagram.blocks.Block.generate_outputs` in the wiring's order, then
    :meth:`~odelab.systems.diagram.blocks.Block.generate_derivative`)."""
    w = diagram.wiring
    g = Writer(diagram, data, offset)
    port: dict[tuple[str, int], str] = {(name, 0): f"_u{i}" for i, name in enumerate(diagram.inputs)}
    for name in w.order:
        b = w.blocks[name]
        if b.SOURCE:
            continue
        ins = [port[p] for p in w.sources[name]] if b.feedthrough else []
        for i, v in enumerate(b.generate_outputs(g, name, ins)):
            port[(name, i)] = v
    for name in diagram.slices:
        b = w.blocks[name]
        b.generate_derivative(g, name, [port[p] for p in w.sources[name]])
    return g.lines
