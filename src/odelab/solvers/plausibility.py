"""Results that cannot be right: two cheap checks on a stiff run's output, said as a warning.

A stiff solver that loses its way (Newton converging to a spurious root, an undamped stiff
error carried onto another branch) can finish with status success and an answer that breaks
what the problem guarantees. odelab cannot know every invariant; two are read off the run
itself, with no extra evaluation, and both are rare in correct runs:

1. **Growth.** The solution grew to more than :data:`GROWTH` (1e6) times its initial scale
   ``max |y0|``: six orders of magnitude beyond where it started. (Not checked when ``y0`` is
   all zeros.)
2. **Sign.** The problem started nonnegative (every ``y0_i >= 0``) and the sum of the
   components stayed constant along the computed solution (to :data:`CONSERVED`, 1e-6 of
   it): a closed system such as mass-action chemical kinetics (Robertson's), whose components
   are amounts and cannot be negative. A component went below ``-NEGATIVE * AbsTol_i``
   (100 times its absolute tolerance, and below -1e-12 times the total): far below anything
   the error control allows. Linear and Runge-Kutta formulas keep a linear invariant the ODE
   has (to the Newton tolerance), so a constant sum on the output means the ODE conserves it;
   a sum that varies (a mechanical oscillator, van der Pol) switches the check off.

The checks run on the stiff methods' results (odelab's ode15s, ode23s, ode23t, ode23tb and
SciPy's Radau, BDF, LSODA). What they find goes into the solution's ``warnings`` (the run's
notes in an experiment) and, from :func:`odelab.solve`, a
:class:`~odelab.exceptions.SolverWarning`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GROWTH", "CONSERVED", "NEGATIVE", "PREFIX", "implausible"]

GROWTH = 1e6
CONSERVED = 1e-6
NEGATIVE = 100.0
PREFIX = "this result cannot be right"


def implausible(t: np.ndarray, y: np.ndarray, y0: np.ndarray, atol, method: str,
                names: tuple[str, ...] | None = None) -> str | None:
    """What is wrong with the output ``(t, y)`` of a run from ``y0`` (None when nothing is found)."""
    y = np.asarray(y)
    y0 = np.asarray(y0)
    if y.ndim != 2 or y.shape[0] < 2 or np.iscomplexobj(y) or not np.all(np.isfinite(y)):
        return None
    n = y.shape[1]
    label = (lambda i: names[i]) if names is not None and len(names) == n else (lambda i: f"y{i + 1}")
    atol = np.broadcast_to(np.asarray(atol, dtype=float), (n,))
    scale = float(np.max(np.abs(y0))) if y0.size else 0.0
    if scale > 0:
        size = np.max(np.abs(y), axis=0)
        i = int(np.argmax(size))
        if size[i] > GROWTH * scale:
            k = int(np.argmax(np.abs(y[:, i])))
            return (f"{PREFIX}: {label(i)} reached {y[k, i]:.3g} at t = {t[k]:.4g}, {size[i] / scale:.2g} times the "
                    f"initial scale max|y0| = {scale:.3g}; {method} may have lost the solution (tighten rtol/atol, "
                    "or compare with another stiff solver).")
    if np.all(y0 >= 0) and scale > 0:
        total = y.sum(axis=1)
        total0 = float(y0.sum())
        if np.all(np.abs(total - total0) <= CONSERVED * abs(total0)):
            floor = -np.maximum(NEGATIVE * atol, 1e-12 * abs(total0))
            low = np.min(y, axis=0)
            bad = np.nonzero(low < floor)[0]
            if bad.size:
                i = int(bad[np.argmin(low[bad] / -floor[bad])])
                k = int(np.argmin(y[:, i]))
                return (f"{PREFIX}: {label(i)} = {y[k, i]:.3g} at t = {t[k]:.4g}, far below -AbsTol = "
                        f"{-atol[i]:.3g}, although the problem started nonnegative and conserves the sum of its "
                        f"components ({total0:.6g}), so its components are amounts that cannot be negative; "
                        f"{method} may have lost the solution (tighten rtol/atol, or compare with another stiff "
                        "solver).")
    return None
