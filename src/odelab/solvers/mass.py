"""Mass matrices for the explicit solvers: ``M(t, y) y' = f(t, y)`` (MATLAB's ``Mass`` option).

MATLAB's ``ode45`` and ``ode23`` accept a non-singular mass matrix and solve ``M y' = f`` for
``y'`` wherever the method needs a derivative (its ``odemassexplicit``): with a constant ``M``
by its LU factors, with ``M(t)`` or ``M(t, y)`` by solving with the matrix of that stage. A
singular ``M`` makes the problem a DAE, which explicit Runge-Kutta methods cannot solve.

``MStateDependence`` says how ``M`` depends on ``y``: "none" (called as ``M(t)``), "weak" or
"strong" (called as ``M(t, y)``; the distinction matters only to implicit methods). When it is
not given, a function taking one argument (besides ``args``) is taken as ``M(t)`` and any
other as ``M(t, y)``; MATLAB's default "weak" would call ``M(t, y)``.
"""

from __future__ import annotations

import inspect

import numpy as np

from odelab.exceptions import InputError

__all__ = ["with_mass"]

_DAE_HINT = (
    "M y' = f with a singular M is a differential-algebraic equation (DAE), which ode45/ode23 cannot "
    "solve: MATLAB uses ode15s or ode23t for it; or eliminate the algebraic states by hand."
)


def _check_matrix(raw, n: int, where: str, dtype) -> np.ndarray:
    try:
        M = np.array(raw, dtype=complex if np.iscomplexobj(raw) else float)
    except (TypeError, ValueError):
        raise InputError(f"the mass matrix {where} must be an n-by-n matrix of numbers; got {raw!r}.",
                         key="mass") from None
    if n == 1 and M.ndim == 0:
        M = M.reshape(1, 1)
    if M.shape != (n, n):
        raise InputError(f"the mass matrix {where} has shape {M.shape} but the state has {n} "
                         f"component{'s' if n != 1 else ''}: it must be {n}-by-{n}.", key="mass")
    if not np.all(np.isfinite(M)):
        raise InputError(f"the mass matrix {where} has entries that are not finite.", key="mass")
    if np.iscomplexobj(M) and dtype != complex:
        raise InputError(f"the mass matrix {where} is complex but y0 is real; give a complex y0.", key="mass")
    if np.linalg.matrix_rank(M) < n:
        raise InputError(f"the mass matrix {where} is singular. {_DAE_HINT}", key="mass")
    return M


def _takes_one_argument(fn, nargs: int) -> bool:
    try:
        params = list(inspect.signature(fn).parameters.values())
    except (TypeError, ValueError):
        return False
    if any(p.kind is p.VAR_POSITIONAL for p in params):
        return False
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    required = [p for p in positional if p.default is p.empty]
    return len(required) <= 1 + nargs and len(positional) == 1 + nargs


def with_mass(fun, mass, dependence: str | None, args: tuple, t0: float, y0: np.ndarray):
    """Return ``(g, dependence)`` with ``g(t, y) = M^-1 f(t, y)`` for the user's mass option."""
    n = y0.size
    if not callable(mass):
        M = _check_matrix(mass, n, "", y0.dtype)

        def solved(t, y):
            return np.linalg.solve(M, fun(t, y))

        return solved, "none"

    if dependence is None:
        dependence = "none" if _takes_one_argument(mass, len(args)) else "weak"
    depends_on_y = dependence != "none"

    def matrix(t, y):
        return mass(t, y, *args) if depends_on_y else mass(t, *args)

    try:
        first = matrix(t0, y0.copy())
    except Exception as exc:
        call = "M(t, y)" if depends_on_y else "M(t)"
        raise InputError(f"the mass function, called as {call} (mstate_dependence = {dependence!r}), raised "
                         f"{type(exc).__name__}: {exc} at t = {t0:g}.", key="mass") from None
    _check_matrix(first, n, f"at t = {t0:g}", y0.dtype)

    def solved(t, y):
        try:
            return np.linalg.solve(np.asarray(matrix(t, y)).reshape(n, n), fun(t, y))
        except np.linalg.LinAlgError:
            raise ValueError(f"the mass matrix is singular at t = {t:.10g}. {_DAE_HINT}") from None

    return solved, dependence
