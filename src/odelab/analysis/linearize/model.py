"""The linear model: :func:`linearize` about an operating point, in incremental variables."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from odelab.analysis.linearize._system import _check_system, _f, _names, _point_text
from odelab.analysis.linearize.jacobian import jacobians
from odelab.analysis.linearize.operating_point import (
    EQUILIBRIUM_TOL,
    NotAnEquilibriumWarning,
    OperatingPoint,
    operating_point,
)
from odelab.exceptions import InputError
from odelab.systems.nonlinear import as_vector

# ---------------------------------------------------------------------------------------
# Linearisation
# ---------------------------------------------------------------------------------------


def linearize(
    system,
    x0=None,
    u0=None,
    *,
    x_guess=None,
    fixed: Mapping[str, float] | None = None,
    free_inputs: Sequence[str] = (),
    t: float = 0.0,
    check: bool = True,
    tol: float = EQUILIBRIUM_TOL,
):
    """The linear model of ``system`` about an operating point, in incremental variables.

    Parameters
    ----------
    system
        A NonlinearSystem (or a StateSpace, returned with the same matrices).
    x0
        The operating state x̄. ``None`` (default): found by :func:`operating_point` for
        ``u0`` (from ``x_guess``, with ``fixed`` states and ``free_inputs``).
    u0
        The operating input ū; default zeros.
    check
        With a given ``x0``: check the shapes ``dynamics`` and ``output`` return and warn
        (:class:`NotAnEquilibriumWarning`) if max |f(x0, u0)| > ``tol``.

    Returns
    -------
    StateSpace
        x̂' = A x̂ + B û, ŷ = C x̂ + D û with ``operating_point`` the
        :class:`OperatingPoint`. Its states, inputs and outputs keep the system's names but
        mean *deviations* x̂ = x - x̄, û = u - ū, ŷ = y - ȳ: simulate it with u - ū from
        x(0) - x̄ and add x̄ (ȳ) back, as :func:`compare_linearization` does.
    """
    from odelab.systems.statespace import StateSpace

    _check_system(system)
    states, inputs, outputs = (_names(system, w) for w in ("states", "inputs", "outputs"))
    t = float(t)
    if x0 is None:
        op = operating_point(system, u0=u0, x_guess=x_guess, fixed=fixed, free_inputs=free_inputs, t=t, tol=tol)
    else:
        if x_guess is not None or fixed or free_inputs:
            raise InputError(
                "give either `x0` (the operating point) or `x_guess`/`fixed`/`free_inputs` "
                "(to search for one), not both.",
                key="x0",
            )
        x = as_vector(x0, states, "x0", word="state")
        u = as_vector(np.zeros(len(inputs)) if u0 is None else u0, inputs, "u0", word="input")
        if check and hasattr(system, "check"):
            system.check(x, u, t)
        f = _f(system, t, x, u)
        residual = float(np.max(np.abs(f), initial=0.0))
        if check and not residual <= tol:
            worst = states[int(np.argmax(np.abs(f)))]
            warnings.warn(
                NotAnEquilibriumWarning(
                    f"x0 = [{_point_text(states, x)}] is not an equilibrium for u0 = "
                    f"[{_point_text(inputs, u)}]: max |f(x0, u0)| = {residual:.3g} "
                    f"(d{worst}/dt = {f[states.index(worst)]:.3g}). The linear model then "
                    "describes deviations from a point that moves, and holds only briefly; "
                    "pass x0=None to find the equilibrium."
                ),
                stacklevel=2,
            )
        op = OperatingPoint(
            x=x,
            u=u,
            y=np.asarray(system.output(t, x, u), dtype=float).reshape(-1),
            residual=residual,
            t=t,
            states=states,
            inputs=inputs,
            outputs=outputs,
        )
    A, B, C, D = jacobians(system, op.x, op.u, t)
    return StateSpace(A, B, C, D, states=states, inputs=inputs, outputs=outputs, operating_point=op)
