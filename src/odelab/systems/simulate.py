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
    method: str = "ode45",
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
        its own (:func:`odelab.experiment.backend.solve_problem`), so both take the same pieces.

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
    from odelab.solvers.api import solve
    from odelab.solvers.options import as_tspan
    from odelab.solvers.registry import get_method

    dynamics = getattr(system, "dynamics", None)
    output = getattr(system, "output", None)
    if not callable(dynamics) or not callable(output):
        raise InputError(
            "`system` must have dynamics(t, x, u) and output(t, x, u) methods (a StateSpace or "
            f"a NonlinearSystem); got {type(system).__name__}.",
            key="system",
        )
    states = tuple(system.states)
    inputs = tuple(system.inputs)
    outputs = tuple(system.outputs)
    tspan = as_tspan(tspan)
    x0 = as_initial_state(x0, len(states), states)
    signals = as_signals(u, inputs)
    kind = get_method(method).kind
    if piece_solver is None:
        piece_solver = python_piece_solver(system, signals, method)

    t0, tf = float(tspan[0]), float(tspan[-1])
    backward = tf < t0
    cuts = np.unique(np.concatenate([np.empty(0), *(s.breakpoints(t0, tf) for s in signals)]))
    if backward:
        cuts = cuts[::-1]
    edges = [t0, *cuts.tolist(), tf]
    if cuts.size and kind in ("adaptive", "implicit", "multistep") and not any(
        _is_max_step(key) and value is not None for key, value in options.items()
    ):
        options = {**options, "max_step": 0.1 * abs(tf - t0)}

    dense = tspan.size == 2  # the solver's natural output points
    user_times = tspan
    ts: list[np.ndarray] = []
    xs: list[np.ndarray] = []
    nsteps, nfailed, nfevals = 0, 0, 0
    linalg = None  # npds, ndecomps, nsolves summed for the stiff solvers
    status, message, method_name = "success", "", method
    notes: list[str] = []
    state = x0
    npieces = len(edges) - 1
    for i in range(npieces):
        a, b = edges[i], edges[i + 1]
        last = i == npieces - 1
        lo, hi = min(a, b), max(a, b)
        # read the inputs on this piece's side of a breakpoint (not at the user's ends)
        lo_is_cut = (lo == a and i > 0) or (lo == b and not last)
        hi_is_cut = (hi == a and i > 0) or (hi == b and not last)
        u_lo = lo if lo_is_cut else -math.inf
        u_hi = float(np.nextafter(hi, -math.inf)) if hi_is_cut else math.inf
        if npieces == 1:
            grid = tspan
        elif dense:
            grid = np.array([a, b])
        else:
            inside = user_times[(user_times > lo) & (user_times < hi)]
            grid = np.concatenate([[a], inside, [b]])  # user_times run in the direction of a -> b
        sol: Solution = piece_solver(grid, state, u_lo, u_hi, options)

        keep = np.ones(sol.t.size, dtype=bool)
        if not dense:
            keep &= np.isin(sol.t, user_times)
        if not last and sol.t.size and sol.t[-1] == b:
            keep[-1] = False  # the breakpoint's row comes from the next piece's start
        ts.append(sol.t[keep])
        xs.append(sol.y[keep])
        nsteps += sol.stats.nsteps
        nfevals += sol.stats.nfevals
        nfailed = None if nfailed is None or sol.stats.nfailed is None else nfailed + sol.stats.nfailed
        if sol.stats.npds is not None:
            counts = (sol.stats.npds, sol.stats.ndecomps, sol.stats.nsolves)
            linalg = counts if linalg is None else tuple(a + b for a, b in zip(linalg, counts))
        method_name = sol.method or method
        notes.extend(w for w in sol.warnings if w not in notes)
        if sol.status != "success":
            status, message = "failed", sol.message
            break
        state = sol.y[-1]
        message = sol.message

    if status == "success" and npieces > 1:
        where = ", ".join(f"{c:g}" for c in cuts[:5]) + (f", ... ({cuts.size} in all)" if cuts.size > 5 else "")
        message = f"{message} Integrated in {npieces} pieces, restarted at the input breakpoints t = {where}."

    t = np.concatenate(ts)
    x = np.concatenate(xs).reshape(t.size, len(states))
    U = np.zeros((t.size, len(signals)))
    for j, signal in enumerate(signals):
        U[:, j] = signal(t)
    Y = np.array([np.asarray(output(ti, xi, ui), dtype=float).reshape(-1) for ti, xi, ui in zip(t, x, U)])
    Y = Y.reshape(t.size, len(outputs))
    for arr in (t, x, U, Y):
        arr.setflags(write=False)
    return Response(
        t=t,
        x=x,
        u=U,
        y=Y,
        states=states,
        inputs=inputs,
        outputs=outputs,
        stats=Stats(nsteps, nfailed, nfevals, *(linalg or ())),
        status=status,
        message=message,
        method=method_name,
        breakpoints=tuple(float(c) for c in cuts),
        warnings=tuple(notes),
    )


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
