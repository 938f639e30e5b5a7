"""MATLAB's ``ode15i``: variable-order (1-5) BDFs for fully implicit equations ``F(t, y, y') = 0``.

Written from L. F. Shampine, *Solving 0 = F(t, y(t), y'(t)) in Matlab*, J. Numer. Math. 10(4),
2002, 291-310, and MATLAB's ``ode15i`` as documented (Kierzenka & Shampine), which it describes:

* **Lagrangian form on a variable mesh.** The solution is kept at the last accepted points
  ``t_n, t_{n-1}, ...`` (``mesh``), not as backward differences: nothing is rescaled when the
  step changes. The predictor of order k is the polynomial through ``y_n .. y_{n-k}``
  extrapolated to ``t_{n+1}`` (value and slope, from Fornberg's weights); the corrector is
  the BDF of order k in its *fixed leading coefficient* form
  ``y'_{n+1} = yp_pred + (alpha_k / h) (y_{n+1} - y_pred)``, ``alpha_k = 1 + 1/2 + ... + 1/k``,
  so the iteration matrix ``dF/dy + (alpha_k / h) dF/dy'`` depends only on ``h`` and ``k``. The
  first step starts from a fictitious point ``y_0 - h y'_0`` at ``t_0 - h``.
* **Simplified Newton**: at most 4 iterations, converged when the observed rate predicts a
  remaining error ``||d|| rho / (1 - rho) <= 0.33 RelTol`` (the rate kept from step to step
  until the matrix changes), abandoned when the rate exceeds 0.9; a failure refreshes stale
  partial derivatives, else cuts the step to a quarter. The matrix is factored only when
  ``|h|`` or ``k`` change.
* **Error estimate** ``err = |C| ||y_{n+1} - y_pred|| prod_j (j |h| / (t_{n+1} - t_{n+1-j}))``
  in MATLAB's weighted max norm ``max(|y_n|, AbsTol/RelTol)``, with the error constant ``C`` of
  the irregular mesh; derivatives of orders k and k-1 from the last points decide an order
  drop, order k+1's (after k+2 steps at constant step size) an order raise.
* **Step rules**: a failed step shrinks by ``min(0.9, max(0.25, 0.9 (RelTol/(2 erropt))^(1/(k+1))))``,
  the second failure by 0.25, the third also drops to order 1; after a step, ``h`` doubles when
  the estimate allows ``2h`` at ``RelTol/2``, shrinks (by 0.5 to 0.9) when it does not allow
  ``h``, and is kept otherwise; ``MaxStep`` 0.1 |tf - t0|, ``hmin = 16 eps(t)``; MATLAB's first
  step ``1.25 ||y'_0 / wt|| / sqrt(RelTol)``.
* **Output**: ``Refine`` (default 1), ``tspan`` and events on the step's interpolating
  polynomial through ``t_{n+1}`` and the k points before it (MATLAB's ``ntrp15i``), which is also
  ``deval``'s; an events function sees ``(t, y, y')`` as MATLAB's does.

Counts as MATLAB's: one evaluation of ``F`` per Newton iteration, ``numjac``'s per partial
derivative, one LU per change of ``|h|`` or ``k``, one linear solve per iteration.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from odelab.exceptions import SolverWarning
from odelab.solvers.api import solve_residual
from odelab.solvers.controller import first_step, given_step
from odelab.solvers.dense import query_times
from odelab.solvers.implicit.driver import Stepper, integrate, register_step
from odelab.solvers.implicit.residual import ResidualWork
from odelab.solvers.plausibility import PREFIX

__all__ = ["ode15i", "BDFIStep", "ImplicitDenseOutput", "fornberg_weights", "LCF"]

EPS = float(np.finfo(float).eps)
MAX_NEWTON = 4

#: alpha_k = sum_{j<=k} 1/j, the BDFs' leading coefficients (index k; 0 unused)
LCF = (0.0, 1.0, 3 / 2, 11 / 6, 25 / 12, 137 / 60)
#: CF[k][j]: the BDF of order k on a constant step, h y'_{n+1} = alpha_k y_{n+1} + sum_j CF[k][j] y_{n+1-j}
CF = {1: (0.0, -1.0), 2: (0.0, -2.0, 1 / 2), 3: (0.0, -3.0, 3 / 2, -1 / 3), 4: (0.0, -4.0, 3.0, -4 / 3, 1 / 4),
      5: (0.0, -5.0, 5.0, -10 / 3, 5 / 4, -1 / 5)}
#: the m-th backward difference of equally spaced values: sum_i (-1)^i C(m, i) y_{n-i}
BACKWARD = {m: tuple(float((-1) ** i * math.comb(m, i)) for i in range(m + 1)) for m in range(1, 8)}


def fornberg_weights(nodes, z: float, order: int) -> list[list[float]]:
    """``c[j][d]``: the weight of the value at ``nodes[j]`` in the ``d``-th derivative at ``z`` of the
    polynomial interpolating at ``nodes`` (d = 0 .. order). B. Fornberg, *Generation of finite
    difference formulas on arbitrarily spaced grids*, Math. Comp. 51 (1988), 699-706 (the
    algorithm of his *Practical Guide to Pseudospectral Methods*, 1996, which MATLAB's ode15i uses)."""
    x = [float(v) for v in nodes]
    n = len(x) - 1
    c = [[0.0] * (order + 1) for _ in range(n + 1)]
    c[0][0] = 1.0
    c1 = 1.0
    c4 = x[0] - z
    for i in range(1, n + 1):
        mn = min(i, order)
        c2 = 1.0
        c5 = c4
        c4 = x[i] - z
        for j in range(i):
            c3 = x[i] - x[j]
            c2 *= c3
            if j == i - 1:
                for d in range(mn, 0, -1):
                    c[i][d] = c1 * (d * c[i - 1][d - 1] - c5 * c[i - 1][d]) / c2
                c[i][0] = -c1 * c5 * c[i - 1][0] / c2
            for d in range(mn, 0, -1):
                c[j][d] = (c4 * c[j][d] - d * c[j][d - 1]) / c3
            c[j][0] = c4 * c[j][0] / c3
        c1 = c2
    return c


def _combine(weights, values) -> np.ndarray:
    """``sum_j weights[j] values[j]`` in index order (the same bits on every machine)."""
    acc = weights[0] * values[0]
    for j in range(1, len(weights)):
        acc = acc + weights[j] * values[j]
    return acc


def _max_weighted(v: np.ndarray, invwt: np.ndarray) -> float:
    return float(np.max(np.abs(v) * invwt)) if v.size else 0.0


def _polynomial(nodes, values, times, derivative: bool):
    """The polynomial through ``(nodes[j], values[j])`` at ``times``: values (m, n), and slopes if asked."""
    times = np.atleast_1d(np.asarray(times, dtype=float))
    out = np.empty((times.size, values[0].size))
    slopes = np.empty_like(out) if derivative else None
    for i, tq in enumerate(times.tolist()):
        c = fornberg_weights(nodes, tq, 1 if derivative else 0)
        out[i] = _combine([row[0] for row in c], values)
        if derivative:
            slopes[i] = _combine([row[1] for row in c], values)
    return out, slopes


class ImplicitDenseOutput:
    """ode15i's ``deval``: on step ``[t_i, t_{i+1}]`` the polynomial of its order ``k_i`` through
    ``t_{i+1}, t_i, ..., t_{i+1-k_i}`` (MATLAB's ``ntrp15i`` on ``sol.x``, ``sol.y``, ``idata.kvec``)."""

    def __init__(self, t: np.ndarray, y: np.ndarray, orders: np.ndarray):
        self.t, self.y, self.orders = t, y, orders

    @property
    def t_start(self) -> float:
        return float(self.t[0])

    @property
    def t_end(self) -> float:
        return float(self.t[-1])

    def __call__(self, tq, derivative: bool = False):
        times, scalar = query_times(tq, self.t_start, self.t_end)
        t = self.t
        tdir = 1.0 if t[-1] >= t[0] else -1.0
        idx = np.clip(np.searchsorted(tdir * t, tdir * times, side="right") - 1, 0, t.size - 2)
        n = self.y.shape[1]
        values = np.empty((times.size, n))
        slopes = np.empty_like(values) if derivative else None
        for m, (i, tq1) in enumerate(zip(idx.tolist(), times.tolist())):
            k = int(self.orders[i])
            first = max(i + 1 - k, 0)
            nodes = t[first:i + 2][::-1]
            v, s = _polynomial(nodes, self.y[first:i + 2][::-1], [tq1], derivative)
            values[m] = v[0]
            if derivative:
                slopes[m] = s[0]
        values[times == t[-1]] = self.y[-1]
        if derivative:
            return (values[0], slopes[0]) if scalar else (values, slopes)
        return values[0] if scalar else values


@register_step("ode15i")
class BDFIStep(Stepper):
    """ode15i's own part of the step (driven by :func:`odelab.solvers.implicit.driver.integrate`); :meth:`run`
    integrates a whole span (:func:`odelab.solvers.api.solve_residual` finds it by the method's name)."""

    fields = (((), np.int64),)  # the order of each step, for deval

    def __init__(self, work: ResidualWork, tspan, rtol, atol, yp0, max_order=5):
        super().__init__(work, tspan, rtol, atol)
        self.yp = np.array(yp0, dtype=float)
        self.maxk = max_order
        self.singular_at = None  # where an iteration matrix was found singular (the status message says so)
        self.rows = ()
        self.current = None  # the last accepted step's polynomial: (nodes, values)

    # --- partial derivatives -------------------------------------------------------------------

    def refresh_jacobian(self, t, y):
        self.dfdy, self.dfdyp = self.work.partials(t, y, self.yp)
        self.jcurrent = True
        self.klast = 0  # forms the iteration matrix again

    # --- the step ------------------------------------------------------------------------------

    def start(self, t, y, f0, hmax, htry):
        if getattr(self, "dfdy", None) is None:  # (the caller may have formed them at t0 already)
            self.dfdy, self.dfdyp = self.work.partials(t, y, self.yp, f0)
        self.jcurrent = True
        wt = np.maximum(np.abs(y), self.threshold)
        if htry == htry:
            absh = given_step(htry, t, hmax)
        else:
            rh = 1.25 * float(np.max(np.abs(self.yp) / wt)) / math.sqrt(self.rtol)
            absh = first_step(rh, self.htspan, hmax, t)
        h = self.tdir * absh
        n = y.size
        self.mesh = [0.0] * (self.maxk + 2)
        self.meshsol = [np.zeros(n) for _ in range(self.maxk + 2)]
        self.mesh[0], self.meshsol[0] = t, y.copy()
        # a fictitious point on the initial slope starts the integration (Shampine 2002)
        self.mesh[1], self.meshsol[1] = t - h, y - h * self.yp
        self.nconh = 1
        self.k, self.klast, self.abshlast = 1, 0, absh
        self.raised_order = False
        self.havrate, self.rate = False, 1.0
        self.lu = None
        return absh

    def begin_step(self, t, y, absh_before, absh, done):
        self.invwt = 1.0 / np.maximum(np.abs(y), self.threshold)

    def attempt(self, t, y, absh, done):
        work, k, invwt, rtol = self.work, self.k, self.invwt, self.rtol
        tnew = self.tf if done else t + self.tdir * absh
        h = tnew - t
        lcf = LCF[k]
        if absh != self.abshlast or k != self.klast:
            if absh != self.abshlast:
                self.nconh = 0
            matrix = self.dfdy + (lcf / h) * self.dfdyp
            self.lu = work.factor(matrix)
            if _singular(self.lu):
                self.singular_at = t
            self.havrate, self.rate = False, 1.0
        self.abshlast, self.klast = absh, k
        mesh, meshsol = self.mesh, self.meshsol
        c = fornberg_weights(mesh[: k + 1], tnew, 1)
        ynew = _combine([row[0] for row in c], meshsol)
        ypnew = _combine([row[1] for row in c], meshsol)
        ypred = ynew
        minnrm = 100 * EPS * _max_weighted(ypred, invwt)
        erconst = -1.0 / (k + 1)
        for j in range(2, k + 1):
            p = 1.0
            for i in range(k + 1):
                p *= ((t - (j - 1) * h) - mesh[i]) / (h * (i + 1))
            erconst -= CF[k][j] * p
        erconst = abs(erconst)

        converged = False
        savnrm = 0.0
        for it in range(1, MAX_NEWTON + 1):
            delta = work.solve(self.lu, -work.F(tnew, ynew, ypnew))
            newnrm = _max_weighted(delta, invwt)
            ynew = ynew + delta
            ypnew = ypnew + (lcf / h) * delta
            if not math.isfinite(newnrm):
                break
            if it == 1:
                if newnrm <= minnrm:
                    converged = True
                    break
                savnrm = newnrm
            else:
                self.rate = (newnrm / savnrm) ** (1.0 / (it - 1))
                self.havrate = True
                if self.rate > 0.9:
                    break
            if self.havrate and newnrm * self.rate / (1.0 - self.rate) <= 0.33 * rtol:
                converged = True
                break
        if not converged:
            return None

        # the scaled derivative of order k+1 from the tentative solution, and the error
        ratio = 1.0
        for i in range(k + 1):
            ratio *= (absh * (i + 1)) / (tnew - mesh[i])
        sderkp1 = _max_weighted(ynew - ypred, invwt) * abs(ratio)
        erropt = sderkp1 / (k + 1)  # the error were the step constant
        err = sderkp1 * erconst
        kopt, sderk = k, None
        if k > 1:
            sderk = self._scaled_derivative(k, tnew, ynew, absh)
            if k == 2:
                if sderk <= 0.5 * sderkp1:
                    kopt, erropt = k - 1, sderk / k
            else:
                sderkm1 = self._scaled_derivative(k - 1, tnew, ynew, absh)
                if max(sderkm1, sderk) <= sderkp1:
                    kopt, erropt = k - 1, sderk / k
        self.tnew, self.h, self.ynew, self.ypnew = tnew, h, ynew, ypnew
        self.sderk, self.sderkp1, self.kopt, self.erropt = sderk, sderkp1, kopt, erropt
        return ynew, err

    def _scaled_derivative(self, m: int, tnew: float, ynew: np.ndarray, absh: float) -> float:
        """``|h|^m`` times the m-th derivative of the polynomial through ``ynew`` and the last m points."""
        values = [ynew, *self.meshsol[:m]]
        if self.nconh >= m:  # a constant step: the m-th backward difference
            return _max_weighted(_combine(BACKWARD[m], values), self.invwt)
        c = fornberg_weights([tnew, *self.mesh[:m]], tnew, m)
        return _max_weighted(_combine([row[m] for row in c], values), self.invwt) * absh ** m

    def after_newton_failure(self, absh, hmin):
        return 0.25 * absh

    def after_error_failure(self, absh, hmin, err, nfails, nofailed):
        kopt = self.kopt
        if nfails == 1:
            erropt = self.erropt
            factor = 0.9 if erropt == 0 else min(0.9, max(0.25, 0.9 * (0.5 * self.rtol / erropt) ** (1 / (kopt + 1))))
            absh = absh * factor
        elif nfails == 2:
            absh = absh * 0.25
        else:
            kopt = 1
            absh = absh * 0.25
        self.k = kopt
        return max(absh, hmin)

    def accept(self, t, y, ynew):
        k, tnew = self.k, self.tnew
        nodes = [tnew, *self.mesh[:k]]
        values = [ynew, *self.meshsol[:k]]
        self.current = (nodes, values)
        self.rows = (k,)

        def interp(times, _nodes=nodes, _values=values):
            return _polynomial(_nodes, _values, times, False)[0]

        return tnew, ynew, interp

    def slope_at(self, tq: float) -> np.ndarray:
        """y' at ``tq`` on the last accepted step's polynomial (its end: the corrector's y')."""
        if self.current is None:  # before the first step: t0's consistent slope
            return self.yp
        if tq == self.tnew:
            return self.ypnew
        nodes, values = self.current
        return _polynomial(nodes, values, [tq], True)[1][0]

    def cut(self, t):
        """A terminal event at ``t``: the step ends there (MATLAB: tnew = te, ynew = ye)."""

    def next_step(self, absh, err, nofailed):
        k, kopt, erropt = self.k, self.kopt, self.erropt
        tnew, ynew = self.tnew, self.ynew
        self.yp = self.ypnew
        self.mesh = [tnew, *self.mesh[:-1]]
        self.meshsol = [ynew, *self.meshsol[:-1]]
        self.jcurrent = self.work.jconstant
        self.nconh = min(self.nconh + 1, self.maxk + 2)
        if self.nconh >= k + 2 and not kopt < k and k != self.maxk and not self.raised_order:
            sderkp2 = _max_weighted(_combine(BACKWARD[k + 2], self.meshsol[: k + 3]), self.invwt)
            if k > 1 and self.sderk <= min(self.sderkp1, sderkp2):
                kopt, erropt = k - 1, self.sderk / k
            elif (k == 1 and sderkp2 < 0.5 * self.sderkp1) or (k > 1 and sderkp2 < self.sderkp1):
                kopt, erropt = k + 1, sderkp2 / (k + 2)
        temp = (erropt / (0.5 * self.rtol)) ** (1.0 / (kopt + 1))
        if temp <= 0.5:
            absh = absh * 2
        elif temp > 1:
            absh = absh * max(0.5, min(0.9, 1 / temp))
        self.raised_order = kopt > k
        self.k = kopt
        return absh

    def dense(self, y_final, store):
        if not store.count:
            return None
        return ImplicitDenseOutput(store.t.copy(), store.y.copy(), store.fields[0].copy())

    @classmethod
    def run(cls, work: ResidualWork, tspan, y0, yp0, f0, rtol, atol, hmax, htry, refine, max_steps, max_order=5,
            events=None, args=(), dfdy=None, dfdyp=None):
        """Integrate ``F(t, y, y') = 0`` with ode15i: ``(engine tuple, stepper, found)``.

        ``events(t, y, yp, *args)``: MATLAB's events function, given ``y'`` on the step's polynomial
        (:meth:`slope_at`). ``dfdy, dfdyp``: the partials at ``t0`` if already formed."""
        stepper = cls(work, tspan, rtol, atol, yp0, max_order=max_order)
        if dfdy is not None:
            stepper.dfdy, stepper.dfdyp = dfdy, dfdyp
        located = None
        if events is not None:
            from odelab.solvers.events import as_event_function

            slope_at = stepper.slope_at

            def with_slope(t, y, *more, _events=events):
                return _events(t, y, slope_at(t), *more)

            located = as_event_function(with_slope, args, float(tspan[0]), y0)
        result = integrate(stepper, tspan, y0, f0, hmax, htry, refine, max_steps, located)
        return result, stepper, work.found


def _singular(lu) -> bool:
    """Whether an LU factorisation from :meth:`Work.factor` has a zero (or non-finite) pivot."""
    kind, fac = lu
    if kind == "ordered":
        rows = fac[0]
        return any(not (rows[j][j] != 0 and math.isfinite(rows[j][j])) for j in range(len(rows)))
    if kind == "dense":
        diag = np.diag(fac[0])
        return bool(np.any(diag == 0) or not np.all(np.isfinite(diag)))
    return False


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
    if sol.status == "failed":
        warnings.warn(sol.message, SolverWarning, stacklevel=2)
    for note in sol.warnings:
        if note.startswith(PREFIX):  # a result that cannot be right, as ode15s's are checked
            warnings.warn(note, SolverWarning, stacklevel=2)
    return sol
