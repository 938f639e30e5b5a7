"""SciPy's ``solve_ivp`` methods behind odelab's :class:`~odelab.solution.Solution`.

The solver classes are stepped here directly, as ``solve_ivp`` steps them, so that accepted
steps can be counted, and rejected attempts too where the method allows: an explicit
Runge-Kutta attempt costs a fixed number of evaluations (RK23 3, RK45 6, DOP853 12), so the
evaluations a step used tell how many attempts it took. SciPy's implicit methods (Radau, BDF,
LSODA) keep their rejections internal; ``stats.nfailed`` is then ``None``, not a guess.
"""

from __future__ import annotations

import numpy as np

from odelab.solution import Solution, Stats
from odelab.solvers.options import SolverOptions
from odelab.solvers.registry import Method

__all__ = ["solve_scipy"]

# Right-hand side evaluations per attempted step of SciPy's explicit Runge-Kutta classes.
_EVALS_PER_ATTEMPT = {"RK23": 3, "RK45": 6, "DOP853": 12}


def solve_scipy(fun, tspan: np.ndarray, y0: np.ndarray, m: Method, opts: SolverOptions) -> Solution:
    from scipy import integrate

    cls = getattr(integrate, m.name)
    n = y0.size
    kwargs = dict(rtol=opts.rtol, atol=opts.atol, max_step=opts.max_step)
    if opts.initial_step == opts.initial_step:  # not NaN
        kwargs["first_step"] = opts.initial_step
    t0, tf = float(tspan[0]), float(tspan[-1])
    raised: list[BaseException] = []

    def rhs(t, y):
        try:
            return np.asarray(fun(t, y), dtype=float).reshape(n)
        except Exception as exc:  # remember it: SciPy would otherwise propagate it unlabelled
            raised.append(exc)
            raise

    t_out = [t0]
    y_out = [y0.copy()]
    per_attempt = _EVALS_PER_ATTEMPT.get(m.name)
    nsteps = 0
    nfailed = 0 if per_attempt else None
    status, message = "success", f"{m.name} reached t = {tf:g}."
    t_eval = tspan[1:] if tspan.size > 2 else None
    nxt = 0
    direction = 1.0 if tf > t0 else -1.0
    solver = None
    try:
        solver = cls(rhs, t0, y0, tf, **kwargs)
        while solver.status == "running":
            before = solver.nfev
            text = solver.step()
            if solver.status == "failed":
                status, message = "failed", f"{m.name} failed at t = {solver.t:.10g}: {text}"
                break
            nsteps += 1
            if per_attempt:
                nfailed += (solver.nfev - before) // per_attempt - 1
            if t_eval is None:
                t_out.append(solver.t)
                y_out.append(solver.y.copy())
            else:
                stop = nxt
                while stop < t_eval.size and direction * (t_eval[stop] - solver.t) <= 0:
                    stop += 1
                if stop > nxt:
                    dense = solver.dense_output()
                    times = t_eval[nxt:stop]
                    t_out.extend(times.tolist())
                    y_out.extend(np.atleast_2d(dense(times).T))
                    nxt = stop
            if opts.max_steps and nsteps >= opts.max_steps and solver.status == "running":
                status = "failed"
                message = (f"{m.name} stopped at t = {solver.t:.10g} of {tf:g} after max_steps = {opts.max_steps} "
                           "steps: " + _step_limit_advice(m, solver, fun, y_out, opts.max_steps, t0, tf))
                break
    except Exception as exc:
        if not raised:
            raise
        status = "failed"
        text = str(exc)
        message = f"{m.name} failed: the right-hand side raised {type(exc).__name__}{': ' + text if text else ''}."
    nfev = int(getattr(solver, "nfev", 0)) if solver is not None else len(raised)
    return Solution(
        t=np.array(t_out),
        y=np.array(y_out, dtype=float).reshape(len(y_out), n),
        stats=Stats(nsteps=nsteps, nfailed=nfailed, nfevals=nfev),
        status=status,
        message=message,
        method=m.name,
        warnings=opts.warnings,
    )


def _step_limit_advice(m: Method, solver, fun, y_out: list, max_steps: int, t0: float, tf: float) -> str:
    """Stiff or only long? SciPy's explicit classes carry their tableau (A, B) for the indicator."""
    if m.stiff:
        return "raise max_steps, or loosen rtol/atol."
    from odelab.solvers.stiffness import diagnose_step_limit, step_limit_advice

    A, B = getattr(solver, "A", None), getattr(solver, "B", None)
    h = getattr(solver, "step_size", None)
    diagnosis = None
    if A is not None and B is not None and h is not None:
        scale = max((float(np.max(np.abs(v))) for v in y_out), default=None)
        diagnosis = diagnose_step_limit(fun, float(solver.t), solver.y, float(h), A, B, scale=scale)
    return step_limit_advice(m.name, diagnosis, max_steps, t0, float(solver.t), tf)
