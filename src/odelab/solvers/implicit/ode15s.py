"""MATLAB's ``ode15s``: variable-order (1-5) numerical differentiation formulas.

Written from Shampine & Reichelt, *The MATLAB ODE Suite*, SIAM J. Sci. Comput. 18(1), 1997,
Sections 2.1-2.3 (and Shampine, Reichelt & Kierzenka, SIAM Review 41(3), 1999, for mass
matrices and index-1 DAEs):

* the NDFs of orders 1-5: BDF plus ``kappa * gamma_k * (y_{n+1} - y^(0)_{n+1})`` with MATLAB's
  ``kappa = -0.1850, -1/9, -0.0823, -0.0415, 0`` (``BDF = true`` sets kappa = 0);
* a quasi-constant step size held in a backward-difference array, rescaled by the paper's
  ``R U`` matrices when the step changes;
* a simplified Newton iteration with the iteration matrix ``M - h/((1-kappa) gamma_k) J``,
  at most 4 iterations, convergence judged from the observed rate; the Jacobian is formed
  once and refreshed only when the iteration fails to converge, and the matrix is
  re-factored only when ``h`` or the order change;
* the local error ``(kappa gamma_k + 1/(k+1)) * ||y_{n+1} - y^(0)_{n+1}||`` in MATLAB's
  weighted max norm, orders k-1 and k+1 estimated from the same differences, a change of
  step and order considered after k+2 steps at constant step and order, and the step
  increased only when that pays (factors 1.2/1.3/1.4 on the estimates, as MATLAB does).
"""

from __future__ import annotations

import math

import numpy as np

from odelab.solution import Solution
from odelab.solvers.api import solve
from odelab.solvers.controller import first_step, given_step, grow, shrink, shrink_after_newton
from odelab.solvers.implicit.common import EPS, SQRT_EPS, Newton, Work, jacobian_times, newton
from odelab.solvers.implicit.driver import Stepper, integrate, register_step
from odelab.solvers.ordered import backwards, matmul

__all__ = ["integrate_ode15s", "NDFStep", "KAPPA", "ode15s"]

# MATLAB's ode15s: alpha = [-37/200, -1/9, -0.0823, -0.0415, 0] for orders 1..5 (index 0 unused).
KAPPA = np.array([0.0, -37 / 200, -1 / 9, -0.0823, -0.0415, 0.0])
GAMMA = np.concatenate([[0.0], np.cumsum(1.0 / np.arange(1, 6))])  # 1, 3/2, 11/6, 25/12, 137/60
# GAMMA[1..k] read backwards, per order k: psi's sum_i GAMMA[i] D[i] in index order without BLAS
_GAMMA_B = {k: backwards(GAMMA[1 : k + 1]) for k in range(1, 6)}
# ndarray.max() and .sum() without their Python layers (the same reductions: bit for bit)
_max, _sum = np.maximum.reduce, np.add.reduce


def _rescale(order: int, factor: float) -> np.ndarray:
    """The paper's R(factor) as an (order+1) x (order+1) matrix (Section 2.3)."""
    i, j = _IJ[order]
    m = np.zeros((order + 1, order + 1))
    m[1:, 1:] = (i - 1 - factor * j) / i
    m[0] = 1.0
    return np.cumprod(m, axis=0)


# per order: the index columns and rows of R, and U = R(1) (constant: formed once)
_IJ = {order: (np.arange(1, order + 1)[:, None], np.arange(1, order + 1)) for order in range(1, 6)}
_U = {order: _rescale(order, 1.0) for order in range(1, 6)}


def change_differences(D: np.ndarray, order: int, factor: float) -> None:
    """Rescale the backward differences ``D[0..order]`` to a step ``factor`` times the old one."""
    RU = matmul(_rescale(order, factor), _U[order])
    D[: order + 1] = matmul(RU.T, D[: order + 1])


@register_step("ode15s")
class NDFStep(Stepper):
    """ode15s's own part of the step: the backward differences ``D`` of the solution (scaled for
    the step ``absh_D``), the order ``k``, the iteration matrix and its LU (keyed on ``|h|`` and
    ``k``), and ``nconhk``, the steps taken at constant step size and order."""

    compile_seconds = 12.0

    @classmethod
    def compiled_arguments(cls, extra: dict) -> tuple:
        """The compiled loop's MaxOrder, GAMMA, alpha and error constants (as __init__ forms them, bit for bit)."""
        kappa = np.zeros(6) if extra["bdf"] else KAPPA
        alpha = (1.0 - kappa) * GAMMA
        erconst = kappa * GAMMA + 1.0 / np.arange(1, 7)
        return int(extra["max_order"]), np.array(GAMMA), alpha, erconst

    @classmethod
    def for_run(cls, work, tspan, rtol, atol, extra, nonnegative=None):
        """MaxOrder and BDF from the run's options; a DAE when the mass matrix is singular."""
        mass, n = work.mass, work.n
        dae = mass is not None and np.linalg.matrix_rank(mass.toarray() if hasattr(mass, "toarray") else mass) < n
        return cls(work, tspan, rtol, atol, max_order=extra["max_order"], bdf=extra["bdf"], dae=dae,
                   nonnegative=nonnegative)

    def __init__(self, work: Work, tspan, rtol, atol, max_order=5, bdf=False, dae=False, nonnegative=None):
        super().__init__(work, tspan, rtol, atol, nonnegative)
        kappa = np.zeros(6) if bdf else KAPPA
        self.alpha = (1.0 - kappa) * GAMMA
        self.erconst = kappa * GAMMA + 1.0 / np.arange(1, 7)
        self.max_order = max_order
        self.dae = dae
        self.memory = Newton()

    def start(self, t, y, f0, hmax, htry):
        work, tdir, rtol = self.work, self.tdir, self.rtol
        self.J = work.jacobian(t, y, f0, self.atol)  # numjac's thresh is AbsTol, as in MATLAB
        self.jcurrent = True
        # The initial slope: y' = M^-1 f (least squares for a singular M: algebraic rows get 0).
        if work.mass is None:
            yp0 = f0
        else:
            Md = work.M.toarray() if hasattr(work.M, "toarray") else np.asarray(work.M)
            yp0 = np.linalg.lstsq(Md, f0, rcond=None)[0]
        wt = np.maximum(np.abs(y), self.threshold)
        if htry == htry:
            absh = given_step(htry, t, hmax)
        else:
            rh = 1.25 * float(np.max(np.abs(yp0) / wt)) / math.sqrt(rtol)
            absh = first_step(rh, self.htspan, hmax, t)
            if not self.dae:
                # The error of BDF1 is h^2/2 |y''|: estimate y'' = f_t + J y' and size h from it.
                h = tdir * absh
                tdel = (t + tdir * min(SQRT_EPS * max(abs(t), abs(t + h)), absh)) - t
                f1 = work.f(t + tdel, y)
                ypp = (f1 - f0) / tdel + jacobian_times(self.J, yp0)
                if work.mass is not None:
                    ypp = np.linalg.lstsq(Md, ypp, rcond=None)[0]
                rh = 1.25 * math.sqrt(0.5 * float(np.max(np.abs(ypp) / wt)) / rtol)
                absh = first_step(rh, self.htspan, hmax, t)
        self.D = np.zeros((self.max_order + 3, y.size))
        self.D[0] = y
        self.D[1] = tdir * absh * yp0
        self.k = 1
        self.absh_D = absh  # the step the differences are scaled for
        self.lu, self.lu_key = None, None
        self.nconhk = 0
        return absh

    def _rescale(self, absh):
        change_differences(self.D, self.k, absh / self.absh_D)
        self.absh_D = absh
        self.nconhk = 0

    def begin_step(self, t, y, absh_before, absh, done):
        if absh != self.absh_D:
            self._rescale(absh)

    def jacobian_changed(self):
        self.lu = None

    def attempt(self, t, y, absh, done):
        work, D, k = self.work, self.D, self.k
        h = self.tf - t if done else self.tdir * absh
        tnew = self.tf if done else t + h
        # MATLAB re-forms the iteration matrix only when |h| or the order changed (or after a
        # failure), with h = tdir*|h|, not with the purified tnew - t: keyed on tnew - t,
        # ulp-level changes of t + h - t re-factored (and reset the Newton rate) on steps where
        # nothing changed.
        if self.lu is None or self.lu_key != (absh, k):
            self.c = h / self.alpha[k]
            self.lu = work.factor(work.M - self.c * self.J)
            self.lu_key = (absh, k)
            self.memory.havrate = False
        c = self.c
        ypred = _sum(D[: k + 1], axis=0)
        psi = _GAMMA_B[k].dot(D[None, 1 : k + 1])[0] / self.alpha[k]
        absy = np.abs(y)
        wt = np.maximum(absy, self.threshold)
        f = work.f
        if work.mass is None:  # (mass_times is the identity)
            def residual(d):
                return c * f(tnew, ypred + d) - (psi + d)
        else:
            mass_times = work.mass_times

            def residual(d):
                return c * f(tnew, ypred + d) - mass_times(psi + d)

        minnrm = 100 * EPS * float(_max(absy / wt))
        d, converged = newton(work, self.lu, residual, np.zeros(y.size), 1.0, wt, self.rtol, self.memory, minnrm=minnrm)
        if not converged:
            return None
        ynew = ypred + d
        self.scale = scale = np.maximum(np.maximum(absy, np.abs(ynew)), self.threshold)
        self.h, self.tnew, self.ypred, self.ynew, self.d = h, tnew, ypred, ynew, d
        return ynew, self.erconst[k] * float(_max(np.abs(d) / scale))

    def after_newton_failure(self, absh, hmin):
        absh_new = shrink_after_newton(absh, hmin)
        self._rescale(absh_new)
        return absh_new

    def after_error_failure(self, absh, hmin, err, nfails, nofailed):
        rtol, k = self.rtol, self.k
        if nfails == 1:
            hopt = shrink(absh, 0.0, err, rtol, 1 / (k + 1), 0.1, 0.833, True)  # 1/1.2
            if k > 1:
                errkm1 = self.erconst[k - 1] * float((np.abs(self.D[k] + self.d) / self.scale).max())
                hkm1 = shrink(absh, 0.0, errkm1, rtol, 1 / k, 0.1, 0.769, True)  # 1/1.3
                if hkm1 > hopt:
                    hopt = min(absh, hkm1)
                    self.k -= 1
            absh_new = max(hmin, hopt)
        else:
            absh_new = shrink(absh, hmin, err, rtol, 0.0, 0.0, 0.0, False)
        self._rescale(absh_new)
        return absh_new

    def accept(self, t, y, ynew):
        D, k, d = self.D, self.k, self.d
        if ynew is not self.ynew:  # NonNegative projected y_n+1: the history is the projected solution
            d = ynew - self.ypred
        D[k + 2] = d - D[k + 1]
        D[k + 1] = d
        for i in range(k, -1, -1):
            D[i] += D[i + 1]
        if self.nn is not None:
            self.nn.clip(D[0])  # in place (the differences summed again may leave -1 ulp)
        h, tnew = self.h, self.tnew

        def interp(times, _D=D[: k + 1].copy()):
            x = (np.asarray(times)[:, None] - (tnew - h * np.arange(k))) / (h * np.arange(1, k + 1))
            return _D[0] + matmul(np.cumprod(x, axis=1), _D[1:])

        self.nconhk = min(self.nconhk + 1, self.max_order + 2)
        return tnew, D[0].copy(), interp

    def next_step(self, absh, err, nofailed):
        k, D, rtol, erconst = self.k, self.D, self.rtol, self.erconst
        if not (nofailed and self.nconhk >= k + 2):
            return absh
        hopt = grow(absh, err, rtol, 1 / (k + 1), 1.2, 10.0)
        kopt = k
        if k > 1:
            errkm1 = erconst[k - 1] * float((np.abs(D[k]) / self.scale).max())
            hkm1 = absh / max(0.1, 1.3 * (errkm1 / rtol) ** (1 / k))
            if hkm1 > hopt:
                hopt, kopt = hkm1, k - 1
        if k < self.max_order:
            errkp1 = erconst[k + 1] * float((np.abs(D[k + 2]) / self.scale).max())
            hkp1 = absh / max(0.1, 1.4 * (errkp1 / rtol) ** (1 / (k + 2)))
            if hkp1 > hopt:
                hopt, kopt = hkp1, k + 1
        if hopt > absh:
            absh = hopt
            if kopt != k:
                self.k = kopt
                self.nconhk = 0
        return absh


def integrate_ode15s(work: Work, tspan, y0, f0, rtol, atol, hmax, htry, refine, max_steps, max_order=5, bdf=False,
                     dae=False, events=None, nonnegative=None):
    """Integrate with ode15s; returns the engine's tuple ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events), located on the step's backward-difference
    interpolant; the events found are left in ``work.found``. ``nonnegative``: the indices
    kept >= 0 (MATLAB's NonNegative), or None."""
    stepper = NDFStep(work, tspan, rtol, atol, max_order=max_order, bdf=bdf, dae=dae, nonnegative=nonnegative)
    return integrate(stepper, tspan, y0, f0, hmax, htry, refine, max_steps, events)


def ode15s(fun, tspan, y0, **options) -> Solution:
    """Solve a stiff ODE or an index-1 DAE ``M y' = f(t, y)`` with MATLAB's ``ode15s``.

    Variable-order (1-5) numerical differentiation formulas (Shampine & Reichelt 1997).
    Options: ``rtol``/``RelTol`` (1e-3), ``atol``/``AbsTol`` (1e-6), ``max_step``
    (0.1*|tf - t0|), ``initial_step``, ``refine`` (1), ``max_steps``, ``max_order``/``MaxOrder``
    (5), ``bdf``/``BDF`` (False: NDFs; True: the backward differentiation formulas),
    ``jacobian`` (a constant matrix or ``J(t, y)``; default finite differences),
    ``jpattern`` (sparsity of df/dy: fewer evaluations and sparse LU), ``vectorized``
    (``fun(t, Y)`` accepts a matrix of states, one per column), ``mass`` (constant M,
    singular for a DAE with consistent initial values).

    Examples
    --------
    >>> import odelab
    >>> vdp = lambda t, y: [y[1], 1000 * (1 - y[0] ** 2) * y[1] - y[0]]
    >>> sol = odelab.ode15s(vdp, [0, 3000], [2, 0])
    >>> sol.success, sol.stats.nsteps < 1000
    (True, True)
    """
    return solve(fun, tspan, y0, method="ode15s", **options)
