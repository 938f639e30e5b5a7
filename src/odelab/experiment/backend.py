"""Which engine runs a case: the Python path or the compiled one (``[solver] backend``).

``"python"`` always uses :func:`odelab.solvers.api.solve`; ``"compiled"`` always uses
:func:`odelab.solvers.compiled.solve_compiled` (numba) and is refused, with the reason, for a
system it cannot compile; ``"auto"`` chooses from the expected work. A fixed-step run knows
its work in advance (the number of steps of its grid). An adaptive run does not, so it starts
on the Python path with a budget of :data:`~odelab.solvers.compiled.AUTO_STEPS` steps: a lab
run finishes inside it and pays no compile cost; a run that exhausts it is long, and is run
again from the start on the compiled path, which takes the same steps (the budget's work,
about 0.2 s, is the price of not guessing).
"""

from __future__ import annotations

from odelab.exceptions import ExperimentError, InputError

__all__ = ["check_backend", "why_not_compiled", "solve_problem"]


def why_not_compiled(method, compiled, options=None) -> str | None:
    """Why the compiled backend cannot run this method, system and options (None if it can)."""
    from odelab.solvers.compiled import PYTHON_ONLY_OPTIONS, unavailable

    if compiled is None:
        return ("it compiles systems written as expressions without inputs (equations, or a state-space model "
                "without inputs); this system is a Python function or has inputs")
    if method.kind not in ("adaptive", "fixed"):
        return (f"it runs odelab's explicit Runge-Kutta methods (ode23, ode45, fixed-step), and {method.name} is "
                + ("SciPy's" if method.kind == "scipy" else "not one of them"))
    if method.kind == "adaptive" and not method.tableau.fsal:
        return (f"its kernels run FSAL pairs and fixed-step methods, and {method.name} is Verner's non-FSAL "
                "pair whose interpolation stages are evaluated on demand (the Python path runs it)")
    python_only = [name for name in PYTHON_ONLY_OPTIONS if (options or {}).get(name) is not None]
    if python_only:
        return f"`{python_only[0]}` calls back into Python"
    reason = unavailable()
    if reason:
        return reason
    return None


def check_backend(backend: str, method, compiled, key: str, options=None, events=None) -> None:
    """Refuse ``backend = "compiled"`` where it cannot run, naming the key and the fix."""
    if backend != "compiled":
        return
    reason = why_not_compiled(method, compiled, options)
    if reason is None and events is not None:
        reason = "the compiled loop does not locate [events] (they call back into Python)"
    if reason:
        raise ExperimentError(f"`{key}` is \"compiled\", but the compiled backend cannot run this case: {reason}. "
                              "Use backend = \"auto\" (or \"python\").", key=key)


def solve_problem(problem, tspan, method_name: str, options: dict, backend: str):
    """Solve a problem without inputs; returns ``(Solution, backend that ran)``."""
    from odelab.solvers.api import solve
    from odelab.solvers.registry import get_method

    method = get_method(method_name)
    if backend == "compiled":
        reason = why_not_compiled(method, problem.compiled, options)
        if reason:
            raise InputError(f"`--backend compiled` cannot run this case: {reason}. Use --backend auto.")
    if backend == "python" or why_not_compiled(method, problem.compiled, options):
        return solve(problem.fun, tspan, problem.x0, method=method_name, **options), "python"
    from odelab.solvers.compiled import AUTO_STEPS, solve_compiled

    if backend == "auto":
        if method.kind == "fixed":
            from odelab.solvers.api import fixed_grid
            from odelab.solvers.options import as_tspan, normalize_options, resolve_options

            tspan_arr = as_tspan(tspan)
            opts = resolve_options(method, normalize_options(options, method), tspan_arr, problem.x0.size)
            if fixed_grid(tspan_arr, opts.h)[0].size - 1 <= AUTO_STEPS:
                return solve(problem.fun, tspan, problem.x0, method=method_name, **options), "python"
        else:
            limit = options.get("max_steps") or 0
            if limit and limit <= AUTO_STEPS:
                return solve(problem.fun, tspan, problem.x0, method=method_name, **options), "python"
            pilot = solve(problem.fun, tspan, problem.x0, method=method_name, **{**options, "max_steps": AUTO_STEPS})
            if not (pilot.status == "failed" and pilot.stats.nsteps == AUTO_STEPS):
                return pilot, "python"  # finished (or failed for its own reason) within the budget
    return solve_compiled(problem.compiled, tspan, problem.x0, method_name, **options), "compiled"
