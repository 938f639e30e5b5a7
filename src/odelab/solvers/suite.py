"""More of MATLAB's ODE suite as functions: ``odelab.ode113(fun, tspan, y0, ...)`` and co.

The stiff solvers' (``odelab.ode15s``, ``ode23s``, ``ode23t``, ``ode23tb``) live in their own
modules (:mod:`odelab.solvers.implicit`), beside their step classes.

Each takes MATLAB's arguments and ``odeset`` option names (``RelTol``, ``AbsTol``,
``MaxStep``, ``InitialStep``, ``Refine``, ``Events``, and for the stiff solvers ``Jacobian``,
``JPattern``, ``Vectorized``, ``Mass``; ``MaxOrder`` and ``BDF`` for ode15s) or odelab's
snake_case names,
and returns a :class:`~odelab.solution.Solution` whose ``stats`` count what MATLAB's
``Stats`` prints (for the stiff solvers also Jacobians, LU decompositions, linear solves).
"""

from __future__ import annotations

import warnings

from odelab.exceptions import SolverWarning
from odelab.solution import Solution
from odelab.solvers.api import solve, solve_residual

__all__ = ["ode113", "ode78", "ode89", "ode15i"]


def ode113(fun, tspan, y0, **options) -> Solution:
    """Solve a non-stiff ODE with MATLAB's ``ode113``: variable-order Adams-Bashforth-Moulton PECE.

    Shampine & Gordon's method (orders 1-13 as MATLAB counts them): two evaluations of ``fun``
    per step, so it wins at tight tolerances and when ``fun`` is expensive. Options as
    :func:`odelab.ode45` (``RelTol``, ``AbsTol``, ``MaxStep``, ``InitialStep``, ``Refine``
    (default 1), ``NormControl``, ``Events``, ``NonNegative``, ``Mass``, ``OutputFcn``...);
    ``deval``/``sol(t)`` evaluate the Adams interpolant (MATLAB's ``ntrp113``).

    Examples
    --------
    >>> import numpy as np, odelab
    >>> sol = odelab.ode113(lambda t, y: np.cos(t), [0, np.pi], 2.0)
    >>> sol.stats
    Stats(nsteps=14, nfailed=0, nfevals=29)
    """
    return solve(fun, tspan, y0, method="ode113", **options)


def ode78(fun, tspan, y0, **options) -> Solution:
    """Solve a non-stiff ODE at tight tolerances with MATLAB's ``ode78``.

    Verner's "most efficient" 8(7) pair (13 stages, advancing with the 8th-order solution)
    with its continuous extension for ``refine``, output times, events and ``deval``; options
    and result as :func:`odelab.ode45` (``refine`` defaults to 1).

    Examples
    --------
    >>> import numpy as np, odelab
    >>> sol = odelab.ode78(lambda t, y: -y, [0, 1], 1.0, RelTol=1e-10, AbsTol=1e-12)
    >>> bool(abs(sol.y[-1, 0] - np.exp(-1)) < 1e-11), sol.stats.nsteps  # MaxStep 0.1*span
    (True, 11)
    """
    return solve(fun, tspan, y0, method="ode78", **options)


def ode89(fun, tspan, y0, **options) -> Solution:
    """Solve a non-stiff ODE at very tight tolerances with MATLAB's ``ode89``.

    Verner's "most robust" 9(8) pair (16 stages, advancing with the 9th-order solution) with
    its 8th-order continuous extension; options and result as :func:`odelab.ode45`
    (``refine`` defaults to 1).
    """
    return solve(fun, tspan, y0, method="ode89", **options)


def ode15i(fun, tspan, y0, yp0, **options):
    """Solve a fully implicit system ``F(t, y, y') = 0`` with MATLAB's ``ode15i``.

    Variable-order (1-5) BDFs in Lagrangian form (Shampine 2002), for ODEs and DAEs of index 1.
    ``fun(t, y, yp)`` returns the residual (one per state); ``y0`` and ``yp0`` must be consistent,
    ``F(t0, y0, yp0) = 0`` (:func:`odelab.decic` makes them so). Options (MATLAB's names too):
    ``rtol``/``RelTol`` (1e-3), ``atol``/``AbsTol`` (1e-6), ``max_step`` (0.1 |tf - t0|),
    ``initial_step``, ``refine`` (1), ``max_steps``, ``max_order``/``MaxOrder`` (5), ``jacobian``
    (a function ``J(t, y, yp) -> (dF/dy, dF/dy')`` or a pair of constant matrices, None for finite
    differences; default both by MATLAB's ``numjac``), ``events`` (``events(t, y, yp) -> (value,
    isterminal, direction)``), ``args``. ``deval``/``sol(t)`` evaluate the BDF polynomials.

    Examples
    --------
    Weissinger's equation, MATLAB's ode15i example (exact solution ``sqrt(t^2 + 1/2)``):

    >>> import numpy as np, odelab
    >>> F = lambda t, y, yp: t*y**2*yp**3 - y**3*yp**2 + t*(t**2 + 1)*yp - t**2*y
    >>> y0, yp0, _ = odelab.decic(F, 1, np.sqrt(1.5), [1], 0, [0])
    >>> sol = odelab.ode15i(F, [1, 10], y0, yp0)
    >>> bool(abs(sol.y[-1, 0] - np.sqrt(100.5)) < 1e-2)
    True
    """
    sol = solve_residual(fun, tspan, y0, yp0, "ode15i", **options)
    from odelab.solvers.plausibility import PREFIX

    if sol.status == "failed":
        warnings.warn(sol.message, SolverWarning, stacklevel=2)
    for note in sol.warnings:
        if note.startswith(PREFIX):  # a result that cannot be right, as ode15s's are checked
            warnings.warn(note, SolverWarning, stacklevel=2)
    return sol
