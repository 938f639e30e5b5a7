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

Diagrams whose every port is a scalar and whose blocks are sources, gains (scalar), sums,
products, saturations, dead zones, integrators (scalar, limited or not), state-space and
transfer-function blocks are generated; :func:`why_not` names the first block that is not
(``fcn``, ``mux``, ``demux``, a matrix gain, a vector integrator).
"""

from __future__ import annotations

import numpy as np

from odelab.systems.diagram import blocks as bk

__all__ = ["why_not", "diagram_source"]

_SCALAR = (bk.Gain, bk.Sum, bk.Product, bk.Saturation, bk.DeadZone, bk.Integrator, bk._Linear)


def why_not(diagram) -> str | None:
    """Why the compiled backend cannot generate this diagram (None if it can)."""
    w = diagram.wiring
    reason = diagram.hybrid_reason()
    if reason:
        return reason
    for name in w.order:
        b = w.blocks[name]
        if b.SOURCE:
            continue
        if not isinstance(b, _SCALAR) or (isinstance(b, bk.Gain) and b.K.ndim != 0):
            return f"its block `{name}` ({b.TYPE}) is evaluated in Python only"
        if any(w.widths[port] != 1 for port in w.sources[name]) or (
                isinstance(b, bk.Integrator) and b.nstates != 1):
            return f"its block `{name}` carries a vector signal, which the compiled engine does not generate"
    return None


def diagram_source(diagram, data: list[float], offset: int) -> list[str]:
    """The body of ``rhs(t, _y, _p, _out)`` after the input lines; the blocks' numbers are
    appended to ``data``, which starts at ``_p[offset]``."""
    w = diagram.wiring
    lines: list[str] = []
    port: dict[tuple[str, int], str] = {(name, 0): f"_u{i}" for i, name in enumerate(diagram.inputs)}
    fresh = iter(range(10 ** 9))

    def number(value: float) -> str:
        data.append(float(value))
        return f"_p[{offset + len(data) - 1}]"

    def var(text: str) -> str:
        name = f"_v{next(fresh)}"
        lines.append(f"    {name} = {text}")
        return name

    def state(name: str, i: int) -> str:
        return f"_y[{diagram.slices[name].start + i}]"

    def accumulate(first: str, terms) -> str:
        """``first``, then each ``(op, term)`` applied left to right, one statement per term:
        the order of numpy's sums, in flat code (a 5,000-input sum written as one nested
        expression is too deep for Python's compiler)."""
        acc = var(first)
        for op, term in terms:
            lines.append(f"    {acc} = {acc} {op} {term}")
        return acc

    def linear_part(M: np.ndarray, row: int, values: list[str]) -> str:
        """numpy's tensordot of one row: sum_j M[row, j] * values[j], left to right from 0.0."""
        return accumulate("0.0", (("+", f"{number(M[row, j])} * {v}") for j, v in enumerate(values)))

    for name in w.order:
        b = w.blocks[name]
        if b.SOURCE:
            continue
        ins = [port[p] for p in w.sources[name]] if b.feedthrough else []
        if isinstance(b, bk.Gain):
            port[(name, 0)] = var(f"{number(b.K)} * {ins[0]}")
        elif isinstance(b, bk.Sum):
            port[(name, 0)] = accumulate(f"{number(b.signs[0])} * {ins[0]}",
                                         (("+" if s > 0 else "-", v) for s, v in zip(b.signs[1:], ins[1:])))
        elif isinstance(b, bk.Product):
            port[(name, 0)] = accumulate(ins[0] if b.ops[0] == "*" else f"(1.0 / {ins[0]})",
                                         zip(b.ops[1:], ins[1:]))
        elif isinstance(b, bk.Saturation):
            lo, hi = number(b.lo), number(b.hi)
            v = ins[0]
            port[(name, 0)] = var(f"({hi} if {v} > {hi} else ({lo} if {v} < {lo} else {v}))")
        elif isinstance(b, bk.DeadZone):
            lo, hi = number(b.lo), number(b.hi)
            v = ins[0]
            port[(name, 0)] = var(f"(({v} - {hi}) if {v} > {hi} else (({v} - {lo}) if {v} < {lo} else 0.0 * {v}))")
        elif isinstance(b, bk.Integrator):
            x = state(name, 0)
            if b.limited:
                lo, hi = number(b.lo), number(b.hi)
                port[(name, 0)] = var(f"({hi} if {x} > {hi} else ({lo} if {x} < {lo} else {x}))")
            else:
                port[(name, 0)] = var(x)
        else:  # state-space or transfer-fcn: y = C x (+ D u), one scalar port per output
            xs = [state(name, i) for i in range(b.nstates)]
            for i in range(len(b.ports())):
                text = linear_part(b.C, i, xs) if b.nstates else "0.0"
                if b.feedthrough:
                    text = f"({text} + {linear_part(b.D, i, ins)})"
                port[(name, i)] = var(text)

    for name, where in diagram.slices.items():
        b = w.blocks[name]
        ins = [port[p] for p in w.sources[name]]
        if isinstance(b, bk.Integrator):
            x, v = state(name, 0), ins[0]
            if b.limited:
                lo, hi = number(b.lo), number(b.hi)
                held = f"(({x} >= {hi}) and ({v} > 0)) or (({x} <= {lo}) and ({v} < 0))"
                lines.append(f"    _out[{where.start}] = (0.0 * {v}) if {held} else {v}")
            else:
                lines.append(f"    _out[{where.start}] = {v}")
        else:
            xs = [state(name, i) for i in range(b.nstates)]
            for i in range(b.nstates):
                lines.append(f"    _out[{where.start + i}] = ({linear_part(b.A, i, xs)} + "
                             f"{linear_part(b.B, i, ins)})")
    return lines
