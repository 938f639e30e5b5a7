"""Simulate a system driven by input signals: :func:`simulate` and its :class:`Response`.

Any object with the system protocol (``nx, nu, states, inputs, outputs``,
``dynamics(t, x, u)`` and ``output(t, x, u)``; :class:`~odelab.systems.statespace.StateSpace`
and :class:`~odelab.systems.nonlinear.NonlinearSystem`) is integrated as the ODE

    x' = system.dynamics(t, x, u(t))

with any method of :func:`odelab.solvers.api.solve`, and its output is evaluated at the
output points.

Discontinuous inputs
--------------------
An explicit Runge-Kutta method assumes a smooth right-hand side: a step that falls inside
a step of the integrator is felt by some stages and not by others, which costs both accuracy
(the local error is O(h), not O(h^5)) and rejected steps. So :func:`simulate` collects the
inputs' breakpoints (:meth:`~odelab.signals.Signal.breakpoints`) and integrates piece by
piece, restarting the solver at each one. Within a piece the inputs are read on the piece's
own side of each end, so the last stage of the step that lands on a step time still sees
the value *before* the step (signals are right-continuous; see :mod:`odelab.signals`).
Without breakpoints :func:`solve` is called once with exactly the user's ``tspan``, so the
result is MATLAB's, point for point.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from odelab.exceptions import InputError
from odelab.systems.common import as_initial_state
from odelab.signals import Signal, as_signals
from odelab.solution import Solution, Stats
from odelab.solvers.registry import DEFAULT_METHOD, get_method

__all__ = ["Response", "simulate"]


@dataclass(frozen=True, eq=False)
class Response:
    """The time response of a system, as python-control's ``TimeResponseData``.

    Attributes
    ----------
    t
        Output times, shape (N,).
    x, u, y
        States, inputs and outputs at those times: shapes (N, nx), (N, nu), (N, ny).
        At a breakpoint time the inputs (and y through D) take their value after the jump.
    states, inputs, outputs
        Names of the columns of x, u and y.
    stats
        Step statistics summed over the pieces (``nfailed`` is None if any piece could
        not count its failures).
    status, message
        ``"success"`` or ``"failed"`` (then t, x, u, y hold what was computed before the
        failure), and why.
    method
        The integration method's registry name.
    breakpoints
        The input breakpoints inside the span, where the solver was restarted.
    warnings
        Warnings from the solver (e.g. a tolerance raised to its minimum), without repeats.
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    y: np.ndarray
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    stats: Stats
    status: str = "success"
    message: str = ""
    method: str = ""
    breakpoints: tuple[float, ...] = ()
    warnings: tuple[str, ...] = ()

    @property
    def success(self) -> bool:
        return self.status == "success"

    def signal(self, name: str) -> np.ndarray:
        """The column named ``name`` among the outputs, then the states, then the inputs."""
        for names, values in ((self.outputs, self.y), (self.states, self.x), (self.inputs, self.u)):
            if name in names:
                return values[:, names.index(name)]
        known = ", ".join(dict.fromkeys([*self.outputs, *self.states, *self.inputs]))
        raise InputError(f"The response has no signal named {name!r}; it has: {known}.", key=name)

    def __repr__(self) -> str:
        return (
            f"Response(method={self.method!r}, status={self.status!r}, points={self.t.size}, "
            f"states={self.states}, inputs={self.inputs}, outputs={self.outputs}, "
            f"pieces={len(self.breakpoints) + 1}, nsteps={self.stats.nsteps}, "
            f"nfevals={self.stats.nfevals})"
        )


def simulate(
    system: Any,
    tspan: Sequence[float],
    x0: Any,
    u: Any = None,
    *,
    method: str = DEFAULT_METHOD,
    piece_solver: Callable[..., Solution] | None = None,
    **options: Any,
) -> Response:
    """Integrate ``system`` over ``tspan`` from ``x0`` with inputs ``u``.

    Parameters
    ----------
    system
        A StateSpace, a NonlinearSystem, or any object with the system protocol.
    tspan
        ``[t0, tf]``: output at the solver's natural points (every step, ``refine`` per step
        for ode45), the pieces' points concatenated when there are breakpoints. Or a longer
        strictly monotonic sequence: output at exactly those times.
    x0
        Initial state, one value per state.
    u
        None (all inputs 0), one signal (a single-input system), a sequence of signals (one
        per input) or a mapping from input names to signals. Numbers are constants and
        callables of t become :class:`~odelab.signals.Function` signals.
    method
        A method name known to :func:`odelab.solvers.api.solve` (``"ode45"``, ``"rk4"``...).
    **options
        Passed to :func:`~odelab.solvers.api.solve` for every piece: ``rtol``, ``atol``,
        ``max_step``, ``initial_step``, ``refine``, ``norm_control``, ``h``... When the
        span is cut at breakpoints and ``max_step`` is not given, ode23/ode45 get MATLAB's
        default for the *whole* span, 0.1*|tf - t0|, rather than one tenth of each piece.
    piece_solver
        ``piece_solver(grid, x, lo, hi, options) -> Solution`` solves one piece from state
        ``x`` over ``grid`` with the inputs read at t clipped to ``[lo, hi]``; the default is
        :func:`~odelab.solvers.api.solve` on ``system.dynamics``. The compiled backend passes
        its own (:func:`odelab.run.backend.solve_problem`), so both take the same pieces.

    Returns
    -------
    Response
        A failed piece ends the simulation: the response then holds the points computed so
        far, ``status == "failed"`` and the piece's message.

    Notes
    -----
    With a two-element ``tspan`` a breakpoint time appears once, from the start of the
    piece after it, so ``y`` jumps there when D != 0 (or the output depends on u). With a
    longer ``tspan`` each piece integrates over its end points and the user's times inside
    it, and only the user's times are returned.
    """
    from odelab.solvers.options import as_tspan

    dynamics = getattr(system, "dynamics", None)
    output = getattr(system, "output", None)
    if not callable(dynamics) or not callable(output):
        raise InputError(
            "`system` must have dynamics(t, x, u) and output(t, x, u) methods (a StateSpace or "
            f"a NonlinearSystem); got {type(system).__name__}.",
            key="system",
        )
    states = tuple(system.states)
    tspan = as_tspan(tspan)
    x0 = as_initial_state(x0, len(states), states)
    signals = as_signals(u, tuple(system.inputs))
    if piece_solver is None:
        piece_solver = python_piece_solver(system, signals, method)

    t0, tf = float(tspan[0]), float(tspan[-1])
    cuts = np.unique(np.concatenate([np.empty(0), *(s.breakpoints(t0, tf) for s in signals)]))
    if tf < t0:
        cuts = cuts[::-1]
    edges = [t0, *cuts.tolist(), tf]
    options = whole_span_max_step(options, method, t0, tf, cut=bool(cuts.size))
    run = _Pieces(method)
    run.integrate(piece_solver, edges, tspan, x0, options)
    message = run.message
    if run.status == "success" and len(edges) > 2:
        where = ", ".join(f"{c:g}" for c in cuts[:5]) + (f", ... ({cuts.size} in all)" if cuts.size > 5 else "")
        message = f"{message} Integrated in {len(edges) - 1} pieces, restarted at the input breakpoints t = {where}."

    t = np.concatenate(run.ts)
    x = np.concatenate(run.xs).reshape(t.size, len(states))
    U = np.zeros((t.size, len(signals)))
    for j, signal in enumerate(signals):
        U[:, j] = signal(t)
    Y = np.array([np.asarray(output(ti, xi, ui), dtype=float).reshape(-1) for ti, xi, ui in zip(t, x, U)])
    Y = Y.reshape(t.size, len(system.outputs))
    for arr in (t, x, U, Y):
        arr.setflags(write=False)
    return Response(
        t=t,
        x=x,
        u=U,
        y=Y,
        states=states,
        inputs=tuple(system.inputs),
        outputs=tuple(system.outputs),
        stats=Stats(run.nsteps, run.nfailed, run.nfevals, *(run.linalg or ())),
        status=run.status,
        message=message,
        method=run.method_name,
        breakpoints=tuple(float(c) for c in cuts),
        warnings=tuple(run.notes),
    )


def piece_window(edges: Sequence[float], i: int) -> tuple[float, float]:
    """Where piece ``i`` (``edges[i]`` to ``edges[i + 1]``) reads its inputs: clipped to its own
    side of each breakpoint (a source's value just before a jump, its new value just after),
    unbounded at the user's ends of the span. Shared by :func:`simulate` and the hybrid driver."""
    a, b = edges[i], edges[i + 1]
    last = i == len(edges) - 2
    lo, hi = min(a, b), max(a, b)
    lo_is_cut = (lo == a and i > 0) or (lo == b and not last)
    hi_is_cut = (hi == a and i > 0) or (hi == b and not last)
    return (lo if lo_is_cut else -math.inf), (float(np.nextafter(hi, -math.inf)) if hi_is_cut else math.inf)


def whole_span_max_step(options: dict, method: str, t0: float, tf: float, *, cut: bool) -> dict:
    """``options`` with MATLAB's default MaxStep for the *whole* span, 0.1 |tf - t0|, when the
    span is cut into pieces and the user set none (each piece would otherwise get a tenth of
    itself); only for the methods that choose their own steps."""
    if not cut or any(_is_max_step(key) and value is not None for key, value in options.items()):
        return options
    if not get_method(method).matlab_defaults:  # MATLAB's MaxStep default: a tenth of the span
        return options
    return {**options, "max_step": 0.1 * abs(tf - t0)}


class _Pieces:
    """The pieces of one :func:`simulate` run, solved in turn: their rows and summed counts."""

    def __init__(self, method: str):
        self.ts: list[np.ndarray] = []
        self.xs: list[np.ndarray] = []
        self.nsteps, self.nfailed, self.nfevals = 0, 0, 0
        self.linalg = None  # npds, ndecomps, nsolves summed for the stiff solvers
        self.status, self.message, self.method, self.method_name = "success", "", method, method
        self.notes: list[str] = []

    def integrate(self, piece_solver, edges, tspan, state, options) -> None:
        """Each piece from the last one's final state; a failed piece ends the run. With a
        two-element tspan the solver's own points, else the user's times inside each piece."""
        dense = tspan.size == 2
        npieces = len(edges) - 1
        for i in range(npieces):
            a, b = edges[i], edges[i + 1]
            lo, hi = min(a, b), max(a, b)
            if npieces == 1:
                grid = tspan
            elif dense:
                grid = np.array([a, b])
            else:
                inside = tspan[(tspan > lo) & (tspan < hi)]
                grid = np.concatenate([[a], inside, [b]])  # the user's times run in the direction of a -> b
            sol: Solution = piece_solver(grid, state, *piece_window(edges, i), options)
            keep = np.ones(sol.t.size, dtype=bool)
            if not dense:
                keep &= np.isin(sol.t, tspan)
            if i < npieces - 1 and sol.t.size and sol.t[-1] == b:
                keep[-1] = False  # the breakpoint's row comes from the next piece's start
            self.add(sol, keep)
            if sol.status != "success":
                self.status, self.message = "failed", sol.message
                return
            state = sol.y[-1]
            self.message = sol.message

    def add(self, sol: Solution, keep: np.ndarray) -> None:
        self.ts.append(sol.t[keep])
        self.xs.append(sol.y[keep])
        stats = sol.stats
        self.nsteps += stats.nsteps
        self.nfevals += stats.nfevals
        self.nfailed = None if self.nfailed is None or stats.nfailed is None else self.nfailed + stats.nfailed
        if stats.npds is not None:
            counts = (stats.npds, stats.ndecomps, stats.nsolves)
            self.linalg = counts if self.linalg is None else tuple(p + q for p, q in zip(self.linalg, counts))
        self.method_name = sol.method or self.method
        self.notes.extend(w for w in sol.warnings if w not in self.notes)


def python_piece_solver(system: Any, signals: Sequence[Signal], method: str) -> Callable[..., Solution]:
    """The default ``piece_solver`` of :func:`simulate`: :func:`~odelab.solvers.api.solve` on
    ``system.dynamics`` with the inputs read at t clipped to the piece's ``[lo, hi]``."""
    from odelab.solvers.api import solve

    def solve_piece(grid, x, lo, hi, options):
        return solve(_piece_rhs(system.dynamics, signals, lo, hi), grid, x, method=method, **options)

    return solve_piece


def _is_max_step(key: str) -> bool:
    """Whether an option name is one of the spellings of max_step (max_step, MaxStep...)."""
    return key.lower().replace("_", "") == "maxstep"


def _piece_rhs(
    dynamics: Callable, signals: Sequence[Signal], lo: float, hi: float
) -> Callable[[float, np.ndarray], np.ndarray]:
    """fun(t, x) = dynamics(t, x, u(t)) with the inputs read at t clipped to [lo, hi]."""
    if not signals:
        empty = np.zeros(0)
        return lambda t, x: dynamics(t, x, empty)
    if math.isinf(lo) and math.isinf(hi):

        def fun(t, x):
            return dynamics(t, x, np.array([s(t) for s in signals]))

    else:

        def fun(t, x):
            tu = min(max(t, lo), hi)
            return dynamics(t, x, np.array([s(tu) for s in signals]))

    return fun
