"""MATLAB's ``decic``: consistent initial conditions ``F(t0, y0, yp0) = 0`` for ode15i.

Written from Shampine, *Solving 0 = F(t, y(t), y'(t)) in Matlab*, J. Numer. Math. 10(4), 2002,
Sec. 3, and MATLAB's ``decic`` as documented: starting from the guesses, a Newton-like iteration
changes the components not held fixed. Each iteration solves the underdetermined linear system
``0 = F + dF/dy dy + dF/dyp dyp`` for the free components so that as many components (of a
transformed basis) as possible stay unchanged: a QR factorisation with column pivoting of
``dF/dyp`` on the free slopes, ``Q^T dF/dy`` on the free values for the rows ``dF/dyp`` cannot
reach (the algebraic equations), each solved for its basic solution (zeros in the columns the
pivoting leaves out, as MATLAB's backslash gives). Three chord iterations per Jacobian, at most
ten Jacobians; a change larger than twice the size of ``(y0, yp0)`` is scaled back to that (a
trust region); converged when the residual's 2-norm is no larger than the guess's and the last
change is below ``1e-3 RelTol`` of the solution's size. The ranks decide what cannot be done:
more components fixed than the system leaves free, or a DAE whose algebraic equations do not
determine its algebraic variables (index greater than 1).
"""

from __future__ import annotations

import numpy as np

from odelab.exceptions import InputError
from odelab.solvers.implicit.residual import ResidualWork, check_jacobian_option, index_problem
from odelab.solvers.optionset import DEFAULT_ATOL, DEFAULT_RTOL, canonical

__all__ = ["decic", "DecicError"]

EPS = float(np.finfo(float).eps)


class DecicError(InputError):
    """decic cannot make the initial conditions consistent (what, and what to change, in the message)."""


def _qr(A: np.ndarray):
    """``Q, R, perm, rank`` of ``A[:, perm] = Q R`` (column pivoting; rank as MATLAB's decic decides it)."""
    from scipy.linalg import qr

    m, p = A.shape
    if p == 0:
        return np.eye(m), np.zeros((m, 0)), np.zeros(0, dtype=int), 0
    Q, R, perm = qr(A, pivoting=True)
    diag = np.abs(np.diag(R))
    tol = max(m, p) * EPS * (diag[0] if diag.size else 0.0)
    rank = int(np.flatnonzero(diag > tol)[-1] + 1) if np.any(diag > tol) else 0
    return Q, R, perm, rank


def _rank(A: np.ndarray) -> int:
    if A.size == 0:
        return 0
    return _qr(A)[3]


def _basic_solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A basic solution of ``A x = b`` (MATLAB's backslash on a rectangular or rank-deficient A):
    QR with column pivoting, zeros in the columns beyond the rank."""
    m, p = A.shape
    x = np.zeros(p)
    if p == 0 or m == 0:
        return x
    Q, R, perm, rank = _qr(A)
    if rank:
        x[perm[:rank]] = np.linalg.solve(R[:rank, :rank], (Q.T @ b)[:rank])
    return x


class _Plan:
    """What stays the same over the chord iterations of one Jacobian: the factorisation and the ranks."""

    def __init__(self, dfdy, dfdyp, n, free_y, free_yp):
        self.n, self.free_y, self.free_yp = n, free_y, free_yp
        self.partials = (dfdy, dfdyp)
        fixed = (n - free_y.size) + (n - free_yp.size)
        if free_y.size == 0:  # 0 = F + dF/dyp dyp
            self.Q, self.R, self.perm, self.rank = _qr(dfdyp[:, free_yp])
            self._check(n - self.rank, fixed)
            self.mode = "yp"
        elif free_yp.size == 0:  # 0 = F + dF/dy dy
            self.Q, self.R, self.perm, self.rank = _qr(dfdy[:, free_y])
            self._check(n - self.rank, fixed)
            self.mode = "y"
        else:
            self.Q, self.R, self.perm, self.rank = _qr(dfdyp[:, free_yp])
            self.mode = "both"
            self.S = None
            if self.rank != n:
                self.S = self.Q.T @ dfdy[:, free_y]
                srank = _rank(self.S[self.rank:, :])
                self._check(n - (self.rank + srank), fixed)

    def _check(self, rankdef: int, fixed: int) -> None:
        if rankdef <= 0:
            return

        why = index_problem(*self.partials)  # no choice of fixed components helps a DAE of index > 1
        if rankdef <= fixed and why is None:
            raise DecicError(
                f"decic cannot make the initial conditions consistent with the components held fixed: the "
                f"equations leave {rankdef} fewer free than that; fix {rankdef} fewer (MATLAB: 'Try freeing "
                f"{rankdef} fixed component{'s' if rankdef != 1 else ''}').", key="fixed")
        reason = why or ("the algebraic equations do not determine the algebraic variables left free (dF/dy' is "
                         "singular and dF/dy does not make up for it): the DAE is of index greater than 1 or singular")
        raise DecicError(f"decic cannot make the initial conditions consistent: {reason}; ode15i and decic solve "
                         "index-1 problems (as MATLAB's).", key="fun")

    def step(self, res: np.ndarray):
        n = self.n
        dy, dyp = np.zeros(n), np.zeros(n)
        d = -(self.Q.T @ res)
        rank = self.rank
        if self.mode == "yp":
            dyp[self.free_yp[self.perm[:rank]]] = np.linalg.solve(self.R[:rank, :rank], d[:rank]) if rank else 0.0
            return dy, dyp
        if self.mode == "y":
            dy[self.free_y[self.perm[:rank]]] = np.linalg.solve(self.R[:rank, :rank], d[:rank]) if rank else 0.0
            return dy, dyp
        if rank == n:
            dyp[self.free_yp[self.perm[:rank]]] = np.linalg.solve(self.R[:rank, :rank], d[:rank])
            return dy, dyp
        S = self.S
        w = _basic_solve(S[rank:, :], d[rank:])
        w1p = np.linalg.solve(self.R[:rank, :rank], d[:rank] - S[:rank, :] @ w) if rank else np.zeros(0)
        dy[self.free_y] = w
        dyp[self.free_yp[self.perm[:rank]]] = w1p
        return dy, dyp


def _free(fixed, n: int, name: str) -> np.ndarray:
    if fixed is None:
        return np.arange(n)
    arr = np.atleast_1d(np.asarray(fixed))
    if arr.size == 0:
        return np.arange(n)
    try:
        flags = arr.astype(float)
    except (TypeError, ValueError):
        raise InputError(f"`{name}` must be {n} zeros and ones (1: held fixed); got {fixed!r}.", key=name) from None
    if flags.size != n or not np.all((flags == 0) | (flags == 1)):
        raise InputError(f"`{name}` must be {n} zeros and ones (1: held fixed, MATLAB's FIXED_Y0); got {fixed!r}.",
                         key=name)
    return np.flatnonzero(flags == 0)


def decic(odefun, t0, y0, fixed_y0, yp0, fixed_yp0, options=None):
    """Consistent initial conditions for ``F(t, y, y') = 0`` (MATLAB's ``decic``).

    Returns ``(y0new, yp0new, resnrm)``: values close to the guesses ``y0``, ``yp0`` with
    ``F(t0, y0new, yp0new) = 0`` (``resnrm`` the 2-norm of that residual), changing only
    components whose flag in ``fixed_y0`` / ``fixed_yp0`` is 0 (None or empty: all may change).
    ``options``: a dict with ``rtol``/``RelTol`` (1e-3), ``atol``/``AbsTol`` (1e-6) and ``jacobian``
    (as :func:`odelab.ode15i` takes it). Raises :class:`DecicError` (an ``InputError``) when it
    cannot: too many components fixed, an index greater than 1, or no convergence.

    Examples
    --------
    >>> import numpy as np, odelab
    >>> F = lambda t, y, yp: t*y**2*yp**3 - y**3*yp**2 + t*(t**2 + 1)*yp - t**2*y
    >>> y0, yp0, resnrm = odelab.decic(F, 1, np.sqrt(1.5), [1], 0, [0])
    >>> round(float(yp0[0]), 6)   # y' = t / sqrt(t^2 + 1/2) at t = 1
    0.816497
    """
    if not callable(odefun):
        raise InputError(f"`odefun` must be a callable F(t, y, yp); got {odefun!r}.", key="odefun")
    from odelab.solvers.options import as_y0

    y0 = np.array(as_y0(y0), dtype=float)
    try:
        yp0 = np.array(as_y0(yp0), dtype=float)
    except InputError as exc:
        raise InputError(str(exc).replace("`y0`", "`yp0`"), key="yp0") from None
    n = y0.size
    if yp0.size != n:
        raise InputError(f"`yp0` has {yp0.size} entries but `y0` has {n}: give one slope per state.", key="yp0")
    try:
        t0 = float(t0)
    except (TypeError, ValueError):
        raise InputError(f"`t0` must be a number; got {t0!r}.", key="t0") from None
    free_y = _free(fixed_y0, n, "fixed_y0")
    free_yp = _free(fixed_yp0, n, "fixed_yp0")
    if free_y.size + free_yp.size < n:
        raise DecicError(f"decic can hold at most {n} of the {2 * n} components of y0 and yp0 fixed (one equation "
                         f"per state leaves {n} to find); {2 * n - free_y.size - free_yp.size} are fixed: free "
                         "some of them.", key="fixed")
    rtol, atol, jacobian = _options(options or {}, n)
    work = ResidualWork(odefun, n, jacobian=jacobian, atol=atol)
    res = _residual(work, t0, y0, yp0)
    dfdy, dfdyp = work.partials(t0, y0, yp0, res)
    resnrm0 = float(np.linalg.norm(res))
    plan = None
    for counter in range(10):
        if plan is None or not work.jconstant:
            plan = _Plan(dfdy, dfdyp, n, free_y, free_yp)
        for _chord in range(3):
            dy, dyp = plan.step(res)
            nrmv = max(float(np.linalg.norm(np.concatenate([y0, yp0]))), float(np.linalg.norm(atol)))
            nrmdv = float(np.linalg.norm(np.concatenate([dy, dyp])))
            if nrmdv > 2 * nrmv:  # a trust region: the change at most twice the solution's size
                factor = 2 * nrmv / nrmdv
                dy, dyp, nrmdv = factor * dy, factor * dyp, factor * nrmdv
            y0, yp0 = y0 + dy, yp0 + dyp
            res = _residual(work, t0, y0, yp0)
            resnrm = float(np.linalg.norm(res))
            if resnrm <= resnrm0 and nrmdv <= 1e-3 * rtol * nrmv:
                return y0, yp0, resnrm
        dfdy, dfdyp = work.partials(t0, y0, yp0, res)
    raise DecicError(
        f"decic did not find consistent initial conditions in 10 iterations (the residual's norm is "
        f"{float(np.linalg.norm(res)):.3g}, from {resnrm0:.3g} at the guesses): the guesses may be too far from "
        "consistent values, or none exist near them; try other guesses, or hold fewer components fixed.", key="fun")


def _residual(work: ResidualWork, t0: float, y0: np.ndarray, yp0: np.ndarray) -> np.ndarray:
    try:
        res = work.F(t0, y0, yp0)
    except InputError:
        raise
    except Exception as exc:
        raise DecicError(f"the residual F(t0, y0, yp0) raised {type(exc).__name__}: {exc} (at y0 = {y0.tolist()}, "
                         f"yp0 = {yp0.tolist()}).", key="fun") from None
    if not np.all(np.isfinite(res)):
        raise DecicError(f"the residual F(t0, y0, yp0) is not finite ({res.tolist()}) at y0 = {y0.tolist()}, yp0 = "
                         f"{yp0.tolist()}: decic cannot go on from there; try other guesses.", key="fun")
    return res


def _options(options, n: int):
    rtol, atol, jacobian = DEFAULT_RTOL, DEFAULT_ATOL, None
    if not isinstance(options, dict):
        raise InputError(f"`options` must be a dict such as {{'RelTol': 1e-6}}; got {options!r}.", key="options")
    for name, value in options.items():
        key = canonical(name)
        if key == "rtol":
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise InputError(f"`{name}` must be a positive number; got {value!r}.", key=name)
            rtol = max(float(value), 100 * EPS)
        elif key == "atol":
            arr = np.asarray(value, dtype=float)
            if arr.size not in (1, n) or not np.all(arr > 0):
                raise InputError(f"`{name}` must be positive, one number or one per state; got {value!r}.", key=name)
            atol = arr
        elif key == "jacobian":
            jacobian = check_jacobian_option(value, n)
        elif key is None or key not in ("rtol", "atol", "jacobian"):
            continue  # MATLAB's decic reads only RelTol, AbsTol and the Jacobian from the options
    return rtol, np.broadcast_to(np.asarray(atol, dtype=float), (n,)), jacobian
