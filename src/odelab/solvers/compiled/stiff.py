"""ode23s and ode15s on the compiled backend: the stiff loops of ``loops/stiff.py.txt``.

An expression system's right-hand side and its exact Jacobian (complex step through generated
code, :func:`odelab.solvers.compiled.codegen.jacobian_source`; a linear system's A) are
compiled with the system, and MATLAB's stiff step loops run in numba with SciPy's LAPACK for
the LU factorisations. They take the steps of the Python path (:mod:`odelab.solvers.implicit`)
given the same exact Jacobian, which is what an experiment's stiff case uses there
(``[solver] jacobian`` is "complex step on the equations", or A), with the same statistics
(steps, failures, evaluations, Jacobians, decompositions, solves).

The iteration matrices factor as the Python path factors them: dense LU, or LAPACK's banded
LU of the matrix permuted to a narrow band when the equations' structure allows
(:func:`odelab.solvers.banded.plan_band` on the pattern of which equation names which state,
the same plan the Python path's ``Work`` makes from the exact Jacobian's ``pattern``).

What the compiled loops do not have stays on the Python path, with the reason:
:func:`why_not_stiff` names it.
"""

from __future__ import annotations

import weakref

import numpy as np

from odelab.exceptions import InputError
from odelab.solution import Solution, Stats
from odelab.solvers.compiled.methods import STIFF_METHODS, method_refusal
from odelab.solvers.compiled.rows import exact_rows
from odelab.solvers.registry import METHODS
from odelab.solvers.status import Status

__all__ = ["STIFF_METHODS", "why_not_stiff", "solve_stiff"]

#: The stiff solvers' options the compiled loops take (others: the Python path).
_EXTRAS_TAKEN = ("jacobian", "vectorized", "max_order", "bdf")


def why_not_stiff(method_name: str, system, options=None) -> str | None:
    """Why the compiled backend cannot run the stiff solver ``method_name`` on ``system`` with
    these options (None if it can)."""
    if method_name not in STIFF_METHODS:
        return method_refusal(METHODS[method_name]) or f"{method_name} is not a stiff solver"
    options = options or {}
    reason = system.why_no_jacobian()
    if reason:
        return reason
    if system.events:
        return "the compiled stiff loops do not locate [events] (the Python path locates them)"
    if options.get("mass") is not None:
        return "`mass` is not in the compiled stiff loops (the Python path runs it)"
    if options.get("jpattern") is not None:
        return ("`jpattern` is not in the compiled stiff loops (they take the pattern of the equations "
                "themselves, and factor banded when it allows; the Python path runs a given one with sparse LU)")
    return _jacobian_refusal(system, options.get("jacobian"))


def _jacobian_refusal(system, jacobian) -> str | None:
    """None when ``jacobian`` is absent or is the system's own exact Jacobian (what the
    compiled loop generates), else why it must run on Python."""
    if jacobian is None:
        return None
    if callable(jacobian):
        if system.kind == "equations" and getattr(jacobian, "source", None) == "complex step on the equations":
            return None
        return "`jacobian` is a Python function (the file's analytic `system.jacobian`, or one passed in)"
    if system.kind == "linear":
        n = len(system.states)
        A = np.asarray(jacobian, dtype=float) if not hasattr(jacobian, "toarray") else None
        if A is not None and A.shape == (n, n) and np.array_equal(A.ravel(), system.values[: n * n]):
            return None
    return "`jacobian` is a matrix other than the system's own Jacobian"


def solve_stiff(system, m, tspan_arr: np.ndarray, y0_arr: np.ndarray, options) -> Solution:
    """Run ``m`` (ode23s or ode15s) compiled; ``options`` as :func:`odelab.solve` takes them (a dict, or
    SolverOptions resolved already: used as they are when they fit this method, span and size)."""
    from odelab.solvers import api
    from odelab.solvers.compiled.cache import load_kernels
    from odelab.solvers.implicit import resolve_extras, step_class
    from odelab.solvers.options import resolved_for

    opts = resolved_for(m, options, tspan_arr, y0_arr.size)
    given = opts.given
    reason = why_not_stiff(m.name, system, given)
    if reason:
        raise InputError(f"the compiled backend cannot run {m.name} here: {reason}; use backend \"python\".",
                         key="backend")
    for name in ("events", "nonnegative", "output_fcn", "args"):
        if getattr(opts, name, None) not in (None, ()):
            raise InputError(f"the compiled backend does not run `{name}` with {m.name} (it calls Python); use "
                             "backend \"python\".", key=name)
    extra = opts.extra if opts.extra is not None else resolve_extras(m, given, y0_arr.size)
    n = y0_arr.size
    module = system.module(jacobian=True)
    rhs, jac = module.rhs, module.jac
    p = system.parameter_vector()
    t0 = float(tspan_arr[0])
    y0_arr = np.array(y0_arr, dtype=float, order="C")
    f0 = np.empty(n)
    rhs(t0, y0_arr.copy(), p, f0)
    if not np.all(np.isfinite(f0)):
        return api._failed_at_start(m, tspan_arr, y0_arr, opts, f"the derivative at t = {t0:g} is not finite "
                                    f"({api._fmt_vec(f0)}): check the right-hand side at the initial state")
    kernels = load_kernels()
    atol = np.ascontiguousarray(np.broadcast_to(np.asarray(opts.atol, dtype=float), (n,)), dtype=float)
    capacity = tspan_arr.size if tspan_arr.size > 2 else 1 + int(opts.refine) * 64
    args = (rhs, jac, np.array(tspan_arr, dtype=float), y0_arr, f0, p, float(opts.rtol), atol.copy(),
            float(opts.max_step), float(opts.initial_step), int(opts.refine), int(opts.max_steps), int(capacity))
    perm, kl, ku = _band_of(system)
    args = (*args, perm, kl, ku)
    # the loop of the method's name (loops/table.py.txt), with what its step class adds (ode15s: its orders)
    result = kernels.loop(m.name)(*args, *step_class(m.name).compiled_arguments(extra))
    t_out, y_out, count, nsteps, nfailed, nfevals, npds, ndecomps, nsolves, status, t_stop, h_stop = result
    t, y = exact_rows(t_out, y_out, count)
    del t_out, y_out, result
    message = api._status_message(status, m, t_stop, h_stop, y, y0_arr, opts, None, tspan_arr)
    return Solution(t=t, y=y, stats=Stats(nsteps=nsteps, nfailed=nfailed, nfevals=nfevals + 1, npds=npds,
                                          ndecomps=ndecomps, nsolves=nsolves),
                    status=Status(status).label, reason=Status(status), message=message, method=m.name,
                    warnings=opts.warnings)


_BANDS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _band_of(system) -> tuple[np.ndarray, int, int]:
    """(perm, kl, ku) of the banded LU for ``system``'s iteration matrices ((empty, 0, 0): dense),
    from its equations' structure as the Python path's Work plans it from ``jacobian.pattern``
    (a linear system's Jacobian is its matrix A, which the Python path factors dense)."""
    cached = _BANDS.get(system)
    if cached is None:
        from odelab.solvers.banded import MIN_STATES, plan_band, structural_pattern

        band = None
        if system.kind == "equations" and len(system.states) >= MIN_STATES:
            band = plan_band(structural_pattern([p.names for p in system._parsed()], system.states))
        cached = (np.zeros(0, dtype=np.int64), 0, 0) if band is None else (band.perm, band.kl, band.ku)
        _BANDS[system] = cached
    return cached
