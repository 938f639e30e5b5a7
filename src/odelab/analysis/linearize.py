"""Operating points, linearisation, and how good the linear model is.

The lab's third part: a nonlinear model x' = f(t, x, u), y = h(t, x, u) is replaced near an
operating point (x̄, ū) with f(x̄, ū) = 0 by its tangent model in incremental variables
x̂ = x - x̄, û = u - ū, ŷ = y - ȳ::

    x̂' = A x̂ + B û,   ŷ = C x̂ + D û,   A = ∂f/∂x, B = ∂f/∂u, C = ∂h/∂x, D = ∂h/∂u.

For the mass-spring-damper m x'' + b x' + f_K(x) = f this is exactly "find x̄ with
f_K(x̄) = f̄ and replace f_K by its tangent k(x̄) = f_K'(x̄)".

Functions
---------
:func:`operating_point`
    Solve f(x̄, ū) = 0 (optionally holding states fixed, or solving for inputs).
:func:`jacobians`
    A, B, C, D to near machine precision: complex-step differentiation when the model
    allows it, Ridders' extrapolated central differences otherwise.
:func:`linearize`
    The incremental :class:`~odelab.systems.statespace.StateSpace`, carrying its
    :class:`OperatingPoint`.
:func:`compare_linearization`, :func:`amplitude_study`
    Simulate both models and measure how far apart they are, and for how large an input
    the linear model stays within a threshold.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.exceptions import InputError
from odelab.systems.nonlinear import as_vector

__all__ = [
    "AmplitudeStudy",
    "ErrorMeasure",
    "LinearizationComparison",
    "NoEquilibriumError",
    "NotAnEquilibriumWarning",
    "OperatingPoint",
    "EQUILIBRIUM_TOL",
    "amplitude_study",
    "compare_linearization",
    "jacobians",
    "linearize",
    "operating_point",
]

#: Default bound on max |f(x̄, ū)| for a point to count as an equilibrium.
EQUILIBRIUM_TOL = 1e-10

#: Complex-step increment. Any h far below sqrt(eps) * |x| gives f'(x) = Im f(x + ih) / h
#: to machine precision, since there is no subtraction (Squire & Trapp, "Using complex
#: variables to estimate derivatives of real functions", SIAM Review 40(1):110-112, 1998);
#: 1e-20 is their choice and keeps h^2 below the smallest normal number's reach for |x| ~ 1.
COMPLEX_STEP = 1e-20

_JACOBIAN_METHODS = ("auto", "complex-step", "richardson")


class NoEquilibriumError(InputError):
    """No equilibrium f(x̄, ū) = 0 was found for the given input."""


class NotAnEquilibriumWarning(UserWarning):
    """A point given as an operating point does not satisfy f(x̄, ū) = 0."""


# ---------------------------------------------------------------------------------------
# Operating points
# ---------------------------------------------------------------------------------------


def _frozen(a) -> np.ndarray:
    out = np.array(a, dtype=float).reshape(-1)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class OperatingPoint:
    """An operating point (x̄, ū, ȳ) of a system, at time ``t``.

    Attributes
    ----------
    x, u, y
        The state, input and output there, shapes (nx,), (nu,), (ny,); read-only.
    residual
        max |f(t, x̄, ū)|: 0 up to rounding at an equilibrium.
    t
        The time at which f was evaluated (matters only for time-varying systems).
    states, inputs, outputs
        The names of the entries of x, u and y.
    """

    x: np.ndarray
    u: np.ndarray
    y: np.ndarray
    residual: float
    t: float = 0.0
    states: tuple[str, ...] = ()
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()

    def __post_init__(self):
        for name in ("x", "u", "y"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        object.__setattr__(self, "residual", float(self.residual))
        object.__setattr__(self, "t", float(self.t))
        for name in ("states", "inputs", "outputs"):
            object.__setattr__(self, name, tuple(getattr(self, name)))

    def is_equilibrium(self, tol: float = EQUILIBRIUM_TOL) -> bool:
        """Whether ``residual <= tol``."""
        return self.residual <= tol

    def as_dict(self) -> dict:
        """``{"x": {name: value}, "u": {...}, "y": {...}, "residual": r, "t": t}``."""
        return {
            "x": dict(zip(self.states, self.x.tolist())),
            "u": dict(zip(self.inputs, self.u.tolist())),
            "y": dict(zip(self.outputs, self.y.tolist())),
            "residual": self.residual,
            "t": self.t,
        }

    def __repr__(self) -> str:
        def named(names, values):
            return ", ".join(f"{n}={v:.10g}" for n, v in zip(names, values))

        return (
            f"OperatingPoint(x: {named(self.states, self.x)}; u: {named(self.inputs, self.u)}; "
            f"y: {named(self.outputs, self.y)}; residual={self.residual:.3g})"
        )


def _is_statespace(system) -> bool:
    try:
        from odelab.systems.statespace import StateSpace
    except ImportError:  # pragma: no cover - statespace is part of odelab
        return False
    return isinstance(system, StateSpace)


def _check_system(system) -> None:
    missing = [a for a in ("states", "inputs", "outputs", "dynamics", "output") if not hasattr(system, a)]
    if missing:
        raise InputError(
            f"`system` must be a NonlinearSystem or StateSpace (with states, inputs, outputs, "
            f"dynamics(t, x, u) and output(t, x, u)); {type(system).__name__} lacks {', '.join(missing)}.",
            key="system",
        )


def _names(system, what: str) -> tuple[str, ...]:
    return tuple(getattr(system, what))


def _f(system, t, x, u) -> np.ndarray:
    return np.asarray(system.dynamics(t, x, u), dtype=float).reshape(-1)


def _point_text(names, values) -> str:
    return ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, values)) or "none"


def operating_point(
    system,
    *,
    u0,
    x_guess=None,
    fixed: Mapping[str, float] | None = None,
    free_inputs: Sequence[str] = (),
    t: float = 0.0,
    tol: float = EQUILIBRIUM_TOL,
) -> OperatingPoint:
    """Find an equilibrium x̄ with f(t, x̄, ū) = 0 for the input ``u0``.

    Parameters
    ----------
    system
        A :class:`~odelab.systems.nonlinear.NonlinearSystem` or
        :class:`~odelab.systems.statespace.StateSpace`.
    u0
        The input ū: a number (one input), a sequence, or a mapping name -> value.
    x_guess
        Where the search starts (default: zeros). A mapping may name only some states; the
        others start at 0. With several equilibria, this chooses which one is found.
    fixed
        States held at given values, e.g. ``{"x": 0.5}``; the others are solved for. With
        more equations than unknowns the result is a least-squares point, accepted only if
        its residual is within ``tol``.
    free_inputs
        Inputs solved for instead of held at ``u0`` (which is then their starting guess):
        with ``fixed={"x": 0.5}, free_inputs=["f"]`` this finds the force f̄ that holds the
        mass at x̄ = 0.5, the lab's question read backwards.
    t
        Time at which f is evaluated.
    tol
        Largest accepted residual max |f(t, x̄, ū)|.

    Returns
    -------
    OperatingPoint

    Raises
    ------
    NoEquilibriumError
        (an :class:`~odelab.exceptions.InputError`) when no point with residual within
        ``tol`` is found; the message gives the best point and residual and what to try.

    Notes
    -----
    Solved with :func:`scipy.optimize.root`, MINPACK's Powell hybrid method (``hybr``)
    first and Levenberg-Marquardt (``lm``) as a fallback, both with the exact Jacobian of
    :func:`jacobians`, then polished by Newton steps so the residual reaches rounding level.
    """
    _check_system(system)
    states, inputs = _names(system, "states"), _names(system, "inputs")
    nx = len(states)
    u = as_vector(np.zeros(len(inputs)) if u0 is None else u0, inputs, "u0", word="input")
    x = np.zeros(nx)
    if x_guess is not None:
        if isinstance(x_guess, Mapping):
            unknown = [k for k in x_guess if k not in states]
            if unknown:
                raise InputError(f"`x_guess` names unknown states {unknown}; the states are {list(states)}.", key="x_guess")
            for k, v in x_guess.items():
                x[states.index(k)] = float(v)
        else:
            x = as_vector(x_guess, states, "x_guess", word="state")
    fixed = dict(fixed or {})
    for k, v in fixed.items():
        if k not in states:
            raise InputError(f"`fixed` names {k!r}, which is not a state; the states are {list(states)}.", key="fixed")
        try:
            x[states.index(k)] = float(v)
        except (TypeError, ValueError):
            raise InputError(f"`fixed[{k!r}]` must be a number; got {v!r}.", key="fixed") from None
    free_inputs = tuple(free_inputs)
    for k in free_inputs:
        if k not in inputs:
            raise InputError(f"`free_inputs` names {k!r}, which is not an input; the inputs are {list(inputs)}.", key="free_inputs")
    if not (isinstance(tol, (int, float)) and tol > 0):
        raise InputError(f"`tol` must be a positive number; got {tol!r}.", key="tol")
    t = float(t)

    ix = np.array([i for i, s in enumerate(states) if s not in fixed], dtype=int)
    iu = np.array([inputs.index(k) for k in free_inputs], dtype=int)
    n_unknown = ix.size + iu.size
    if n_unknown > nx:
        raise InputError(
            f"{n_unknown} unknowns ({', '.join([states[i] for i in ix] + list(free_inputs))}) but only "
            f"{nx} equations f(x̄, ū) = 0: the equilibrium is not unique. Hold more states with "
            "`fixed` or solve for fewer inputs.",
            key="free_inputs" if free_inputs else "fixed",
        )

    def unpack(z):
        xx, uu = x.copy(), u.copy()
        xx[ix] = z[: ix.size]
        uu[iu] = z[ix.size :]
        return xx, uu

    def residual(z):
        xx, uu = unpack(z)
        return _f(system, t, xx, uu)

    def jac(z):
        xx, uu = unpack(z)
        AB = _jacobian_block(system, "dynamics", t, xx, uu, "auto")
        return AB[:, np.concatenate([ix, nx + iu])]

    z = np.concatenate([x[ix], u[iu]])
    r = residual(z)
    if not np.all(np.isfinite(r)):
        bad = [s for s, v in zip(states, r) if not np.isfinite(v)]
        raise InputError(
            f"`dynamics` is not finite at the starting point ({_point_text(states, x)}) for "
            f"{', '.join(bad)}; give an `x_guess` inside the model's domain.",
            key="x_guess",
        )
    best_z, best_r = z, float(np.max(np.abs(r), initial=0.0))
    if best_r > tol and n_unknown > 0:
        best_z, best_r = _solve_equilibrium(residual, jac, z, square=n_unknown == nx, tol=tol)
    elif 0 < best_r and n_unknown > 0:  # a guess already within tol: take it to rounding level
        best_z = _polish(residual, jac, best_z)
        best_r = float(np.max(np.abs(residual(best_z)), initial=0.0))
    xx, uu = unpack(best_z)
    if not best_r <= tol:
        r = residual(best_z)
        worst = states[int(np.nanargmax(np.abs(r)))] if np.any(np.isfinite(r)) else states[0]
        what = f"u0 = [{_point_text(inputs, u)}]" if inputs else "this system"
        raise NoEquilibriumError(
            f"no equilibrium found for {what}: the best point found, [{_point_text(states, xx)}]"
            + (f" with [{_point_text(free_inputs, uu[iu])}]" if iu.size else "")
            + (f" (holding {_point_text(list(fixed), list(fixed.values()))})" if fixed else "")
            + f", leaves max |f(x̄, ū)| = {best_r:.3g} (in d{worst}/dt), above `tol` = {tol:g}. "
            "The system may have no equilibrium for this input (x' = 1 + x^2 has none), or the "
            "search needs help: try another `x_guess`, hold a state with `fixed`, a different "
            "`u0`, or a larger `tol` if the residual is rounding error of large terms.",
            key="u0",
        )
    return OperatingPoint(
        x=xx,
        u=uu,
        y=np.asarray(system.output(t, xx, uu), dtype=float).reshape(-1),
        residual=best_r,
        t=t,
        states=states,
        inputs=inputs,
        outputs=_names(system, "outputs"),
    )


def _solve_equilibrium(residual, jac, z0, *, square: bool, tol: float):
    """Best (z, max|residual|) found by hybr (square systems), lm, and Newton polishing."""
    from scipy.optimize import root

    def norm(z):
        r = residual(z)
        return float(np.max(np.abs(r))) if np.all(np.isfinite(r)) else math.inf

    candidates = [(norm(z0), z0)]
    attempts = (["hybr"] if square else []) + ["lm"]
    for method in attempts:
        start = min(candidates, key=lambda c: c[0])[1]
        options = {"xtol": 1e-14} if method == "hybr" else {"xtol": 1e-15, "ftol": 1e-15}
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore", RuntimeWarning)
                sol = root(residual, start, jac=jac, method=method, options=options)
            z = np.asarray(sol.x, dtype=float)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
            if isinstance(exc, InputError):
                raise
            continue
        z = _polish(residual, jac, z)
        candidates.append((norm(z), z))
        if candidates[-1][0] <= tol:
            break
    r, z = min(candidates, key=lambda c: c[0])
    return z, r


def _polish(residual, jac, z, steps: int = 4):
    """Newton (Gauss-Newton when not square) steps, kept only while they reduce the residual."""
    r = residual(z)
    if not np.all(np.isfinite(r)):
        return z
    size = np.max(np.abs(r), initial=0.0)
    for _ in range(steps):
        if size == 0.0:
            break
        try:
            with np.errstate(all="ignore"):
                dz = np.linalg.lstsq(jac(z), -r, rcond=None)[0]
        except (np.linalg.LinAlgError, ValueError):
            break
        z_new = z + dz
        r_new = residual(z_new)
        new_size = np.max(np.abs(r_new), initial=0.0) if np.all(np.isfinite(r_new)) else math.inf
        if not new_size < size:
            break
        z, r, size = z_new, r_new, new_size
    return z


# ---------------------------------------------------------------------------------------
# Jacobians
# ---------------------------------------------------------------------------------------


class _NotComplexSafe(Exception):
    """The function does not support complex-step differentiation."""


try:  # numpy >= 1.25
    from numpy.exceptions import ComplexWarning
except ImportError:  # pragma: no cover
    ComplexWarning = np.ComplexWarning  # type: ignore[attr-defined]


def _complex_step_jacobian(fun, z0: np.ndarray, f0: np.ndarray) -> np.ndarray:
    """J[:, j] = Im fun(z0 + i h e_j) / h (Squire & Trapp 1998), or raise _NotComplexSafe.

    A function is rejected when it raises on complex input (``math.sin`` raises TypeError),
    silently drops the imaginary part (numpy's ComplexWarning, turned into an error here),
    returns a real array, or returns non-finite values.
    """
    J = np.empty((f0.size, z0.size))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ComplexWarning)
        for j in range(z0.size):
            z = z0.astype(complex)
            z[j] += 1j * COMPLEX_STEP
            try:
                f = np.asarray(fun(z))
            except InputError:
                raise
            except Exception as exc:  # any failure on complex input means: not safe
                raise _NotComplexSafe(f"{type(exc).__name__}: {exc}") from exc
            if not np.iscomplexobj(f):
                raise _NotComplexSafe("returned real values for complex input")
            f = f.reshape(-1)
            if f.size != f0.size or not np.all(np.isfinite(f)):
                raise _NotComplexSafe("returned non-finite values for complex input")
            J[:, j] = f.imag / COMPLEX_STEP
    return J


def _central_jacobian(fun, z0: np.ndarray, f0: np.ndarray) -> np.ndarray:
    """One central difference per column, h = eps^(1/3) max(1, |z_j|); error ~ 1e-10 relative.

    Used only to cross-check complex-step results of functions not known to be analytic.
    """
    J = np.empty((f0.size, z0.size))
    for j in range(z0.size):
        h = np.finfo(float).eps ** (1 / 3) * max(1.0, abs(z0[j]))
        zp, zm = z0.copy(), z0.copy()
        zp[j] += h
        zm[j] -= h
        J[:, j] = (np.asarray(fun(zp), dtype=float).reshape(-1) - np.asarray(fun(zm), dtype=float).reshape(-1)) / (2 * h)
    return J


def _ridders_jacobian(fun, z0: np.ndarray, f0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Central differences with Richardson extrapolation, adaptively (Ridders' method).

    Column j is the limit h -> 0 of D(h) = (f(z + h e_j) - f(z - h e_j)) / 2h, whose error
    is a series in h^2. D is computed for h_k = h_0 / 1.4^k and a Neville tableau
    extrapolates it to h = 0, one more power of h^2 per level; the entry whose change from
    its neighbours is smallest is kept, and the search stops when higher levels get worse
    (rounding takes over). Ridders, "Accurate computation of F'(x) and F'(x) F''(x)",
    Adv. Eng. Software 4(2):75-76, 1982; Press et al., *Numerical Recipes*, 3rd ed., §5.7.

    Accuracy: for smooth f the error is typically 1e-12 to 1e-13 of the scale of f (against
    ~1e-8 for a forward difference and ~1e-10 for one central difference); the per-column
    error estimate (the returned second array) is the tableau's own, max over components.
    h_0 = 0.01 max(1, |z_j|); if f is not finite there (a domain edge), h_0 is reduced.
    """
    con, con2, ntab, safe = 1.4, 1.96, 10, 2.0
    m, n = f0.size, z0.size
    J = np.zeros((m, n))
    err_est = np.zeros(n)

    def central(j, h):
        zp, zm = z0.copy(), z0.copy()
        zp[j] += h
        zm[j] -= h
        with np.errstate(all="ignore"):
            return (np.asarray(fun(zp), dtype=float).reshape(-1) - np.asarray(fun(zm), dtype=float).reshape(-1)) / (2 * h)

    for j in range(n):
        h = 0.01 * max(1.0, abs(z0[j]))
        d = central(j, h)
        while not np.all(np.isfinite(d)) and h > 1e-8 * max(1.0, abs(z0[j])):
            h /= 10
            d = central(j, h)
        a = np.empty((ntab, ntab, m))
        a[0, 0] = d
        best, err = d, math.inf
        for i in range(1, ntab):
            h /= con
            a[0, i] = central(j, h)
            if not np.all(np.isfinite(a[0, i])):
                break
            fac = con2
            for k in range(1, i + 1):
                a[k, i] = (a[k - 1, i] * fac - a[k - 1, i - 1]) / (fac - 1.0)
                fac *= con2
                errt = max(np.max(np.abs(a[k, i] - a[k - 1, i])), np.max(np.abs(a[k, i] - a[k - 1, i - 1])))
                if errt <= err:
                    err, best = errt, a[k, i]
            if np.max(np.abs(a[i, i] - a[i - 1, i - 1])) >= safe * err:
                break
        J[:, j] = best
        err_est[j] = err
    return J, err_est


def _jacobian_block(system, which: str, t: float, x: np.ndarray, u: np.ndarray, method: str) -> np.ndarray:
    """[∂g/∂x  ∂g/∂u] of g = system.dynamics (which="dynamics") or system.output."""
    nx = x.size
    plain = getattr(system, which)
    safe = getattr(system, f"complex_step_{which}", None)
    if which == "output" and safe is None and getattr(system, "has_output_function", True) is False:
        # y = x: exactly [I 0].
        return np.hstack([np.eye(nx), np.zeros((nx, u.size))])
    trusted = getattr(system, "complex_step", None)

    def split(fn):
        return lambda z: fn(t, z[:nx], z[nx:])

    z0 = np.concatenate([x, u]).astype(float)
    f0 = np.asarray(plain(t, x, u), dtype=float).reshape(-1)

    if method == "richardson":
        return _ridders_jacobian(split(plain), z0, f0)[0]
    candidate = safe if safe is not None else plain
    if method == "complex-step" or safe is not None or trusted is True:
        try:
            return _complex_step_jacobian(split(candidate), z0, f0)
        except _NotComplexSafe as exc:
            if method == "complex-step":
                raise InputError(
                    f"`{which}` of this system does not support complex-step differentiation "
                    f"({exc}); use method='auto' or 'richardson'.",
                    key="method",
                ) from None
            return _ridders_jacobian(split(plain), z0, f0)[0]
    if trusted is False:
        return _ridders_jacobian(split(plain), z0, f0)[0]
    # Unknown Python function: try complex step, and accept it only if a central
    # difference agrees, since a function can accept complex numbers and still not be
    # analytic (abs(v) * v gives the wrong derivative without any error).
    try:
        J = _complex_step_jacobian(split(plain), z0, f0)
    except _NotComplexSafe:
        return _ridders_jacobian(split(plain), z0, f0)[0]
    J_check = _central_jacobian(split(plain), z0, f0)
    scale = np.max(np.abs(J_check), initial=0.0) + np.max(np.abs(f0), initial=0.0) + 1e-300
    if np.all(np.isfinite(J_check)) and np.max(np.abs(J - J_check), initial=0.0) <= 1e-6 * scale:
        return J
    return _ridders_jacobian(split(plain), z0, f0)[0]


def jacobians(system, x0, u0=None, t: float = 0.0, *, method: str = "auto"):
    """The Jacobians A = ∂f/∂x, B = ∂f/∂u, C = ∂h/∂x, D = ∂h/∂u at (t, x0, u0).

    Parameters
    ----------
    system
        A NonlinearSystem or StateSpace (whose own matrices are returned).
    x0, u0
        The point; ``u0`` defaults to zeros. Numbers, sequences or mappings name -> value.
    t
        Time.
    method
        ``"auto"`` (default), ``"complex-step"`` or ``"richardson"``.

    Returns
    -------
    A, B, C, D : ndarray
        Shapes (nx, nx), (nx, nu), (ny, nx), (ny, nu).

    Notes
    -----
    With ``"auto"``:

    * a system built from expressions is differentiated by complex step,
      f'(x) = Im f(x + ih) / h with h = 1e-20 (Squire & Trapp, SIAM Review 40(1), 1998),
      through its complex-step-safe functions: no subtraction, so the result is exact to
      rounding (~1e-16 relative);
    * a Python-function system is tried with complex input; if it raises, drops the
      imaginary part (ComplexWarning), returns real values, or disagrees with a central
      difference (a non-analytic function such as ``abs``), it falls back to
    * Ridders' adaptive central differences with Richardson extrapolation, typically
      accurate to 1e-12..1e-13 of the scale of f for smooth f (never a forward difference).

    ``NonlinearSystem(..., complex_step=True/False)`` skips the detection. When y = x,
    C = I and D = 0 exactly.
    """
    _check_system(system)
    if method not in _JACOBIAN_METHODS:
        raise InputError(f"`method` must be one of {', '.join(_JACOBIAN_METHODS)}; got {method!r}.", key="method")
    states, inputs = _names(system, "states"), _names(system, "inputs")
    if _is_statespace(system):
        return tuple(np.array(getattr(system, name), dtype=float, copy=True) for name in "ABCD")
    x = as_vector(x0, states, "x0", word="state")
    u = as_vector(np.zeros(len(inputs)) if u0 is None else u0, inputs, "u0", word="input")
    t = float(t)
    nx = x.size
    AB = _jacobian_block(system, "dynamics", t, x, u, method)
    CD = _jacobian_block(system, "output", t, x, u, method)
    return AB[:, :nx], AB[:, nx:], CD[:, :nx], CD[:, nx:]


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


# ---------------------------------------------------------------------------------------
# How good is the linear model?
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ErrorMeasure:
    """How far the linear model is from the nonlinear one for one state or output.

    Attributes
    ----------
    max_abs_error
        max_t |z_nl(t) - z_lin(t)|, with z_lin in absolute variables (x̄ or ȳ added back).
    max_rel_error
        ``max_abs_error / peak_deviation``.
    peak_deviation
        max_t |z_nl(t) - z̄|: the size of the incremental response, the normalisation.

    Notes
    -----
    The relative error is normalised by the peak incremental response, not pointwise: a
    pointwise |z_nl - z_lin| / |z_nl - z̄| is undefined where the response crosses the
    operating point (and |z_nl - z_lin| / |z_nl| measures x̄, not the model). When the
    response does not move at all (peak 0), the relative error is 0 if the models agree
    exactly and inf otherwise.
    """

    max_abs_error: float
    max_rel_error: float
    peak_deviation: float


def _error_measure(z_nl: np.ndarray, z_lin: np.ndarray, z_bar: float) -> ErrorMeasure:
    if z_nl.size == 0:
        return ErrorMeasure(math.nan, math.nan, math.nan)
    abs_err = float(np.max(np.abs(z_nl - z_lin)))
    peak = float(np.max(np.abs(z_nl - z_bar)))
    if peak > 0:
        rel = abs_err / peak
    else:
        rel = 0.0 if abs_err == 0 else math.inf
    return ErrorMeasure(abs_err, rel, peak)


@dataclass(frozen=True)
class LinearizationComparison:
    """The nonlinear and the linear model simulated with the same input, side by side.

    Attributes
    ----------
    t
        The common output times, shape (N,).
    x_nonlinear, x_linear
        States, shape (N, nx), both in absolute variables (x̄ added back to the linear run).
    y_nonlinear, y_linear
        Outputs, shape (N, ny), both absolute (ȳ added back).
    u
        The input applied to the nonlinear model, shape (N, nu).
    states, inputs, outputs
        Names.
    operating_point
        The linear model's :class:`OperatingPoint`.
    state_errors, output_errors
        Name -> :class:`ErrorMeasure`.
    status, message
        ``"success"``, or ``"failed"`` when either simulation stopped early (the errors then
        cover the times both reached); the message says which and why.
    nonlinear, linear
        The two :class:`~odelab.systems.simulate.Response` objects as simulated (the linear
        one in incremental variables).
    """

    t: np.ndarray
    x_nonlinear: np.ndarray
    x_linear: np.ndarray
    y_nonlinear: np.ndarray
    y_linear: np.ndarray
    u: np.ndarray
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    operating_point: OperatingPoint
    state_errors: Mapping[str, ErrorMeasure]
    output_errors: Mapping[str, ErrorMeasure]
    status: str = "success"
    message: str = ""
    nonlinear: Any = field(default=None, repr=False, compare=False)
    linear: Any = field(default=None, repr=False, compare=False)

    @property
    def success(self) -> bool:
        return self.status == "success"

    def error(self, name: str) -> ErrorMeasure:
        """The :class:`ErrorMeasure` of an output or, failing that, a state, by name."""
        if name in self.output_errors:
            return self.output_errors[name]
        if name in self.state_errors:
            return self.state_errors[name]
        raise InputError(
            f"{name!r} is neither an output ({', '.join(self.outputs)}) nor a state "
            f"({', '.join(self.states)}).",
            key="quantity",
        )

    @property
    def max_abs_error(self) -> dict[str, float]:
        """Name -> max absolute error, states then outputs (an output sharing a state's name wins)."""
        return {k: e.max_abs_error for k, e in {**self.state_errors, **self.output_errors}.items()}

    @property
    def max_rel_error(self) -> dict[str, float]:
        """Name -> max error relative to the peak incremental response (see ErrorMeasure)."""
        return {k: e.max_rel_error for k, e in {**self.state_errors, **self.output_errors}.items()}

    def __repr__(self) -> str:
        rel = ", ".join(f"{k}={v:.3g}" for k, v in self.max_rel_error.items())
        return f"LinearizationComparison(status={self.status!r}, points={self.t.size}, max_rel_error: {rel})"


def _deviation_signals(u, inputs: tuple[str, ...], u_bar: np.ndarray):
    """The input of the linear model, û = u - ū, one signal per input."""
    from odelab.signals import as_signals

    signals = as_signals(u, inputs)
    return tuple(s - float(ub) if ub != 0 else s for s, ub in zip(signals, u_bar))


def _common_times(t_nl: np.ndarray) -> np.ndarray:
    """The nonlinear run's output times as a strictly increasing tspan for the linear run.

    A run restarted at a breakpoint may report that time twice (before and after the
    jump); the linear run is asked for each time once and its values are spread back.
    """
    return np.unique(t_nl)


def compare_linearization(
    system,
    linear,
    u,
    x_init,
    tspan,
    *,
    method: str = "ode45",
    **options,
) -> LinearizationComparison:
    """Simulate the nonlinear system and its linearisation with the same input; compare.

    Parameters
    ----------
    system
        The nonlinear system.
    linear
        Its linearisation, a StateSpace from :func:`linearize` (it must carry an
        ``operating_point``).
    u
        The input of the nonlinear system: a signal (one input), a sequence or a mapping of
        signals, or None (zero input).
    x_init
        The nonlinear system's initial state x(0).
    tspan
        ``[t0, tf]`` or output times, as for :func:`~odelab.systems.simulate.simulate`.
    method, **options
        Solver and its options (``rtol``, ``atol``, ``max_step``...), used for both runs.

    Returns
    -------
    LinearizationComparison

    Notes
    -----
    The linear model runs in incremental variables, as in the lab: input û = u - ū, initial
    state x̂(0) = x(0) - x̄; then x̄ and ȳ are added back. It is evaluated at the nonlinear
    run's output times (passed as its ``tspan``), so both are compared point by point on
    the same grid, and the comparison measures the model, not an interpolation. The
    relative errors are normalised by the peak incremental response, see
    :class:`ErrorMeasure`.
    """
    from odelab.systems.simulate import simulate

    _check_system(system)
    op = getattr(linear, "operating_point", None)
    if not isinstance(op, OperatingPoint):
        raise InputError(
            "`linear` has no operating point: build it with linearize(system, ...), which "
            "records x̄, ū and ȳ, so the comparison knows what to add back.",
            key="linear",
        )
    states, inputs, outputs = (_names(system, w) for w in ("states", "inputs", "outputs"))
    for what, mine, theirs in (
        ("states", states, tuple(linear.states)),
        ("inputs", inputs, tuple(linear.inputs)),
        ("outputs", outputs, tuple(linear.outputs)),
    ):
        if len(mine) != len(theirs):
            raise InputError(
                f"`linear` has {len(theirs)} {what} ({', '.join(theirs)}) but `system` has "
                f"{len(mine)} ({', '.join(mine)}): it is not a linearisation of this system.",
                key="linear",
            )
    x_init = as_vector(x_init, states, "x_init", word="state")

    nl = simulate(system, tspan, x_init, u, method=method, **options)
    t = np.asarray(nl.t, dtype=float)
    du = _deviation_signals(u, inputs, op.u)
    t_lin = _common_times(t)
    if t_lin.size >= 2:
        lin = simulate(linear, t_lin, x_init - op.x, du if inputs else None, method=method, **options)
    else:  # the nonlinear run stopped at once; nothing to compare
        lin = None

    n = t.size
    if lin is not None and lin.t.size == t_lin.size and np.array_equal(lin.t, t_lin):
        index = np.searchsorted(t_lin, t)
        x_lin = np.asarray(lin.x)[index] + op.x
        y_lin = np.asarray(lin.y)[index] + op.y
        n_ok = n
    else:  # the linear run stopped early (or never ran): compare where both have values
        reached = 0 if lin is None else int(np.searchsorted(t, lin.t[-1], side="right")) if lin.t.size else 0
        n_ok = min(reached, n)
        x_lin = np.full((n, len(states)), np.nan)
        y_lin = np.full((n, len(outputs)), np.nan)
        if lin is not None and n_ok:
            index = np.searchsorted(np.asarray(lin.t), t[:n_ok])
            x_lin[:n_ok] = np.asarray(lin.x)[index] + op.x
            y_lin[:n_ok] = np.asarray(lin.y)[index] + op.y
    x_nl, y_nl = np.asarray(nl.x, dtype=float), np.asarray(nl.y, dtype=float)

    state_errors = {
        s: _error_measure(x_nl[:n_ok, i], x_lin[:n_ok, i], op.x[i]) for i, s in enumerate(states)
    }
    output_errors = {
        s: _error_measure(y_nl[:n_ok, i], y_lin[:n_ok, i], op.y[i]) for i, s in enumerate(outputs)
    }
    problems = []
    if nl.status != "success":
        problems.append(f"the nonlinear run failed: {nl.message}")
    if lin is None:
        problems.append("the linear run was not started (the nonlinear run gave fewer than 2 times)")
    elif lin.status != "success":
        problems.append(f"the linear run failed: {lin.message}")
    if problems:
        status = "failed"
        message = "; ".join(problems) + f" The errors cover t <= {t[n_ok - 1]:g}." if n_ok else "; ".join(problems)
    else:
        status, message = "success", "Both runs reached the end of the time span."
    return LinearizationComparison(
        t=t,
        x_nonlinear=x_nl,
        x_linear=x_lin,
        y_nonlinear=y_nl,
        y_linear=y_lin,
        u=np.asarray(nl.u, dtype=float),
        states=states,
        inputs=inputs,
        outputs=outputs,
        operating_point=op,
        state_errors=state_errors,
        output_errors=output_errors,
        status=status,
        message=message,
        nonlinear=nl,
        linear=lin,
    )


@dataclass(frozen=True)
class AmplitudeStudy:
    """How the linearisation error grows with the size of the input.

    Attributes
    ----------
    amplitudes
        The amplitudes studied, increasing.
    quantity
        The name (output or state) whose error decides ``max_amplitude_within``.
    threshold
        The largest acceptable relative error.
    relative_error, absolute_error
        The max relative / absolute error of ``quantity``, one per amplitude.
    max_rel_error, max_abs_error
        Name (every state and output) -> array of errors, one per amplitude.
    comparisons
        The :class:`LinearizationComparison` of each amplitude.
    max_amplitude_within
        The largest *tested* amplitude a such that the relative error of ``quantity`` is
        within ``threshold`` (<=) for a and every smaller tested amplitude, and every run up
        to a succeeded; None if the smallest amplitude already exceeds it. No interpolation.
    threshold_amplitude
        An estimate of the amplitude where the error reaches ``threshold``: linear
        interpolation of log(error) against log(amplitude) between ``max_amplitude_within``
        and the next tested amplitude (the error is close to a power law c a^p there). None
        when the threshold is not crossed within the tested range.
    """

    amplitudes: np.ndarray
    quantity: str
    threshold: float
    relative_error: np.ndarray
    absolute_error: np.ndarray
    max_rel_error: Mapping[str, np.ndarray]
    max_abs_error: Mapping[str, np.ndarray]
    comparisons: tuple[LinearizationComparison, ...] = field(repr=False)
    max_amplitude_within: float | None = None
    threshold_amplitude: float | None = None

    def slope(self, name: str | None = None) -> float:
        """The least-squares slope p of log(relative error) against log(amplitude).

        The relative error behaves like c a^p: p = 2 about a point where the nonlinearity
        is odd (the first neglected term is cubic), p = 1 where a quadratic term remains.
        ``name`` defaults to ``quantity``; amplitudes with zero or non-finite error are left out.
        """
        name = self.quantity if name is None else name
        if name not in self.max_rel_error:
            raise InputError(f"{name!r} is not a state or output of the study; use one of {list(self.max_rel_error)}.", key="name")
        err = np.asarray(self.max_rel_error[name], dtype=float)
        ok = np.isfinite(err) & (err > 0)
        if np.count_nonzero(ok) < 2:
            raise InputError(f"the slope needs at least two amplitudes with a positive, finite error for {name!r}.", key="name")
        return float(np.polyfit(np.log(self.amplitudes[ok]), np.log(err[ok]), 1)[0])

    def __repr__(self) -> str:
        return (
            f"AmplitudeStudy(quantity={self.quantity!r}, threshold={self.threshold:g}, "
            f"amplitudes={self.amplitudes.tolist()}, relative_error="
            f"{[float(f'{e:.3g}') for e in self.relative_error]}, "
            f"max_amplitude_within={self.max_amplitude_within}, "
            f"threshold_amplitude={self.threshold_amplitude})"
        )


def amplitude_study(
    system,
    linear,
    make_input: Callable[[float], Any],
    amplitudes: Sequence[float],
    x_init,
    tspan,
    *,
    threshold: float = 0.05,
    quantity: str | None = None,
    method: str = "ode45",
    **options,
) -> AmplitudeStudy:
    """For how large an input does the linear model stay good? Compare at several amplitudes.

    Parameters
    ----------
    system, linear
        The nonlinear system and its linearisation (with an operating point).
    make_input
        ``make_input(a)`` returns the input signal(s) for amplitude ``a``, e.g.
        ``lambda a: Step(time=1, initial=f_bar, final=f_bar + a)``.
    amplitudes
        Positive amplitudes (sorted here). To study negative inputs, let ``make_input``
        flip the sign.
    x_init, tspan, method, **options
        As for :func:`compare_linearization`; the same for every amplitude.
    threshold
        The acceptable relative error (default 5 %).
    quantity
        The output or state whose relative error is judged; default the first output.

    Returns
    -------
    AmplitudeStudy
        A failed run (e.g. the nonlinear model blows up) counts as exceeding the threshold.
    """
    if not callable(make_input):
        raise InputError(f"`make_input` must be a function of the amplitude; got {make_input!r}.", key="make_input")
    try:
        a = np.array(amplitudes, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"`amplitudes` must be numbers; got {amplitudes!r}.", key="amplitudes") from None
    if a.size == 0 or not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise InputError(
            f"`amplitudes` must be positive, finite numbers (at least one); got {a.tolist()}. "
            "To study negative inputs, let `make_input` flip the sign.",
            key="amplitudes",
        )
    a = np.unique(a)
    if not (isinstance(threshold, (int, float)) and math.isfinite(threshold) and threshold > 0):
        raise InputError(f"`threshold` must be positive; got {threshold!r}.", key="threshold")
    states, outputs = _names(system, "states"), _names(system, "outputs")
    if quantity is None:
        quantity = outputs[0] if outputs else states[0]
    elif quantity not in outputs and quantity not in states:
        raise InputError(
            f"`quantity` must be an output ({', '.join(outputs)}) or a state "
            f"({', '.join(states)}); got {quantity!r}.",
            key="quantity",
        )

    comparisons = tuple(
        compare_linearization(system, linear, make_input(float(ai)), x_init, tspan, method=method, **options)
        for ai in a
    )
    names = list(dict.fromkeys([*states, *outputs]))
    rel = {n: np.array([c.max_rel_error[n] for c in comparisons]) for n in names}
    abs_ = {n: np.array([c.max_abs_error[n] for c in comparisons]) for n in names}
    err = np.array([c.error(quantity).max_rel_error for c in comparisons])
    err_abs = np.array([c.error(quantity).max_abs_error for c in comparisons])
    for arr in (*rel.values(), *abs_.values(), err, err_abs):
        arr.setflags(write=False)
    a.setflags(write=False)

    ok = np.array([c.success for c in comparisons]) & (err <= threshold)
    k = int(np.argmin(ok)) if not ok.all() else a.size  # index of the first amplitude not within
    max_within = float(a[k - 1]) if k > 0 else None
    threshold_amplitude = None
    if 0 < k < a.size and comparisons[k].success and err[k - 1] > 0 and np.isfinite(err[k]):
        la, lb = math.log(a[k - 1]), math.log(a[k])
        ea, eb = math.log(err[k - 1]), math.log(err[k])
        if eb > ea:
            threshold_amplitude = float(math.exp(la + (math.log(threshold) - ea) * (lb - la) / (eb - ea)))
    return AmplitudeStudy(
        amplitudes=a,
        quantity=quantity,
        threshold=float(threshold),
        relative_error=err,
        absolute_error=err_abs,
        max_rel_error=rel,
        max_abs_error=abs_,
        comparisons=comparisons,
        max_amplitude_within=max_within,
        threshold_amplitude=threshold_amplitude,
    )
