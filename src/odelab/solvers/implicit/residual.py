"""A fully implicit system ``F(t, y, y') = 0``: its residual, its two partial derivatives, the counters.

What ode15i (:mod:`odelab.solvers.implicit.ode15i`) and decic
(:mod:`odelab.solvers.implicit.decic`) share, as MATLAB's ``ode15ipdinit``/``ode15ipdupdate``
do for them (Shampine, *Solving 0 = F(t, y(t), y'(t)) in Matlab*, J. Numer. Math. 10(4), 2002):

* the residual ``F(t, y, yp)``, each evaluation counted;
* ``dF/dy`` and ``dF/dyp``: the user's (a function ``J(t, y, yp) -> (dfdy, dfdyp)`` or a pair of
  constant matrices, either part may be None), or for each part not given MATLAB's ``numjac``
  (:mod:`odelab.solvers.numjac`: adaptive increments ``fac * max(|v|, AbsTol)``, the factors kept
  from one Jacobian to the next, one for ``y`` and one for ``yp``), its evaluations counted in
  ``nfevals`` as MATLAB counts them. Expression systems pass their exact partials by complex
  step (:class:`odelab.systems.implicit.ImplicitSystem`);
* the LU of an iteration matrix and its solves (:class:`odelab.solvers.implicit.common.Work`'s).
"""

from __future__ import annotations

import math

import numpy as np

from odelab.exceptions import InputError
from odelab.solvers.implicit.common import Work
from odelab.solvers.optionset import DEFAULT_ATOL

__all__ = ["ResidualWork", "check_jacobian_option", "index_problem"]

EPS = float(np.finfo(float).eps)


def _matrix(value, n: int, name: str):
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"`jacobian` ({name}) must be an {n}-by-{n} matrix of numbers; got {value!r}.",
                         key="jacobian") from None
    if n == 1 and arr.size == 1:
        arr = arr.reshape(1, 1)
    if arr.shape != (n, n):
        raise InputError(f"`jacobian` ({name}) must be an {n}-by-{n} matrix (one row per residual, one column per "
                         f"state); got shape {arr.shape}.", key="jacobian")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"`jacobian` ({name}) must have finite entries.", key="jacobian")
    return arr


def check_jacobian_option(value, n: int):
    """ode15i's ``Jacobian``: a callable ``J(t, y, yp) -> (dfdy, dfdyp)``, or a pair ``(dfdy, dfdyp)`` of
    constant matrices (MATLAB's ``{dfdy, dfdyp}``), either of them None for finite differences."""
    if value is None or callable(value):
        return value
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return tuple(None if part is None else _matrix(part, n, what) for part, what in zip(value, ("dF/dy", "dF/dy'")))
    raise InputError("`jacobian` of ode15i is a function J(t, y, yp) returning (dF/dy, dF/dy'), or a pair "
                     f"(dF/dy, dF/dy') of constant matrices (None for finite differences); got {value!r}.",
                     key="jacobian")


class ResidualWork(Work):
    """``F(t, y, yp)``, its partials and MATLAB's counters (``nfevals``, ``npds``, ``ndecomps``, ``nsolves``)."""

    def __init__(self, fun, n: int, *, jacobian=None, atol=DEFAULT_ATOL):
        super().__init__(fun, n)
        self.atol = np.broadcast_to(np.asarray(atol, dtype=float), (n,))
        self.partials_function = jacobian if callable(jacobian) else None
        given = jacobian if isinstance(jacobian, tuple) else (None, None)
        self.constant = given  # constant parts (MATLAB's {dfdy, dfdyp}); None: formed at each refresh
        #: both parts constant: the Jacobian never needs refreshing (MATLAB's Jconstant)
        self.jconstant = given[0] is not None and given[1] is not None
        self.fac_y = self.fac_yp = None  # numjac's increment factors, one set per partial

    def F(self, t: float, y: np.ndarray, yp: np.ndarray) -> np.ndarray:
        """The residual (one evaluation)."""
        self.nfevals += 1
        return np.asarray(self.fun(t, y, yp), dtype=float).reshape(self.n)

    def partials(self, t: float, y: np.ndarray, yp: np.ndarray, f=None):
        """``(dF/dy, dF/dyp)`` at ``(t, y, yp)`` (one partial-derivative evaluation, as MATLAB counts:
        ``npds``); ``f = F(t, y, yp)`` serves the differences (evaluated here when needed and None)."""
        from odelab.solvers.numjac import numjac

        self.npds += 1
        n = self.n
        dfdy, dfdyp = self.constant
        if self.partials_function is not None:
            got = self.partials_function(t, y, yp)
            if not (isinstance(got, (tuple, list)) and len(got) == 2):
                raise InputError("the `jacobian` function of ode15i must return two matrices, (dF/dy, dF/dy'); "
                                 f"it returned {type(got).__name__}.", key="jacobian")
            dfdy, dfdyp = (None if part is None else _matrix(part, n, what)
                           for part, what in zip(got, ("dF/dy", "dF/dy'")))
        if dfdy is None or dfdyp is None:
            if f is None:
                f = self.F(t, y, yp)
            if dfdy is None:
                result = numjac(lambda _t, v: self.fun(_t, v, yp), t, y, f, self.atol, self.fac_y)
                self.fac_y, dfdy = result.fac, result.dfdy
                self.nfevals += result.nfevals
            if dfdyp is None:
                result = numjac(lambda _t, v: self.fun(_t, y, v), t, yp, f, self.atol, self.fac_yp)
                self.fac_yp, dfdyp = result.fac, result.dfdy
                self.nfevals += result.nfevals
        return np.asarray(dfdy, dtype=float), np.asarray(dfdyp, dtype=float)


def index_problem(dfdy: np.ndarray, dfdyp: np.ndarray) -> str | None:
    """Why ``F(t, y, y') = 0`` is not of index 1 where these partials were taken, or None.

    With ``r = rank dF/dy'``, ``N`` a basis of its null space (the algebraic directions) and ``W``
    one of its left null space (the algebraic equations), the pencil ``dF/dy + c dF/dy'`` has
    index at most 1 exactly when ``W dF/dy N`` is nonsingular: the algebraic equations determine
    the algebraic variables (Brenan, Campbell & Petzold, *Numerical Solution of Initial-Value
    Problems in DAEs*, 1996, Sec. 2.2). Ranks as MATLAB's decic decides them: singular values
    above ``n eps`` of the largest (``sqrt(eps)`` of ``||dF/dy||`` for ``W dF/dy N``, whose
    numerical partials carry that much error)."""
    n = dfdy.shape[0]
    if n == 0:
        return None
    U, s, Vt = np.linalg.svd(dfdyp)
    r = int(np.sum(s > n * EPS * s[0])) if s[0] > 0 else 0
    if r == n:
        return None
    A = U[:, r:].T @ dfdy @ Vt[r:].T
    scale = float(np.linalg.norm(dfdy, 2))
    sa = np.linalg.svd(A, compute_uv=False)
    rank = int(np.sum(sa > math.sqrt(EPS) * scale)) if scale > 0 else 0
    if rank == n - r:
        return None
    algebraic = n - r
    return (f"dF/dy' has rank {r} of {n} ({algebraic} algebraic equation{'s' if algebraic != 1 else ''}), and "
            f"dF/dy does not determine the algebraic variables from {'them' if algebraic != 1 else 'it'} "
            f"(rank {rank} of {algebraic} on those directions): the DAE is of index 2 or higher, or singular there")
