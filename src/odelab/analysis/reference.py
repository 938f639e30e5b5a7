"""The high-accuracy reference: one tight solve per problem, stiff-aware and bounded.

``[reference] method = "high-accuracy"`` measures a run against a solve at ``rtol = 1e-12``
(``atol = 1e-14``) unless the file says otherwise. Its ``solver`` is ``"auto"`` by default:

* it starts with SciPy's DOP853 (8th order, the right tool at such tolerances for a non-stiff
  problem) and, after 2,000 steps and again after each tenfold more, asks the stiffness
  indicator (:mod:`odelab.solvers.stiffness`) whether the steps are held by the method's
  stability rather than by accuracy (``|h| rho(J)`` at DOP853's stability boundary and the
  fastest mode much faster than the solution). If so the problem is stiff and the reference is
  restarted with SciPy's **Radau** (implicit, order 5, L-stable), the standard stiff solver for
  tight tolerances; its note says so and why;
* a named solver (``"DOP853"``, ``"Radau"``, ``"BDF"``, ``"LSODA"``, ...) is used as given.

Either way it is **bounded**: at most ``max_steps`` steps (the run's ``--max-steps``), after
which it fails with a message instead of running on. The solve covers ``[t0, tf]`` once and
keeps each step's continuous extension, so every case of a sweep over the same problem (a
work-precision study of 36 cases) is measured against the same solve, evaluated at its own
output times, as the solvers' own ``t_eval`` output would be. ``progress(text)`` (optional) is
told what the reference is doing, for a status line; this module never prints.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from odelab.solvers.registry import METHODS, REFERENCE_METHOD

__all__ = ["AUTO", "PROBE_STEPS", "STIFF_SOLVER", "Reference", "high_accuracy", "cached", "clear_cache",
           "DENSE_SOLVERS"]

AUTO = "auto"
PROBE_STEPS = 2_000  # DOP853 steps before the first stiffness check (then after 10x, 100x, ...)
STIFF_SOLVER = "Radau"
DENSE_SOLVERS = ("DOP853", "RK45", "RK23", "Radau", "BDF", "LSODA")  # SciPy's, with continuous extensions
_CACHE: OrderedDict = OrderedDict()
_CACHE_SIZE = 8


@dataclass
class Reference:
    """A reference solve over ``[t0, tf]``: ``status`` "success" or "failed", the ``solver`` that
    ran, a ``note`` on how it was chosen (empty for a named solver), the ``message`` of a failure,
    ``nsteps`` and ``nfevals``. ``values(t)`` evaluates the solution at times inside the span."""

    solver: str
    status: str
    message: str
    note: str = ""
    nsteps: int = 0
    nfevals: int = 0
    t_steps: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pieces: list = field(default_factory=list)
    y0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    t0: float = 0.0

    def values(self, t) -> np.ndarray:
        """The solution at the times ``t`` (len(t), n), from the step that contains each one."""
        t = np.asarray(t, dtype=float).reshape(-1)
        out = np.empty((t.size, self.y0.size))
        if not self.pieces:
            out[:] = self.y0
            return out
        ends = self.t_steps  # the end of each step, increasing in the direction of integration
        forward = ends[-1] >= self.t0
        key = (t if forward else -t)
        index = np.searchsorted(ends if forward else -ends, key, side="left")
        index = np.clip(index, 0, len(self.pieces) - 1)
        for i in np.unique(index):
            mask = index == i
            out[mask] = np.atleast_2d(self.pieces[i](t[mask]).T).reshape(int(mask.sum()), self.y0.size)
        out[t == self.t0] = self.y0
        return out


def _stiff_here(solver, fun, scale: float):
    from odelab.solvers.stiffness import diagnose_step_limit

    A, B, h = getattr(solver, "A", None), getattr(solver, "B", None), getattr(solver, "step_size", None)
    if A is None or B is None or h is None:
        return None
    return diagnose_step_limit(fun, float(solver.t), solver.y, float(h), A, B, scale=scale)


def _run(fun, t0, tf, y0, name, rtol, atol, max_steps, progress, probe, jac=None):
    """Step SciPy's ``name`` from t0 to tf, keeping each step's continuous extension.

    Returns ``(Reference, diagnosis)``; ``diagnosis`` is set when ``probe`` and the steps were
    found held by stability (the caller restarts with a stiff solver)."""
    from scipy import integrate

    cls = getattr(integrate, name)
    kwargs = dict(rtol=rtol, atol=atol)
    if jac is not None and METHODS[name].stiff:  # SciPy's implicit methods take a Jacobian
        kwargs["jac"] = jac
    solver = cls(fun, t0, np.array(y0, dtype=float), tf, **kwargs)
    ends, pieces = [], []
    nsteps = 0
    check = PROBE_STEPS
    scale = float(np.max(np.abs(y0))) if np.size(y0) else 0.0
    report_every = 500
    while solver.status == "running":
        text = solver.step()
        if solver.status == "failed":
            ref = Reference(name, "failed", f"{name} failed at t = {solver.t:.6g}: {text}", nsteps=nsteps,
                            nfevals=int(solver.nfev), y0=np.array(y0, dtype=float), t0=t0)
            return ref, None
        nsteps += 1
        ends.append(float(solver.t))
        pieces.append(solver.dense_output())
        scale = max(scale, float(np.max(np.abs(solver.y))))
        if progress is not None and nsteps % report_every == 0:
            progress(f"reference by {name}: t = {solver.t:.3g} of {tf:.3g}, {nsteps:,} steps")
        at_budget = bool(max_steps) and nsteps >= max_steps
        if probe and (nsteps >= check or at_budget) and solver.status == "running":
            check *= 10
            diagnosis = _stiff_here(solver, fun, scale)
            if diagnosis is not None and diagnosis.stiff:
                return None, (float(solver.t), diagnosis)
        if max_steps and nsteps >= max_steps and solver.status == "running":
            msg = (f"{name} stopped at t = {solver.t:.6g} of {tf:g} after max_steps = {max_steps:,} steps (the "
                   "run's budget, --max-steps)")
            return Reference(name, "failed", msg, nsteps=nsteps, nfevals=int(solver.nfev),
                             y0=np.array(y0, dtype=float), t0=t0), None
    ref = Reference(name, "success", f"{name} reached t = {tf:g}.", nsteps=nsteps, nfevals=int(solver.nfev),
                    t_steps=np.array(ends), pieces=pieces, y0=np.array(y0, dtype=float), t0=t0)
    return ref, None


def high_accuracy(fun: Callable, t0: float, tf: float, y0, *, solver: str = AUTO, rtol: float = 1e-12,
                  atol: float = 1e-14, max_steps: int = 0, jac=None,
                  progress: Callable[[str], None] | None = None) -> Reference:
    """Solve ``y' = fun(t, y)`` on ``[t0, tf]`` tightly: see the module's notes.

    ``solver``: ``"auto"`` (DOP853, switching to Radau when the problem proves stiff) or one of
    SciPy's methods with a continuous extension (:data:`DENSE_SOLVERS`). ``max_steps``: the
    budget of steps (0: none). ``jac``: an exact Jacobian for the stiff solver, if known.
    """
    raised: list[BaseException] = []
    y0 = np.asarray(y0, dtype=float).reshape(-1)
    n = y0.size

    def rhs(t, y):
        try:
            return np.asarray(fun(t, y), dtype=float).reshape(n)
        except Exception as exc:
            raised.append(exc)
            raise

    name = REFERENCE_METHOD if solver == AUTO else solver
    if name not in DENSE_SOLVERS:
        raise ValueError(f"high_accuracy runs SciPy's {', '.join(DENSE_SOLVERS)} (or 'auto'); got {solver!r}")
    try:
        if progress is not None:
            progress(f"reference by {name} at rtol {rtol:g}")
        ref, stiff = _run(rhs, t0, tf, y0, name, rtol, atol, max_steps, progress, probe=solver == AUTO, jac=jac)
        if stiff is not None:
            t_stiff, diagnosis = stiff
            note = (f"the problem is stiff: {name}'s steps were held by stability at t = {t_stiff:.4g} "
                    f"(|h| rho(J) = {diagnosis.h_rho:.3g} at its limit {diagnosis.boundary:.3g}, the fastest mode "
                    f"{diagnosis.rho / max(diagnosis.rate, 1e-300):.3g} times faster than the solution), so the "
                    f"reference is {STIFF_SOLVER}'s")
            if progress is not None:
                progress(f"stiff ({name} held by stability at t = {t_stiff:.3g}); reference by {STIFF_SOLVER}")
            ref, _ = _run(rhs, t0, tf, y0, STIFF_SOLVER, rtol, atol, max_steps, progress, probe=False, jac=jac)
            ref.note = note
    except Exception as exc:
        if not raised:
            raise
        text = str(exc)
        return Reference(name, "failed", f"{name} failed: the right-hand side raised {type(exc).__name__}"
                         f"{': ' + text if text else ''}.", y0=y0, t0=t0)
    if progress is not None:
        progress(f"reference done: {ref.solver}, {ref.nsteps:,} steps" if ref.status == "success"
                 else f"reference failed: {ref.message}")
    return ref


def cached(key, compute: Callable[[], Reference]) -> Reference:
    """The reference stored under ``key`` (computed by ``compute()`` the first time, kept for the
    process's next cases; the last few are kept)."""
    if key in _CACHE:
        _CACHE.move_to_end(key)
        return _CACHE[key]
    ref = compute()
    _CACHE[key] = ref
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return ref


def clear_cache() -> None:
    _CACHE.clear()

