"""odelab's own stiff solvers, written from the MATLAB ODE Suite papers (one module each).

:func:`solve_implicit` runs one of them for :func:`odelab.solve`: each module registers its step
class under its method's name (``@register_step("ode23t")``), found by :func:`step_class`, and
:func:`~odelab.solvers.implicit.driver.integrate` drives it; :func:`resolve_extras`
checks MATLAB's options that only they take (``Jacobian``, ``JPattern``, ``Vectorized``,
``Mass``, ``MaxOrder``, ``BDF``). SciPy is imported only when a solve starts.
"""

from __future__ import annotations

import importlib

import numpy as np

from odelab.exceptions import InputError
from odelab.solvers.implicit.common import Work
from odelab.solvers.implicit.driver import STEPS, Stepper, integrate
from odelab.solvers.optionset import as_bool

__all__ = ["resolve_extras", "solve_implicit", "step_class", "EXTRA_DEFAULTS"]

EXTRA_DEFAULTS = {"jacobian": None, "jpattern": None, "vectorized": False, "mass": None, "max_order": 5,
                  "bdf": False}


def _square(name, value, n, what):
    if hasattr(value, "toarray"):  # a scipy.sparse matrix
        shape = value.shape
    else:
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"`{name}` must be {what}: a {n}-by-{n} matrix; got {value!r}.", key=name) from None
        if n == 1 and arr.ndim < 2 and arr.size == 1:
            arr = arr.reshape(1, 1)
        shape = arr.shape
        if arr.ndim == 2 and shape == (n, n) and not np.all(np.isfinite(arr)):
            raise InputError(f"`{name}` must have finite entries.", key=name)
        value = arr
    if tuple(shape) != (n, n):
        raise InputError(f"`{name}` must be {what}: a {n}-by-{n} matrix (one row and column per state); "
                         f"got shape {tuple(shape)}.", key=name)
    return value


def resolve_extras(method, opts, n: int) -> dict:
    """Check the stiff solvers' own options and fill in MATLAB's defaults."""
    out = dict(EXTRA_DEFAULTS)
    if "max_order" in opts:
        k = opts["max_order"]
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= 5:
            raise InputError(f"`max_order` must be 1, 2, 3, 4 or 5 ({method.name}'s MaxOrder); got {k!r}.",
                             key="max_order")
        out["max_order"] = int(k)
    if "bdf" in opts:
        out["bdf"] = as_bool("bdf", opts["bdf"])
    if "vectorized" in opts:
        out["vectorized"] = as_bool("vectorized", opts["vectorized"])
    jac = opts.get("jacobian")
    if method.residual:  # ode15i: J(t, y, yp) -> (dF/dy, dF/dy'), or the pair of constant matrices
        from odelab.solvers.implicit.residual import check_jacobian_option

        out["jacobian"] = check_jacobian_option(jac, n)
        return out
    if jac is not None:
        out["jacobian"] = jac if callable(jac) else _square("jacobian", jac, n, "df/dy (constant) or a callable J(t, y)")
    if opts.get("jpattern") is not None:
        pattern = _square("jpattern", opts["jpattern"], n, "the sparsity pattern of df/dy (nonzero where f_i "
                          "depends on y_j)")
        out["jpattern"] = pattern
    if opts.get("mass") is not None and opts.get("nonnegative") is not None:
        raise InputError(f"`nonnegative` with a `mass` matrix: {method.name} keeps a solution non-negative only "
                         "for y' = f(t, y), as MATLAB's (its NonNegative is not available with a Mass); remove "
                         "one of them (for M y' = f with M nonsingular, write y' = M^-1 f).", key="nonnegative")
    if opts.get("mass") is not None:
        mass = opts["mass"]
        if callable(mass):
            raise InputError("`mass` must be a constant matrix: odelab's stiff solvers take M y' = f(t, y) with "
                             "a constant M (MATLAB's time- or state-dependent Mass is not supported).", key="mass")
        mass = _square("mass", mass, n, "the mass matrix M of M y' = f(t, y)")
        dense = mass.toarray() if hasattr(mass, "toarray") else mass
        if not method.dae and np.linalg.matrix_rank(dense) < n:
            from odelab.solvers.registry import methods_with

            first, *others = methods_with(lambda m: m.dae)
            also = f" (or {', '.join(others)})" if others else ""
            raise InputError(f"`mass` is singular (a DAE); {method.name} needs a nonsingular mass matrix: use "
                             f"{first}{also} for index-1 DAEs, as in MATLAB.", key="mass")
        out["mass"] = mass
    return out


def solve_implicit(fun, tspan, y0, f0, m, opts, events=None):
    """Run the native stiff solver ``m`` and wrap its result as the engine's tuple plus counters.

    ``events``: ``(ev, v0)`` from :func:`odelab.solvers.events.as_event_function`, or None; the
    events found are in ``work.found`` afterwards."""
    extra = opts.extra
    n = y0.size
    mass = extra["mass"]
    jpattern = extra["jpattern"]
    if jpattern is not None and mass is not None:
        from scipy import sparse

        mass = sparse.csc_matrix(mass, dtype=float)
    elif mass is not None and hasattr(mass, "toarray"):
        mass = mass.toarray()
    work = Work(fun, n, jacobian=extra["jacobian"], jpattern=jpattern, vectorized=extra["vectorized"], mass=mass)
    atol = np.broadcast_to(np.asarray(opts.atol, dtype=float), (n,))
    nonnegative = opts.nonnegative  # the right-hand side is already wrapped (odelab.solvers.api)
    stepper = step_class(m.name).for_run(work, tspan, opts.rtol, atol, extra, nonnegative)
    result = integrate(stepper, tspan, y0, f0, opts.max_step, opts.initial_step, opts.refine, opts.max_steps, events)
    return result, work


def step_class(name: str) -> type[Stepper]:
    """The step class of the stiff method ``name``: its module, ``odelab.solvers.implicit.<name>``,
    registers it when imported (:func:`~odelab.solvers.implicit.driver.register_step`)."""
    if name not in STEPS:
        importlib.import_module(f"{__name__}.{name}")
    return STEPS[name]
