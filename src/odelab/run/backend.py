"""Which engine runs a case: the Python path or the compiled one (``[solver] backend``).

``"python"`` always uses :func:`odelab.solvers.api.solve`; ``"compiled"`` always uses
:func:`odelab.solvers.compiled.solve_compiled` (numba) and is refused, with the reason, for a
system it cannot compile; ``"auto"`` chooses from the expected work. A fixed-step run knows
its work in advance (the number of steps of its grid). An adaptive run does not, so it starts
on the Python path with a budget of :data:`~odelab.solvers.compiled.AUTO_STEPS` steps (over
all its pieces, with inputs or event restarts): a lab run finishes inside it and pays no compile
cost. A run that exhausts it is long: from the pilot's speed and the share of the time span it
covered, the whole run on Python is estimated and compared with the compile it would need
(:func:`~odelab.solvers.compiled.expected_compile_seconds`: seconds when the loops and the
system are not built yet, a fraction of a second when they are cached); the cheaper one runs,
from the start (the compiled path takes the same steps). The budget's work, about 0.3 s, is
the price of not guessing.
"""

from __future__ import annotations

import time

import numpy as np

from odelab.exceptions import InputError
from odelab.solution import Solution, Stats
from odelab.solvers.options import as_tspan, given_options, resolved_for
from odelab.solvers.registry import get_method

__all__ = ["solve_problem", "simulate_problem", "solve_events_problem", "run_hybrid"]


def _given(opts) -> dict:
    """The keyword arguments that hand ``opts`` to odelab.solve or solve_compiled: a dict as keywords, resolved
    SolverOptions as ``resolved=`` (carried to the driver as they are)."""
    return dict(opts) if isinstance(opts, dict) else {"resolved": opts}


def _with(options, **changes):
    """``options`` (a dict, or resolved SolverOptions) with ``changes``."""
    return {**options, **changes} if isinstance(options, dict) else options.updated(**changes)


def solve_problem(problem, tspan, method_name: str, options, backend: str, rows_to=None):
    """Solve a problem without inputs; returns ``(Solution, backend that ran)``. ``options``: a dict, or
    resolved SolverOptions, which the Python path carries to the driver as they are. ``rows_to``: the run's
    spool (:mod:`odelab.store.spool`), where the compiled loop writes a long run's rows as its blocks fill."""
    from odelab.solvers.api import solve
    from odelab.solvers.compiled import AUTO_STEPS, solve_compiled

    def python(opts):
        return solve(problem.system.fun, tspan, problem.x0, method=method_name, **_given(opts))

    def compiled(opts):
        return solve_compiled(problem.system.compiled, tspan, problem.x0, method_name, rows_to=rows_to,
                              **_given(opts))

    def pilot(opts):
        sol = python(_with(opts, max_steps=AUTO_STEPS))
        if sol.status == "failed" and sol.stats.nsteps == AUTO_STEPS:
            return None, float(sol.t[-1])
        return sol, None

    return _choose(problem, tspan, method_name, options, backend, python, compiled, pilot)


class _BudgetSpent(Exception):
    """The pilot of ``backend = "auto"`` used its steps at time ``t``: the run is long."""

    def __init__(self, t: float):
        super().__init__(t)
        self.t = t


def _budgeted(solve_piece):
    """``solve_piece(..., options)`` sharing one budget of AUTO_STEPS steps over all the pieces."""
    from odelab.solvers.compiled import AUTO_STEPS

    left = [AUTO_STEPS]

    def piece(*args):
        *rest, options = args
        if left[0] <= 0:
            raise _BudgetSpent(float(args[0][0]))
        sol = solve_piece(*rest, {**options, "max_steps": left[0]})
        left[0] -= sol.stats.nsteps
        if sol.status == "failed" and left[0] <= 0:
            raise _BudgetSpent(float(sol.t[-1]))
        return sol

    return piece


def simulate_problem(problem, tspan, method_name: str, options, backend: str):
    """Simulate a problem with inputs (restarting at their breakpoints, as
    :func:`odelab.systems.simulate.simulate`); returns ``(Response, backend that ran)``. The
    compiled path takes the same pieces, each solved by the compiled loop; the pilot of
    ``"auto"`` spends one budget of steps over all the pieces."""
    from odelab.solvers.compiled import solve_compiled
    from odelab.systems.simulate import python_piece_solver, simulate

    signals = list(problem.system.signals)

    def python(opts, piece_solver=None):  # each piece resolves the options for its span
        return simulate(problem.system.model, tspan, problem.x0, u=signals, method=method_name, piece_solver=piece_solver,
                        **given_options(opts))

    def compiled_piece(grid, x, lo, hi, opts):
        return solve_compiled(problem.system.compiled, grid, x, method_name, input_bounds=(lo, hi), **opts)

    def pilot(opts):
        try:
            return python(opts, _budgeted(python_piece_solver(problem.system.model, signals, method_name))), None
        except _BudgetSpent as spent:
            return None, spent.t

    return _choose(problem, tspan, method_name, options, backend, python,
                   lambda opts: python(opts, compiled_piece), pilot)


def solve_events_problem(problem, tspan, method_name: str, options, backend: str):
    """Integrate a problem with [events] (:func:`odelab.experiment.events.solve_with_events`,
    restarting after each reset); returns ``(its tuple, backend that ran)``. The compiled path
    locates the same events in the compiled loop; the pilot of ``"auto"`` spends one budget of
    steps over all the restarts."""
    from odelab.experiment.events import solve_with_events
    from odelab.solvers.api import solve
    from odelab.solvers.compiled import solve_compiled

    events = problem.system.events

    def run(opts, solve_piece=None):  # each piece (between events) resolves the options for its span
        return solve_with_events(problem.system.fun, tspan, problem.x0, method_name, given_options(opts), events,
                                 problem.states, solve_piece=solve_piece)

    def python_piece(ts, x, o):
        return solve(problem.system.fun, ts, x, method=method_name, events=events.function, **o)

    def compiled_piece(ts, x, o):
        return solve_compiled(problem.system.compiled, ts, x, method_name, **o)

    def pilot(opts):
        try:
            return run(opts, _budgeted(python_piece)), None
        except _BudgetSpent as spent:
            return None, spent.t

    return _choose(problem, tspan, method_name, options, backend, run, lambda opts: run(opts, compiled_piece), pilot)


def _choose(problem, tspan, method_name, options, backend, python, compiled, pilot):
    """Run ``python(options)`` or ``compiled(options)`` as ``backend`` says (see the module
    docstring); ``pilot(options)`` is the Python run within the budget and None, or None and the
    time it reached when the budget ran out."""
    from odelab.solvers.compiled import AUTO_STEPS, expected_compile_seconds
    from odelab.solvers.compiled.capability import why_not_compiled

    method = get_method(method_name)
    reason = why_not_compiled(method, problem.system.compiled, given_options(options))
    if reason is None and problem.system.events is not None and not problem.system.compiled.events:
        reason = "the compiled loop locates [events] of expression systems only"
    if backend == "compiled" and reason:
        raise InputError(f"`--backend compiled` cannot run this case: {reason}. Use --backend auto.")
    if backend == "python" or reason:
        return python(options), "python"
    if backend == "auto":
        if not method.adaptive:
            from odelab.solvers.api import fixed_grid

            tspan_arr = as_tspan(tspan)
            opts = resolved_for(method, options, tspan_arr, problem.x0.size)  # the case's, as resolved at load
            if fixed_grid(tspan_arr, opts.h)[0].size - 1 <= AUTO_STEPS:
                return python(options), "python"
        else:
            limit = given_options(options).get("max_steps") or 0
            if limit and limit <= AUTO_STEPS:
                return python(options), "python"
            start = time.perf_counter()
            result, reached = pilot(options)
            if result is not None:
                return result, "python"  # finished (or failed for its own reason) within the budget
            # A long run. Compile only if that costs less than the whole run on Python, estimated
            # from the pilot's speed and the share of the time span it covered.
            elapsed = time.perf_counter() - start
            t0, tf = float(tspan[0]), float(tspan[-1])
            progress = abs(reached - t0) / abs(tf - t0) if tf != t0 else 1.0
            steps = AUTO_STEPS / progress if progress > 0 else float("inf")
            if limit:  # max_steps (or odelab run's budget) caps the work: stiff.toml's ode45 stops at 20 000
                steps = min(steps, limit)
            loop = "events" if problem.system.events is not None else "adaptive"
            if method.stiff:
                loop = method.name
            if elapsed * steps / AUTO_STEPS < expected_compile_seconds(problem.system.compiled, loop):
                return python(options), "python"
    return compiled(options), "compiled"


def run_stateless(problem, tspan, options):  # -> Integration
    """A diagram without state (sources through gains to outputs): evaluated at its output times as Simulink
    evaluates such a model (every MaxStep, the span over 50 by default, and at the sources' jumps), its
    algebraic loops solved at each point; nothing is integrated."""
    from odelab.store.result import Integration

    d = problem.system.diagram
    t, u = d.output_times(tspan, given_options(options).get("max_step"))
    message = (f"the diagram has no state: its outputs evaluated at {t.size} times (every max_step and at the "
               "sources' jumps), as Simulink evaluates a model without states")
    notes = [message]
    stop = d.first_stop(t, u)
    if stop is not None:
        t, u = t[:stop[0] + 1], u[:stop[0] + 1]
        message = f"stopped at t = {t[-1]:.10g} by the stop block `{stop[1]}` (its input became nonzero)"
    return Integration(t, np.zeros((t.size, 0)), u if d.inputs else None, Stats(0, 0, 0), "success", message,
                       tuple(notes))


def run_hybrid(problem, tspan, method: str, options, backend: str):  # -> Integration
    """Run a diagram with switching or discrete blocks on the hybrid driver
    (:func:`odelab.systems.diagram.hybrid.simulate_hybrid`, the Python engine); returns its
    :class:`~odelab.store.result.Integration`. With ``backend = "auto"`` the message says
    which block kept the compiled engine out."""
    from odelab.store.result import Integration
    from odelab.systems.diagram.hybrid import simulate_hybrid

    d = problem.system.diagram
    options = given_options(options)  # each piece resolves them for its span
    if problem.system.events is not None:  # [events]: their resets and records, each piece on the hybrid driver
        from odelab.experiment.events import solve_with_events

        seen: list[str] = []

        def piece(ts, x, opts):
            r = simulate_hybrid(d, ts, x, method=method, zero_crossing=d.zero_crossing,
                                events=problem.system.events.function, **opts)
            seen.extend(n for n in r.notes if n not in seen)
            return Solution(t=r.t, y=r.x, stats=r.stats, status=r.status, message=r.message, method=r.method,
                            warnings=r.warnings, te=r.te, ye=r.ye, ie=r.ie)

        t, x, stats, status, message, warns, records, marks = solve_with_events(
            None, tspan, problem.x0, method, options, problem.system.events, problem.states, solve_piece=piece)
        return Integration(t, x, None, stats, status, message, [*warns, *seen], records, marks)
    r = simulate_hybrid(d, tspan, problem.x0, method=method, zero_crossing=d.zero_crossing, **options)
    from odelab.solvers.compiled import AUTO_STEPS

    message = r.message
    notes = [n for n in r.notes if n not in r.warnings]
    if backend == "auto" and r.stats.nsteps > AUTO_STEPS:  # long enough that auto would have compiled it
        notes.append(f"ran on the Python engine, not the compiled one: {d.hybrid_reason()}")
        message += f" Ran on the Python engine: {d.hybrid_reason()}."
    u = r.u if d.inputs else None
    return Integration(r.t, r.x, u, r.stats, r.status, message, (*r.warnings, *notes))
