"""A wired diagram -> an ordinary system the solvers, the linearisation and the report use.

The states are the states of the blocks that hold them (integrators, state-space and
transfer-function blocks), in the order of ``states`` or of the blocks' declaration; the
inputs are the source blocks (their signals drive :func:`~odelab.systems.simulate.simulate`,
which restarts the solver at their discontinuities, as for any input); the outputs are the
named ports. One evaluation computes every port in the order :func:`~odelab.systems.diagram.
graph.wire` fixed once, then the derivatives of the blocks with state.

A diagram made only of linear blocks compiles to a :class:`~odelab.systems.statespace.
StateSpace` whose A, B, C, D are read off the evaluation at unit vectors (exact: the blocks
are linear with no offsets, so each column is the product of the gains along the paths, to
round-off), so it gets the exact LTI reference. Any other diagram compiles to a
:class:`~odelab.systems.nonlinear.NonlinearSystem` that also offers its complex-step variant,
so its Jacobians (its linear model about an operating point) are exact too.
"""

from __future__ import annotations

import difflib
from functools import partial

import numpy as np

from odelab import signals as sg
from odelab.exceptions import InputError
from odelab.solvers.registry import DEFAULT_METHOD
from odelab.systems.diagram.blocks import Clock
from odelab.systems.diagram.graph import DiagramError, Wiring
from odelab.systems.diagram.ratelimit import signal_slope

__all__ = ["AlgebraicLoopError", "CompiledDiagram"]


class AlgebraicLoopError(ArithmeticError):
    """An algebraic loop of a diagram has no (unique) solution at some instant."""


class CompiledDiagram:
    """A diagram ready to evaluate: states, inputs (sources), outputs, x0 and the system."""

    def __init__(self, wiring: Wiring, *, states: list[str] | None = None, t0: float = 0.0,
                 zero_crossing: bool = True, loop_note: bool = True):
        self.wiring = wiring
        blocks = wiring.blocks
        holders = [n for n, b in blocks.items() if b.nstates]
        if states is not None:
            for i, name in enumerate(states):
                if name not in blocks or not blocks[name].nstates:
                    close = difflib.get_close_matches(str(name), holders, n=1)
                    hint = f" Did you mean `{close[0]}`?" if close else ""
                    raise DiagramError(f"`system.states[{i}]`: {name!r} is not a block with state ({', '.join(holders)})."
                                       f"{hint}", key=f"system.states[{i}]")
            missing = [n for n in holders if n not in states]
            if missing or len(set(states)) != len(states):
                raise DiagramError(f"`system.states` orders the blocks with state: list each of {', '.join(holders)} "
                                   "once.", key="system.states")
            holders = list(states)
        self.slices: dict[str, slice] = {}
        names: list[str] = []
        x0 = []
        for name in holders:
            b = blocks[name]
            self.slices[name] = slice(len(names), len(names) + b.nstates)
            names.extend(b.state_names(name))
            x0.append(b.initial_state())
        self.states = tuple(names)
        self.x0 = np.concatenate(x0) if x0 else np.zeros(0)
        self.inputs = tuple(n for n, b in blocks.items() if b.SOURCE)
        self.signals = tuple(sg.Ramp(slope=1.0, start=float(t0), initial=float(t0)) if isinstance(blocks[n], Clock)
                             else blocks[n].signal for n in self.inputs)
        self.outputs = tuple(wiring.outputs)
        # a diagram without state is evaluated at its output times (run.backend.run_stateless), not integrated:
        # it has no state-space model of its own
        self.linear = bool(names) and all(b.linear for b in blocks.values())
        self.zero_crossing = bool(zero_crossing)  # [solver] zero_crossing: off for every block
        self._order = [n for n in wiring.order if not blocks[n].SOURCE]
        self._system = None
        self._z_last = None  # the last solution of the algebraic loops (Newton's next start)
        #: blocks whose derivative needs their input's slope (rate limiters), in evaluation order
        self._sloped = [n for n in wiring.order if getattr(blocks[n], "NEEDS_SLOPE", False)]
        self._in_slope = False
        #: where the sources' slopes are taken (the hybrid driver sets its piece)
        self.slope_window = (-np.inf, np.inf)
        #: what a run should say about the diagram once (the algebraic loops it solves)
        self.notes: list[str] = [f"algebraic loop {text} solved by Newton's method at each evaluation, as Simulink "
                                 "does (set [system] algebraic_loops = \"error\" to refuse it, \"none\" to say "
                                 "nothing)" for text in wiring.loops] if loop_note else []

    # -- evaluation ------------------------------------------------------------------------------

    def _ports(self, t, x, u, cplx, cut=None):
        """Every port's value; with ``cut`` (a block name) that block's input is u's last entry
        instead of the signal wired to it (the loop opened there). A diagram with algebraic
        loops solves for their unknowns first (:meth:`_solve_loops`)."""
        if not self.wiring.torn:
            return self._sweep(t, x, u, cplx, cut)
        return self._solve_loops(t, x, u, cplx, cut)

    def _sweep(self, t, x, u, cplx, cut=None, z=None):
        """One evaluation in the wiring's order; ``z`` gives the torn blocks' outputs."""
        w = self.wiring
        vals = {(name, 0): u[i:i + 1] for i, name in enumerate(self.inputs)}
        for name in self._order:
            b = w.blocks[name]
            if z is not None and name in z:
                for i, v in enumerate(z[name]):
                    vals[(name, i)] = v
                continue
            xs = x[self.slices[name]] if name in self.slices else None
            if not b.feedthrough:
                ins = []
            elif name == cut:
                ins = [u[-1:]]
            else:
                ins = [vals[s] for s in w.sources[name]]
            for i, v in enumerate(b.outputs(t, xs, ins, cplx)):
                vals[(name, i)] = v
        return vals

    def _residual(self, t, x, u, cplx, cut, zvec):
        """F(z) = (the torn blocks' outputs computed from their inputs) - z, and the ports."""
        w = self.wiring
        z, k = {}, 0
        for name in w.torn:
            n = len(w.blocks[name].ports())
            z[name] = [zvec[k + i:k + i + 1] for i in range(n)]
            k += n
        vals = self._sweep(t, x, u, cplx, cut, z)
        out = []
        for name in w.torn:
            b = w.blocks[name]
            xs = x[self.slices[name]] if name in self.slices else None
            ins = [u[-1:]] if name == cut else [vals[s] for s in w.sources[name]]
            out.extend(b.outputs(t, xs, ins, cplx))
        actual = np.concatenate([np.broadcast_to(v, (1,) + np.shape(zvec)[1:]) for v in out])
        return actual - zvec, vals

    def _solve_loops(self, t, x, u, cplx, cut=None):
        """Newton's method on the torn blocks' outputs (Simulink's algebraic loop solver): the
        Jacobian by complex steps (exact), from the last solution; a singular Jacobian or no
        convergence raises :class:`AlgebraicLoopError` naming the loop and t."""
        m = sum(len(self.wiring.blocks[n].ports()) for n in self.wiring.torn)
        batch = np.broadcast_shapes(np.shape(t), np.shape(x)[1:], np.shape(u)[1:])  # many points at once
        shape = (m,) + batch
        dtype = complex if (cplx or np.iscomplexobj(x) or np.iscomplexobj(u)) else float
        last = self._z_last
        start = last.reshape((m,) + (1,) * (len(shape) - 1)) if last is not None and last.shape == (m,) else 0.0
        z = np.array(np.broadcast_to(start, shape), dtype=dtype)
        xr, ur = (np.real(x), np.real(u)) if dtype is complex else (x, u)
        h = 1e-30
        for _ in range(50):
            F, vals = self._residual(t, x, u, dtype is complex, cut, z)
            if np.all(np.isfinite(F)) and self._converged(F, z):
                self._z_last = np.real(z).copy() if z.ndim == 1 else None
                return vals
            J = np.empty((m, m) + batch)
            for j in range(m):
                step = np.zeros(shape, dtype=complex)
                step[j] = 1j * h
                Fj, _ = self._residual(t, xr, ur, True, cut, np.real(z) + step)
                J[:, j] = np.imag(Fj) / h
            Jn = np.moveaxis(J, (0, 1), (-2, -1)) if J.ndim > 2 else J
            Fn = np.moveaxis(F, 0, -1)[..., None] if F.ndim > 1 else F
            with np.errstate(all="ignore"):
                cond = np.linalg.cond(Jn)
            if not np.all(np.isfinite(cond)) or np.any(cond > 1e14):
                raise AlgebraicLoopError(self._loop_text(t, "its Jacobian is singular: the loop has no unique "
                                                            "solution there"))
            dz = np.linalg.solve(Jn, -Fn)
            z = z + (np.moveaxis(dz[..., 0], -1, 0) if F.ndim > 1 else dz)
        raise AlgebraicLoopError(self._loop_text(t, "Newton's method did not converge in 50 iterations: the loop "
                                                    "has no solution there"))

    @staticmethod
    def _converged(F, z) -> bool:
        """Newton's test on the loop's residual: the real part against the solution's size, and (a complex step,
        linearising) the imaginary part against the imaginary part's own size. The imaginary parts are 1e-30
        small: tested against 1 + |z| they would pass before Newton solved for them, and the derivative through
        the loop would come out as zero (issue 41: L(s) = 0 through a solved loop)."""
        real_ok = np.max(np.abs(np.real(F)), initial=0.0) <= 1e-13 * (1.0 + np.max(np.abs(np.real(z)), initial=0.0))
        if not np.iscomplexobj(F):
            return bool(real_ok)
        imag = np.max(np.abs(np.imag(F)), initial=0.0)
        return bool(real_ok and (imag == 0.0 or imag <= 1e-13 * np.max(np.abs(np.imag(z)), initial=0.0)))

    def _loop_text(self, t, why):
        where = f"t = {float(np.ravel(np.real(t))[0]):.10g}" if np.size(t) == 1 else "some output point"
        return f"the algebraic loop {'; '.join(self.wiring.loops)} at {where}: {why}"

    def _dynamics(self, t, x, u, cplx=False, cut=None):
        w = self.wiring
        vals = self._ports(t, x, u, cplx, cut)
        parts = [w.blocks[n].derivative(t, x[s], [u[-1:]] if n == cut else [vals[p] for p in w.sources[n]])
                 for n, s in self.slices.items()]
        if self._sloped and not cplx and cut is None and not self._in_slope:
            for n in self._sloped:  # a rate limiter tracking its input: y' = u', in evaluation order
                b = w.blocks[n]
                if b.mode is not None and int(np.asarray(b.mode).reshape(-1)[0]) == 1:
                    k = list(self.slices).index(n)
                    parts[k] = b.derivative(t, x[self.slices[n]], [vals[p] for p in w.sources[n]],
                                            slope=self.input_slope(n, t, x, u, np.concatenate(parts)))
        if not parts:  # a diagram without state (gains from sources to outputs): nothing moves
            return np.zeros((0,) + np.shape(t)) if np.ndim(t) else np.zeros(0)
        return np.concatenate(parts)

    def input_slope(self, name: str, t, x, u, xdot=None) -> float:
        """d/dt of the signal into block ``name`` along the trajectory at (t, x) with the sources'
        values ``u``: a complex step of the evaluation in the direction (1, x', the sources'
        slopes), exact to round-off (the sources' slopes are taken inside ``slope_window``)."""
        lo, hi = self.slope_window
        t = float(t)
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        if xdot is None:
            self._in_slope = True
            try:
                xdot = self._dynamics(t, x, u)
            finally:
                self._in_slope = False
        xdot = np.array(xdot, dtype=float)
        xdot[self.slices[name]] = 0.0  # the block's own output does not move its input (no loop through it)
        udot = np.array([signal_slope(s, t, lo, hi) for s in self.signals]) if self.signals else np.zeros(0)
        h = 1e-30
        vals = self._ports(t + 1j * h, x + 1j * h * xdot, u + 1j * h * udot, True)
        src = self.wiring.sources[name][0]
        return float(np.imag(np.asarray(vals[src]).reshape(-1)[0])) / h

    def _output(self, t, x, u, cplx=False):
        vals = self._ports(t, x, u, cplx)
        return np.concatenate([np.reshape(vals[p], (1,)) for p in self.wiring.outputs.values()]) \
            if self.outputs else np.zeros(0)

    def dynamics(self, t, x, u=None):
        """x' at one point."""
        return self._dynamics(t, np.asarray(x), np.zeros(0) if u is None else np.asarray(u))

    def output(self, t, x, u=None):
        """y at one point."""
        return self._output(t, np.asarray(x), np.zeros(0) if u is None else np.asarray(u))

    def output_many(self, t, x, u=None) -> np.ndarray:
        """y at many points at once: t (N,), x (N, nx), u (N, nu) -> (N, ny)."""
        t = np.asarray(t, dtype=float)
        u = np.zeros((t.size, 0)) if u is None else np.asarray(u, dtype=float)
        x = np.asarray(x, dtype=float)
        if self.wiring.torn:  # point by point from the last solution; NaN where a loop has none
            rows = []
            for i in range(t.size):
                try:
                    rows.append(self._output(t[i], x[i], u[i]))
                except AlgebraicLoopError:
                    rows.append(np.full(len(self.outputs), np.nan))
            return np.array(rows).reshape(t.size, len(self.outputs))
        vals = self._ports(t, x.T, u.T, False)
        return np.column_stack([np.broadcast_to(vals[p][0], t.shape) for p in self.wiring.outputs.values()]) \
            if self.outputs else np.zeros((t.size, 0))

    @property
    def hybrid(self) -> bool:
        """Whether the diagram runs on the hybrid driver (:mod:`~odelab.systems.diagram.hybrid`):
        it has switching blocks with zero-crossing detection on, a relay, or discrete blocks."""
        from odelab.systems.diagram.hybrid import needs_hybrid

        return needs_hybrid(self, self.zero_crossing)

    def hybrid_reason(self) -> str | None:
        """Which block makes the diagram hybrid, as a sentence (None if it is not)."""
        for name in self.wiring.order:
            b = self.wiring.blocks[name]
            if b.DISCRETE:
                return f"its block `{name}` ({b.TYPE}) is discrete (sample time {b.sample}), run by the Python driver"
            if b.STATEFUL_MODE:
                return f"its block `{name}` ({b.TYPE}) switches with memory, run by the Python driver"
            if self.zero_crossing and b.zero_crossing:
                return (f"its block `{name}` ({b.TYPE}) has zero crossings located by the Python driver "
                        "(zero_crossing = false on it compiles it)")
        return None

    # -- the system ----------------------------------------------------------------------------

    @property
    def system(self):
        """A StateSpace (every block linear) or a NonlinearSystem, with the diagram's names."""
        if self._system is None:
            self._system = self._state_space() if self.linear else self._nonlinear()
        return self._system

    def matrices(self):
        """A, B, C, D of a linear diagram, column by column from unit vectors."""
        if not self.linear:
            raise InputError("the diagram has nonlinear blocks; linearise it about an operating point instead.")
        n, m, p = len(self.states), len(self.inputs), len(self.outputs)
        A, B = np.zeros((n, n)), np.zeros((n, m))
        C, D = np.zeros((p, n)), np.zeros((p, m))
        # Many unit vectors per evaluation (the blocks work on columns, as in output_many): one
        # evaluation per column made a diagram of 10,000 integrators quadratic in Python calls.
        chunk = 256
        for into, other, target_x in ((A, C, True), (B, D, False)):
            width = n if target_x else m
            for j0 in range(0, width, chunk):
                k = min(chunk, width - j0)
                e = np.zeros((width, k))
                e[np.arange(j0, j0 + k), np.arange(k)] = 1.0
                x, u = (e, np.zeros((m, k))) if target_x else (np.zeros((n, k)), e)
                into[:, j0:j0 + k] = self._dynamics(0.0, x, u).reshape(n, k)
                if p:
                    vals = self._ports(0.0, x, u, False)
                    other[:, j0:j0 + k] = np.vstack([np.broadcast_to(vals[q], (1, k))
                                                    for q in self.wiring.outputs.values()])
        return A, B, C, D

    def _state_space(self):
        from odelab.systems.statespace import StateSpace

        A, B, C, D = self.matrices()
        if not self.outputs:
            return StateSpace(A, B, None, None, states=self.states, inputs=self.inputs)
        return StateSpace(A, B, C, D, states=self.states, inputs=self.inputs, outputs=self.outputs)

    def _nonlinear(self):
        from odelab.systems.nonlinear import NonlinearSystem

        # bound methods and partials of them, not lambdas: the system pickles with the diagram
        system = NonlinearSystem(partial(self._dynamics), partial(self._output) if self.outputs else None,
                                 states=self.states, inputs=self.inputs, outputs=self.outputs or None,
                                 name="diagram", complex_step=True)
        system.complex_step_dynamics = partial(self._dynamics, cplx=True)
        if self.outputs:
            system.complex_step_output = partial(self._output, cplx=True)
        return system

    def open_loop(self, at: str):
        """The diagram with the loop opened at the input of block ``at``: a NonlinearSystem with
        one more input, ``loop_in`` (what now enters ``at``), and one output, ``loop_out`` (the
        signal that was wired into ``at``). Linearised, L(s) = -loop_out/loop_in is the loop gain
        with the convention that the closed loop is 1/(1 + L) (MATLAB's ``margin`` convention)."""
        from odelab.systems.nonlinear import NonlinearSystem

        w = self.wiring
        if at not in w.blocks or w.blocks[at].SOURCE:
            names = [n for n, b in w.blocks.items() if not b.SOURCE]
            close = difflib.get_close_matches(str(at), names, n=1)
            hint = f" Did you mean `{close[0]}`?" if close else ""
            raise DiagramError(f"`analysis.loop`: {at!r} is not a block with an input ({', '.join(names)}).{hint}",
                               key="analysis.loop")
        feeds = w.sources[at]
        if len(feeds) != 1 or w.widths[feeds[0]] != 1:
            raise DiagramError(f"`analysis.loop`: block {at!r} has {len(feeds)} inputs; open the loop at a block "
                               "with one scalar input (e.g. the actuator or the plant).", key="analysis.loop")
        src = feeds[0]

        def dynamics(t, x, u, cplx=False):
            return self._dynamics(t, x, u, cplx, cut=at)

        def output(t, x, u, cplx=False):
            return np.reshape(self._ports(t, x, u, cplx, cut=at)[src], (1,))

        system = NonlinearSystem(dynamics, output, states=self.states, inputs=(*self.inputs, "loop_in"),
                                 outputs=("loop_out",), name=f"loop opened at {at}", complex_step=True)
        system.complex_step_dynamics = lambda t, x, u: dynamics(t, x, u, True)
        system.complex_step_output = lambda t, x, u: output(t, x, u, True)
        return system

    def output_times(self, tspan, max_step: float | None = None):
        """A diagram without state, evaluated as Simulink does: (t, u) at its output times. ``tspan`` of two
        entries: every ``max_step`` (Simulink's auto: the span over 50) and at the sources' breakpoints, each
        listed twice (the value just before the jump, then after); a longer ``tspan``: its times."""
        tspan = np.asarray(tspan, dtype=float).reshape(-1)
        if tspan.size > 2:
            t = tspan
            u = np.array([[s(tt) for s in self.signals] for tt in t]).reshape(t.size, len(self.signals))
            return t, u
        t0, tf = float(tspan[0]), float(tspan[-1])
        span = tf - t0
        h = abs(span) / 50 if not max_step or not np.isfinite(max_step) else float(max_step)
        n = max(1, int(np.ceil(abs(span) / h - 1e-9))) if span else 0
        grid = [t0 + span * k / n for k in range(n)] + [tf] if n else [t0]
        jumps = sorted({float(b) for s in self.signals for b in s.breakpoints(min(t0, tf), max(t0, tf))
                        if min(t0, tf) < b < max(t0, tf)})
        rows: list[tuple[float, float]] = [(tt, tt) for tt in grid if tt not in jumps]
        rows += [(b, np.nextafter(b, -np.inf if span > 0 else np.inf)) for b in jumps] + [(b, b) for b in jumps]
        rows.sort(key=lambda r: (r[0] if span >= 0 else -r[0], r[1] == r[0]))
        t = np.array([r[0] for r in rows])
        u = np.array([[s(at) for s in self.signals] for _, at in rows]).reshape(t.size, len(self.signals))
        return t, u

    def first_stop(self, t, u) -> tuple[int, str] | None:
        """(row, block) of the first output time at which a stop block's input is nonzero (a diagram without
        state, evaluated at its output times), or None."""
        stops = [n for n, b in self.wiring.blocks.items() if getattr(b, "STOPS", False)]
        if not stops:
            return None
        for i in range(np.size(t)):
            vals = self._ports(float(t[i]), np.zeros(0), np.asarray(u[i], dtype=float), False)
            for n in stops:
                if self.wiring.blocks[n].stopped([vals[p] for p in self.wiring.sources[n]]):
                    return i, n
        return None

    def simulate(self, tspan, *, method: str = DEFAULT_METHOD, x0=None, **options):
        """Simulate the diagram from its blocks' initial states (or ``x0``) with its sources."""
        if self.hybrid:
            from odelab.systems.diagram.hybrid import simulate_hybrid

            return simulate_hybrid(self, tspan, self.x0 if x0 is None else x0, method=method,
                                   zero_crossing=self.zero_crossing, **options)
        from odelab.systems.simulate import simulate

        return simulate(self.system, tspan, self.x0 if x0 is None else x0, u=list(self.signals) or None,
                        method=method, **options)

    def __repr__(self) -> str:
        kind = "linear" if self.linear else "nonlinear"
        return (f"CompiledDiagram({kind}, states={list(self.states)}, inputs={list(self.inputs)}, "
                f"outputs={list(self.outputs)})")
