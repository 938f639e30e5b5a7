"""A case's high-accuracy reference: shared by the cases of one problem, bounded by the run's budget.

The solve itself is :func:`odelab.analysis.reference.high_accuracy` (stiff-aware, bounded).
Here: which cases share one (the same file, the same problem: everything in the case's
configuration but its ``[solver]`` and names), whether a problem can take the shared path (no
inputs, events or switching blocks: those restart the solver at their instants and keep the
per-case solve of :func:`odelab.run.runner._integrate`), and the progress hook a front
end sets (:func:`set_progress`) to show a status line while a reference runs.
"""

from __future__ import annotations

import json
from typing import Callable

import numpy as np

__all__ = ["set_progress", "shared_reference", "can_share", "reference_key", "prepare"]

_PROGRESS: list[Callable[[str], None] | None] = [None]


def set_progress(callback: Callable[[str], None] | None) -> None:
    """Have ``callback(text)`` told what a reference being computed in this process is doing."""
    _PROGRESS[0] = callback


def can_share(problem) -> bool:
    from odelab.analysis.reference import AUTO, DENSE_SOLVERS

    solver = problem.reference_solver[0]
    hybrid = problem.system.diagram is not None and getattr(problem.system.diagram, "hybrid", False)
    fmu = problem.system.fmu is not None  # an FMU's reference is its own run (events, its state)
    return (problem.reference == "high-accuracy" and not problem.system.signals and problem.system.events is None and not hybrid
            and not fmu
            and (solver == AUTO or solver in DENSE_SOLVERS))


def reference_key(case, max_steps: int | None) -> tuple:
    p = case.problem
    physics = {k: v for k, v in case.config.items() if k not in ("solver", "name", "title", "description", "case")}
    text = json.dumps(physics, sort_keys=True, default=str)
    return (str(case.source), case.file_hash, case.experiment, text, p.reference_solver, float(p.tspan[0]),
            float(p.tspan[-1]), p.x0.tobytes(), int(max_steps or 0))


def shared_reference(case, max_steps: int | None):
    """The :class:`~odelab.analysis.reference.Reference` of ``case``'s problem (solved once per process)."""
    from odelab.analysis.reference import cached, high_accuracy

    p = case.problem
    solver, rtol, atol = p.reference_solver

    def compute():
        return high_accuracy(p.system.fun, float(p.tspan[0]), float(p.tspan[-1]), p.x0, solver=solver, rtol=rtol,
                             atol=atol, max_steps=int(max_steps or 0), jac=_jacobian(p), progress=_PROGRESS[0])

    return cached(reference_key(case, max_steps), compute)


def _jacobian(p):
    jac = p.options.get("jacobian")
    if callable(jac):
        return jac
    if jac is not None:
        return np.asarray(jac, dtype=float)
    return None


def prepare(cases, max_steps: int | None, progress: Callable[[str], None] | None = None) -> int:
    """Compute, in this process, the shared references the ``cases`` will need (before a process
    pool forks its workers, which then inherit them): returns how many were computed."""
    previous = _PROGRESS[0]
    set_progress(progress)
    seen = set()
    try:
        for case in cases:
            if case.problem.linearize is not None or not can_share(case.problem):
                continue
            key = reference_key(case, max_steps)
            if key in seen:
                continue
            seen.add(key)
            if progress is not None:
                set_progress(lambda text, _name=case.experiment: progress(f"{_name}: {text}"))
            shared_reference(case, max_steps)
    finally:
        set_progress(previous)
    return len(seen)
