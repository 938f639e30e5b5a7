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

from odelab.exceptions import ExperimentError, InputError

__all__ = ["check_backend", "why_not_compiled", "solve_problem", "simulate_problem"]


def why_not_compiled(method, compiled, options=None) -> str | None:
    """Why the compiled backend cannot run this method, system and options (None if it can)."""
    from odelab.solvers.compiled import PYTHON_ONLY_OPTIONS, method_refusal, unavailable

    reason = method_refusal(method)
    if reason:
        return reason
    if compiled is None:
        return ("it compiles systems written as expressions (equations, a state-space model, a diagram of linear "
                "blocks); this system is a Python function or a diagram with nonlinear blocks")
    if method.stiff:
        from odelab.solvers.compiled.stiff import why_not_stiff

        reason = why_not_stiff(method.name, compiled, options)
        if reason:
            return reason
    python_only = [name for name in PYTHON_ONLY_OPTIONS if (options or {}).get(name) is not None]
    if python_only:
        return f"`{python_only[0]}` calls back into Python"
    reason = compiled.why_not()
    if reason:
        return reason
    reason = unavailable()
    if reason:
        return reason
    return None


def check_backend(backend: str, method, compiled, key: str, options=None, events=None) -> None:
    """Refuse ``backend = "compiled"`` where it cannot run, naming the key and the fix."""
    if backend != "compiled":
        return
    reason = why_not_compiled(method, compiled, options)
    if reason is None and events is not None and not compiled.events:
        reason = "the compiled loop locates [events] of expression systems only"
    if reason:
        raise ExperimentError(f"`{key}` is \"compiled\", but the compiled backend cannot run this case: {reason}. "
                              "Use backend = \"auto\" (or \"python\").", key=key)


def solve_problem(problem, tspan, method_name: str, options: dict, backend: str):
    """Solve a problem without inputs; returns ``(Solution, backend that ran)``."""
    from odelab.solvers.api import solve
    from odelab.solvers.compiled import AUTO_STEPS, solve_compiled

    def python(opts):
        return solve(problem.fun, tspan, problem.x0, method=method_name, **opts)

    def compiled(opts):
        return solve_compiled(problem.compiled, tspan, problem.x0, method_name, **opts)

    def pilot(opts):
        sol = python({**opts, "max_steps": AUTO_STEPS})
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


def simulate_problem(problem, tspan, method_name: str, options: dict, backend: str):
    """Simulate a problem with inputs (restarting at their breakpoints, as
    :func:`odelab.systems.simulate.simulate`); returns ``(Response, backend that ran)``. The
    compiled path takes the same pieces, each solved by the compiled loop; the pilot of
    ``"auto"`` spends one budget of steps over all the pieces."""
    from odelab.solvers.compiled import solve_compiled
    from odelab.systems.simulate import python_piece_solver, simulate

    signals = list(problem.signals)

    def python(opts, piece_solver=None):
        return simulate(problem.system, tspan, problem.x0, u=signals, method=method_name, piece_solver=piece_solver,
                        **opts)

    def compiled_piece(grid, x, lo, hi, opts):
        return solve_compiled(problem.compiled, grid, x, method_name, input_bounds=(lo, hi), **opts)

    def pilot(opts):
        try:
            return python(opts, _budgeted(python_piece_solver(problem.system, signals, method_name))), None
        except _BudgetSpent as spent:
            return None, spent.t

    return _choose(problem, tspan, method_name, options, backend, python,
                   lambda opts: python(opts, compiled_piece), pilot)


def solve_events_problem(problem, tspan, method_name: str, options: dict, backend: str):
    """Integrate a problem with [events] (:func:`odelab.experiment.events.solve_with_events`,
    restarting after each reset); returns ``(its tuple, backend that ran)``. The compiled path
    locates the same events in the compiled loop; the pilot of ``"auto"`` spends one budget of
    steps over all the restarts."""
    from odelab.experiment.events import solve_with_events
    from odelab.solvers.api import solve
    from odelab.solvers.compiled import solve_compiled

    events = problem.events

    def run(opts, solve_piece=None):
        return solve_with_events(problem.fun, tspan, problem.x0, method_name, opts, events, problem.states,
                                 solve_piece=solve_piece)

    def python_piece(ts, x, o):
        return solve(problem.fun, ts, x, method=method_name, events=events.function, **o)

    def compiled_piece(ts, x, o):
        return solve_compiled(problem.compiled, ts, x, method_name, **o)

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
    import time

    from odelab.solvers.compiled import AUTO_STEPS, expected_compile_seconds
    from odelab.solvers.registry import get_method

    method = get_method(method_name)
    reason = why_not_compiled(method, problem.compiled, options)
    if reason is None and problem.events is not None and not problem.compiled.events:
        reason = "the compiled loop locates [events] of expression systems only"
    if backend == "compiled" and reason:
        raise InputError(f"`--backend compiled` cannot run this case: {reason}. Use --backend auto.")
    if backend == "python" or reason:
        return python(options), "python"
    if backend == "auto":
        if not method.adaptive:
            from odelab.solvers.api import fixed_grid
            from odelab.solvers.options import as_tspan, normalize_options, resolve_options

            tspan_arr = as_tspan(tspan)
            opts = resolve_options(method, normalize_options(options, method), tspan_arr, problem.x0.size)
            if fixed_grid(tspan_arr, opts.h)[0].size - 1 <= AUTO_STEPS:
                return python(options), "python"
        else:
            limit = options.get("max_steps") or 0
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
            loop = "events" if getattr(problem, "events", None) is not None else "adaptive"
            if method.stiff:
                loop = method.name
            if elapsed * steps / AUTO_STEPS < expected_compile_seconds(problem.compiled, loop):
                return python(options), "python"
    return compiled(options), "compiled"
