"""Simulink's Transport Delay block, and diagrams that hold one, solved as delay equations by dde23.

``transport-delay`` (``delay`` T > 0, ``initial`` output before the delay has elapsed, Simulink's
names) outputs its input as it was T seconds earlier: ``y(t) = u(t - T)`` for ``t >= t0 + T``,
``initial`` before. It has no direct feedthrough (its output at t does not depend on its input
at t), so it opens algebraic loops as an integrator does.

**How a diagram with transport delays runs.** Not with a buffer of past inputs on the
diagram's driver, but as delay equations for :func:`odelab.dde23` (the same machinery as
``lag(x, tau)`` in equations), because the delayed input is a function of the *state* at
``t - T``: ``u(t - T) = g(t - T, x(t - T))``, with g one evaluation of the diagram. dde23 keeps
the state's Hermite interpolant of the whole past and its error control sees the delayed
values; a buffer of the input would need its own interpolation, with an error nobody controls.
Each evaluation at ``(t, x, Z)`` (``Z[:, j] = x(t - T_j)``) first evaluates the diagram at
``t - T_j`` with the state ``Z[:, j]`` to get each delay block's input there, then the diagram at
``(t, x)`` with those outputs. The delay's output jumps at ``t0 + T`` (from ``initial`` to
``u(t0)``), a point dde23 tracks anyway (the derivative's jump at t0, one lag on); every source
jumps at its breakpoints, which are dde23's ``Jumps``: the solver steps exactly onto them and
onto their echoes ``+ T``, ``+ 2T``, ... (four levels).

Limits, each refused with its reason: the input of a transport delay may not depend at the same
instant on a transport delay's output (two delays in series: write one with the sum of the
delays); no algebraic loops, switching blocks with zero-crossing detection, or discrete blocks
in the same diagram yet.

**Linearisation** replaces each delay by its Pade approximation of order ``pade_order``
(default 2, as Simulink's ``linmod``; python-control's ``control.pade`` gives the same
coefficients): :func:`pade_state_space`.
"""

from __future__ import annotations

import math
import numpy as np

from odelab.exceptions import InputError
from odelab.solvers.registry import DELAY_METHOD
from odelab.systems.diagram.blocks import Gain, TransferFcn
from odelab.systems.diagram.compile import CompiledDiagram
from odelab.systems.diagram.graph import wire
from odelab.systems.diagram.transport import TransportDelay

__all__ = ["TransportDelay", "DelayDiagram", "pade_coefficients", "pade_state_space"]


class DelayDiagram:
    """A compiled diagram with transport delays, as the delay equations :func:`odelab.dde23` solves.

    Offers what :func:`odelab.solve` (method ``dde23``) takes: ``lags``, ``ddefun(t, x, Z)``,
    ``history(x0)`` and ``jumps``; after a run, :meth:`output_many` gives the diagram's outputs
    (the delays' outputs come from the solution at ``t - T``).
    """

    method = DELAY_METHOD

    def __init__(self, diagram, t0: float):
        self.diagram = diagram
        w = diagram.wiring
        blocks = w.blocks
        self.t0 = float(t0)
        self.delays = [n for n in w.order if isinstance(blocks[n], TransportDelay)]
        if not self.delays:
            raise ValueError("no transport-delay block")
        first = self.delays[0]
        if w.torn:
            raise InputError(f"a diagram with a transport delay (`{first}`) and an algebraic loop "
                             f"({'; '.join(w.loops)}) is not supported yet: break the loop with a dynamic block.",
                             key=f"blocks.{first}")
        for name in w.order:
            b = blocks[name]
            if b.DISCRETE or b.STATEFUL_MODE or (diagram.zero_crossing and b.zero_crossing):
                raise InputError(f"a diagram with a transport delay (`{first}`) and the {b.TYPE} block `{name}` "
                                 "(discrete or switching, run by the hybrid driver) is not supported yet"
                                 + ("; zero_crossing = false on it runs it" if b.ZC else "") + ".",
                                 key=f"blocks.{name}")
        for name in self.delays:
            upstream = self._feedthrough_sources(name)
            hit = [n for n in upstream if n in self.delays]
            if hit:
                raise InputError(f"the input of transport delay `{name}` depends at the same instant on the output of "
                                 f"transport delay `{hit[0]}` (delays in series): write one transport-delay whose "
                                 "delay is their sum.", key=f"blocks.{name}")
        lags: list[float] = []
        self.column = {}
        for name in self.delays:
            T = blocks[name].T
            if T not in lags:
                lags.append(T)
            self.column[name] = lags.index(T)
        self.lags = np.array(lags)
        self.states = diagram.states
        self.signals = diagram.signals
        self._nan = {n: [np.full(blocks[n].y0.size, np.nan)] for n in self.delays}
        self._solution = None

    def _feedthrough_sources(self, name: str) -> set[str]:
        """The blocks whose outputs reach ``name``'s input at the same instant (through feedthrough blocks)."""
        w = self.diagram.wiring
        seen: set[str] = set()
        stack = [src for src, _ in w.sources[name]]
        while stack:
            b = stack.pop()
            if b in seen:
                continue
            seen.add(b)
            if w.blocks[b].feedthrough:
                stack.extend(src for src, _ in w.sources[b])
        return seen

    def _u(self, t: float) -> np.ndarray:
        return np.array([float(np.ravel(s(t))[0]) for s in self.signals])

    def _delayed_outputs(self, t: float, past) -> dict:
        """Each delay block's output at ``t``: ``initial`` before ``t0 + T``, else its input at ``t - T``
        from the diagram evaluated at ``t - T`` with the state ``past(name, t - T)``."""
        w = self.diagram.wiring
        z = {}
        for name in self.delays:
            b = w.blocks[name]
            s = t - b.T
            if s < self.t0:
                z[name] = [b.y0]
            else:
                vals = self.diagram._sweep(s, past(name, s), self._u(s), False, None, self._nan)
                v = np.ravel(vals[w.sources[name][0]])
                z[name] = [np.broadcast_to(v, (b.y0.size,)) if v.size == 1 else v]
        return z

    def ddefun(self, t, x, Z):
        """x' at ``t`` from the state ``x`` and the delayed states ``Z[:, j] = x(t - lags[j])``."""
        d = self.diagram
        w = d.wiring
        z = self._delayed_outputs(t, lambda name, s: Z[:, self.column[name]])
        vals = d._sweep(t, x, self._u(t), False, None, z)
        return np.concatenate([w.blocks[n].derivative(t, x[sl], [vals[p] for p in w.sources[n]])
                               for n, sl in d.slices.items()])

    def jumps(self, t0: float, tf: float) -> np.ndarray:
        """dde23's ``Jumps``: the sources' breakpoints inside the span. (A delay's output that jumps
        at t0 + T from ``initial`` makes only the derivative jump there, at a point dde23 tracks
        anyway: t0 plus a lag.)"""
        cuts = [np.asarray(s.breakpoints(float(t0), float(tf)), dtype=float) for s in self.signals]
        return np.unique(np.concatenate([np.empty(0), *cuts]))

    def history(self, x0):
        return np.asarray(x0, dtype=float).copy()

    def remember(self, solution) -> None:
        """Keep the run's solution (its Hermite interpolant): the outputs need the state at t - T."""
        self._solution = solution

    def __call__(self, t, x):
        raise InputError("this diagram has a transport delay: it is solved by dde23, which gives the delayed "
                         "values; use method = \"dde23\" (or \"auto\").", key="fun")

    def output_many(self, t, x, u=None) -> np.ndarray:
        """The diagram's outputs at the times ``t`` (N,) with the states ``x`` (N, nx)."""
        d = self.diagram
        sol = self._solution
        if sol is None:
            raise InputError("the outputs of a diagram with a transport delay come from its solution: solve it first.")
        t = np.atleast_1d(np.asarray(t, dtype=float))
        x = np.asarray(x, dtype=float).reshape(t.size, -1)
        lo = float(sol.interpolant.t_start)
        rows = []
        for i in range(t.size):
            z = self._delayed_outputs(float(t[i]), lambda name, s: sol.interpolant(max(s, lo)))
            vals = d._sweep(float(t[i]), x[i], self._u(float(t[i])), False, None, z)
            rows.append([float(np.ravel(vals[p])[0]) for p in d.wiring.outputs.values()])
        return np.array(rows, dtype=float).reshape(t.size, len(d.outputs))


# --- linearisation --------------------------------------------------------------------------------


def pade_coefficients(T: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The [n/n] Pade approximation of exp(-T s): (num, den) in descending powers of s, den monic.

    num_k = (2n - k)! n! / ((2n)! k! (n - k)!) (-T)^k for the s^k term (den the same with +T), as
    python-control's ``pade`` and MATLAB's ``pade`` compute them.
    """
    if n == 0:
        return np.array([1.0]), np.array([1.0])
    c = [math.factorial(2 * n - k) * math.factorial(n) / (math.factorial(2 * n) * math.factorial(k)
                                                            * math.factorial(n - k)) for k in range(n + 1)]
    num = np.array([c[k] * (-T) ** k for k in range(n + 1)][::-1])
    den = np.array([c[k] * T ** k for k in range(n + 1)][::-1])
    return num / den[0], den / den[0]


def pade_state_space(T: float, n: int):
    """A, B, C, D (controllable canonical form) of the order-n Pade approximation of exp(-T s)."""
    num, den = pade_coefficients(T, n)
    if n == 0:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[1.0]])
    a = den[1:]  # den = s^n + a1 s^(n-1) + ... + an
    d = num[0]
    b = num[1:] - d * a  # strictly proper part
    A = np.zeros((n, n))
    A[0, :] = -a
    A[1:, :-1] = np.eye(n - 1)
    B = np.zeros((n, 1))
    B[0, 0] = 1.0
    C = b.reshape(1, n)
    D = np.array([[d]])
    return A, B, C, D


def pade_diagram(diagram, t0: float = 0.0):
    """The diagram with each transport delay replaced by its Pade approximation of order
    ``pade_order`` (a transfer-fcn block; order 0 is the wire itself, a unit gain): the linear
    model Simulink's ``linmod`` builds. Its ``notes`` say which delays were approximated.

    The states of the approximations are named ``<delay>.x1``, ``<delay>.x2``, ... (after the
    diagram's own states, in the order of the blocks).
    """
    w = diagram.wiring
    blocks = {}
    notes = []
    for name, b in w.blocks.items():
        if isinstance(b, TransportDelay):
            (src, port), = w.sources[name]
            ports = w.blocks[src].ports()
            ref = src if len(ports) == 1 else f"{src}.{ports[port]}"
            if b.order == 0:
                blocks[name] = Gain(gain=1.0, input=ref)
            else:
                num, den = pade_coefficients(b.T, b.order)
                blocks[name] = TransferFcn(num=num.tolist(), den=den.tolist(), input=ref)
            notes.append(f"transport delay `{name}` ({b.T:g} s) linearised as its Pade approximation of order "
                         f"{b.order} (pade_order; Simulink's linmod does the same)")
        else:
            blocks[name] = b
    outputs = {}
    for out, (src, port) in w.outputs.items():
        ports = w.blocks[src].ports()
        outputs[out] = src if len(ports) == 1 else f"{src}.{ports[port]}"
    order = [*diagram.slices, *(n for n, b in w.blocks.items() if isinstance(b, TransportDelay) and blocks[n].nstates)]
    compiled = CompiledDiagram(wire(blocks, outputs, "warning"), states=order, t0=t0,
                               zero_crossing=diagram.zero_crossing, loop_note=True)
    compiled.notes[:0] = notes
    return compiled
