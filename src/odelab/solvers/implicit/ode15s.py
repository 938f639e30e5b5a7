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
import warnings

import numpy as np

from odelab.solvers.status import Status
from odelab.solvers.controller import clamp_step, first_step, given_step, grow, shrink, shrink_after_newton
from odelab.solvers.implicit.common import SQRT_EPS, NonNegative, Output, Work

__all__ = ["integrate_ode15s", "KAPPA"]

# MATLAB's ode15s: alpha = [-37/200, -1/9, -0.0823, -0.0415, 0] for orders 1..5 (index 0 unused).
KAPPA = np.array([0.0, -37 / 200, -1 / 9, -0.0823, -0.0415, 0.0])
GAMMA = np.concatenate([[0.0], np.cumsum(1.0 / np.arange(1, 6))])  # 1, 3/2, 11/6, 25/12, 137/60
MAX_NEWTON = 4


def _rescale(order: int, factor: float) -> np.ndarray:
    """The paper's R(factor) as an (order+1) x (order+1) matrix (Section 2.3)."""
    i = np.arange(1, order + 1)[:, None]
    j = np.arange(1, order + 1)
    m = np.zeros((order + 1, order + 1))
    m[1:, 1:] = (i - 1 - factor * j) / i
    m[0] = 1.0
    return np.cumprod(m, axis=0)


def change_differences(D: np.ndarray, order: int, factor: float) -> None:
    """Rescale the backward differences ``D[0..order]`` to a step ``factor`` times the old one."""
    RU = _rescale(order, factor) @ _rescale(order, 1.0)
    D[: order + 1] = RU.T @ D[: order + 1]


def integrate_ode15s(work: Work, tspan, y0, f0, rtol, atol, hmax, htry, refine, max_steps, max_order=5, bdf=False,
                     dae=False, events=None, nonnegative=None):
    """Integrate with ode15s; returns the engine's tuple ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events), located on the step's backward-difference
    interpolant; the events found are left in ``work.found``. ``nonnegative``: a
    :class:`~odelab.solvers.implicit.common.NonNegative` (MATLAB's NonNegative), or None."""
    kappa = np.zeros(6) if bdf else KAPPA
    alpha = (1.0 - kappa) * GAMMA
    erconst = kappa * GAMMA + 1.0 / np.arange(1, 7)
    n = y0.size
    t0, tf = float(tspan[0]), float(tspan[-1])
    tdir = 1.0 if tf > t0 else -1.0
    threshold = atol / rtol
    nn = None if nonnegative is None else NonNegative(nonnegative, threshold)
    out = Output(tspan, y0, refine, events, nn)
    nsteps = nfailed = 0
    status, exception = Status.SUCCESS, None
    t, y = t0, y0.copy()
    absh = 0.0
    M = work.M
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # singular iteration matrices show as failed Newton iterations
        try:
            J = work.jacobian(t, y, f0, atol)  # numjac's thresh is AbsTol, as in MATLAB
            Jcurrent = True
            # The initial slope: y' = M^-1 f (least squares for a singular M: algebraic rows get 0).
            if work.mass is None:
                yp0 = f0
            else:
                Md = M.toarray() if hasattr(M, "toarray") else np.asarray(M)
                yp0 = np.linalg.lstsq(Md, f0, rcond=None)[0]
            htspan = abs(float(tspan[1]) - t0)
            wt = np.maximum(np.abs(y), threshold)
            if htry == htry:
                absh = given_step(htry, t0, hmax)
            else:
                rh = 1.25 * float(np.max(np.abs(yp0) / wt)) / math.sqrt(rtol)
                absh = first_step(rh, htspan, hmax, t0)
                if not dae:
                    # The error of BDF1 is h^2/2 |y''|: estimate y'' = f_t + J y' and size h from it.
                    h = tdir * absh
                    tdel = (t + tdir * min(SQRT_EPS * max(abs(t), abs(t + h)), absh)) - t
                    f1 = work.f(t + tdel, y)
                    ypp = (f1 - f0) / tdel + J @ yp0
                    if work.mass is not None:
                        ypp = np.linalg.lstsq(Md, ypp, rcond=None)[0]
                    rh = 1.25 * math.sqrt(0.5 * float(np.max(np.abs(ypp) / wt)) / rtol)
                    absh = first_step(rh, htspan, hmax, t0)

            D = np.zeros((max_order + 3, n))
            D[0] = y
            D[1] = tdir * absh * yp0
            k = 1
            absh_D = absh  # the step the differences are scaled for
            lu = None
            lu_key = None
            rate, havrate = 0.0, False
            nconhk = 0
            h = tdir * absh
            while True:
                hmin, absh, done = clamp_step(t, tf, absh, hmax)
                if absh != absh_D:
                    change_differences(D, k, absh / absh_D)
                    absh_D = absh
                    nconhk = 0
                nofailed = True
                nfails = 0
                while True:  # attempts at this step
                    h = tf - t if done else tdir * absh
                    tnew = tf if done else t + h
                    # MATLAB re-forms the iteration matrix only when |h| or the order changed
                    # (or after a failure), with h = tdir*|h|, not with the purified tnew - t:
                    # keyed on tnew - t, ulp-level changes of t + h - t re-factored (and reset
                    # the Newton rate) on steps where nothing changed.
                    if lu is None or lu_key != (absh, k):
                        c = h / alpha[k]
                        lu = work.factor(M - c * J)
                        lu_key = (absh, k)
                        havrate = False
                    ypred = D[: k + 1].sum(axis=0)
                    psi = (GAMMA[1 : k + 1] @ D[1 : k + 1]) / alpha[k]
                    wt = np.maximum(np.abs(y), threshold)
                    minnrm = 100 * np.finfo(float).eps * float(np.max(np.abs(y) / wt))
                    d = np.zeros(n)
                    ynew = ypred
                    converged = False
                    oldnrm = 0.0
                    for it in range(1, MAX_NEWTON + 1):
                        rhs = c * work.f(tnew, ynew) - work.mass_times(psi + d)
                        dy = work.solve(lu, rhs)
                        newnrm = float(np.max(np.abs(dy) / wt))
                        d = d + dy
                        ynew = ypred + d
                        if not math.isfinite(newnrm):
                            break
                        if newnrm <= minnrm:
                            converged = True
                            break
                        if it == 1:
                            if havrate:
                                errit = newnrm * rate / (1 - rate)
                                if errit <= 0.05 * rtol:
                                    converged = True
                                    break
                            else:
                                rate = 0.0
                        elif newnrm > 0.9 * oldnrm:
                            break
                        else:
                            rate = max(0.9 * rate, newnrm / oldnrm)
                            havrate = True
                            errit = newnrm * rate / (1 - rate)
                            if errit <= 0.5 * rtol:
                                converged = True
                                break
                            if it == MAX_NEWTON or 0.5 * rtol < errit * rate ** (MAX_NEWTON - it):
                                break
                        oldnrm = newnrm
                    if not converged:
                        nfailed += 1
                        if not Jcurrent:
                            J = work.jacobian(t, y, None, atol)
                            Jcurrent = True
                            lu = None
                            continue
                        if absh <= hmin:
                            status = Status.STEP_UNDERFLOW
                            break
                        absh_old = absh
                        absh = shrink_after_newton(absh, hmin)
                        change_differences(D, k, absh / absh_old)
                        absh_D = absh
                        done = False
                        nofailed = False
                        nconhk = 0
                        continue
                    scale = np.maximum(np.maximum(np.abs(y), np.abs(ynew)), threshold)
                    err = erconst[k] * float(np.max(np.abs(d) / scale))
                    if nn is not None:
                        err = nn.error(err, ynew, rtol)
                    if err > rtol:
                        nfailed += 1
                        nfails += 1
                        if absh <= hmin:
                            status = Status.STEP_UNDERFLOW
                            break
                        absh_old = absh
                        if nfails == 1:
                            hopt = shrink(absh, 0.0, err, rtol, 1 / (k + 1), 0.1, 0.833, True)  # 1/1.2
                            if k > 1:
                                errkm1 = erconst[k - 1] * float(np.max(np.abs(D[k] + d) / scale))
                                hkm1 = shrink(absh, 0.0, errkm1, rtol, 1 / k, 0.1, 0.769, True)  # 1/1.3
                                if hkm1 > hopt:
                                    hopt = min(absh, hkm1)
                                    k -= 1
                            absh = max(hmin, hopt)
                        else:
                            absh = shrink(absh, hmin, err, rtol, 0.0, 0.0, 0.0, False)
                        change_differences(D, k, absh / absh_old)
                        absh_D = absh
                        done = False
                        nofailed = False
                        nconhk = 0
                        continue
                    if err != err:
                        status = Status.NONFINITE
                    break
                if status != Status.SUCCESS:
                    break

                # Accept: update the differences to the new point.
                nsteps += 1
                if nn is not None:  # the projected y_n+1 (negative listed components set to 0) is the history's
                    clipped = nn.clip(ynew)
                    if clipped is not ynew:
                        ynew, d = clipped, clipped - ypred
                D[k + 2] = d - D[k + 1]
                D[k + 1] = d
                for i in range(k, -1, -1):
                    D[i] += D[i + 1]
                if nn is not None:
                    D[0] = nn.clip(D[0])  # (the differences summed again may leave -1 ulp)
                Jcurrent = False
                kk, hh, tt = k, h, tnew

                def interp(times, _D=D[: kk + 1].copy(), _k=kk, _h=hh, _t=tt):
                    x = (np.asarray(times)[:, None] - (_t - _h * np.arange(_k))) / (_h * np.arange(1, _k + 1))
                    return _D[0] + np.cumprod(x, axis=1) @ _D[1:]

                if out.step(t, tnew, D[0], interp):
                    t, y = out.t[-1], out.y[-1]
                    status = Status.TERMINAL_EVENT
                    break
                t, y = tnew, D[0].copy()
                nconhk = min(nconhk + 1, max_order + 2)
                if done:
                    break
                if max_steps and nsteps >= max_steps:
                    status = Status.MAX_STEPS
                    break
                if nofailed and nconhk >= k + 2:
                    hopt = grow(absh, err, rtol, 1 / (k + 1), 1.2, 10.0)
                    kopt = k
                    if k > 1:
                        errkm1 = erconst[k - 1] * float(np.max(np.abs(D[k]) / scale))
                        hkm1 = absh / max(0.1, 1.3 * (errkm1 / rtol) ** (1 / k))
                        if hkm1 > hopt:
                            hopt, kopt = hkm1, k - 1
                    if k < max_order:
                        errkp1 = erconst[k + 1] * float(np.max(np.abs(D[k + 2]) / scale))
                        hkp1 = absh / max(0.1, 1.4 * (errkp1 / rtol) ** (1 / (k + 2)))
                        if hkp1 > hopt:
                            hopt, kopt = hkp1, k + 1
                    if hopt > absh:
                        absh = hopt
                        if kopt != k:
                            k = kopt
                            nconhk = 0
        except Exception as exc:  # the user's right-hand side (or Jacobian) failed
            status, exception = Status.FUN_RAISED, exc
    t_out, y_out = out.arrays()
    work.found = out.found()
    return t_out, y_out, nsteps, nfailed, status, t, absh, exception
