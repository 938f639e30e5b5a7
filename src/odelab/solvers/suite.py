"""Verner's pairs of MATLAB's ODE suite as functions: ``odelab.ode78(fun, tspan, y0, ...)`` and ``odelab.ode89``.

The others live with their methods: ``odelab.ode23`` and ``ode45`` in :mod:`odelab.solvers.api`, ``ode113``
in :mod:`odelab.solvers.adams`, ``dde23`` in :mod:`odelab.solvers.dde23`, the stiff solvers (``odelab.ode15s``,
``ode23s``, ``ode23t``, ``ode23tb``) and ``ode15i`` in their own modules of :mod:`odelab.solvers.implicit`,
beside their step classes.

Each takes MATLAB's arguments and ``odeset`` option names (``RelTol``, ``AbsTol``, ``MaxStep``,
``InitialStep``, ``Refine``, ``Events``...) or odelab's snake_case names, and returns a
:class:`~odelab.solution.Solution` whose ``stats`` count what MATLAB's ``Stats`` prints.
"""

from __future__ import annotations

from odelab.solution import Solution
from odelab.solvers.api import solve

__all__ = ["ode78", "ode89"]


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
