"""The Jacobians A, B, C, D: complex-step, central and Ridders' extrapolated differences."""

from __future__ import annotations

import math
import warnings

import numpy as np

from odelab.analysis.linearize._system import _check_system, _is_statespace, _names
from odelab.exceptions import InputError
from odelab.systems.nonlinear import as_vector

#: Complex-step increment. Any h far below sqrt(eps) * |x| gives f'(x) = Im f(x + ih) / h
#: to machine precision, since there is no subtraction (Squire & Trapp, "Using complex
#: variables to estimate derivatives of real functions", SIAM Review 40(1):110-112, 1998);
#: 1e-20 is their choice and keeps h^2 below the smallest normal number's reach for |x| ~ 1.
COMPLEX_STEP = 1e-20

_JACOBIAN_METHODS = ("auto", "complex-step", "richardson")


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
