"""MATLAB's ``ode23t``: the trapezoidal rule with its "free" interpolant, for moderately stiff
problems and index-1 DAEs.

Written from Shampine, Reichelt & Kierzenka, *Solving index-1 DAEs in MATLAB and Simulink*,
SIAM Review 41(3), 1999 (the trapezoidal rule and its interpolant), with the step-size,
Jacobian and Newton machinery of Shampine & Reichelt, *The MATLAB ODE Suite*, SIAM J. Sci.
Comput. 18(1), 1997, Section 2 (shared with :mod:`ode15s`).

With ``z = h y'`` the trapezoidal rule is ``y_{n+1} = y_n + (z_n + z_{n+1}) / 2`` and the
unknown is ``z_{n+1}``, the solution of ``M z_{n+1} = h f(t_{n+1}, y_{n+1})``. Written so, an
algebraic equation (a zero row of ``M``) is imposed at every step, which makes the rule usable
for index-1 DAEs with a singular mass matrix (the slope of the algebraic states starts
consistent, see :func:`~odelab.solvers.implicit.common.consistent_slope`).

* The rule fixes an interpolant for free: the quadratic ``y_n + s z_n + s^2 (z_{n+1} - z_n)/2``
  (``s = (t - t_n)/h``) matches ``y_n``, ``y_{n+1}`` and both slopes. odelab uses it on the
  first step and afterwards the quadratic through ``y_{n-1}, y_n, y_{n+1}``, equally free and of
  the same order, because the slopes of stiff components are noisy (next item; see
  :func:`interpolant`). It serves ``Refine`` and ``tspan`` output.
* The local error, ``h^3 y''' / 12``, is estimated by Milne's device from a prediction exact for
  quadratics, ``ypred - y(t_{n+1}) = -P y''' / 6``: ``est = h^3 / (h^3 + 2P) (ynew - ypred)``.
  The prediction extrapolates the last three solution *values* (``P = h (h + h_1)(h + h_1 +
  h_2)``); the first two steps use ``y'`` (and, for the first, ``y'' = f_t + J y'``). Values,
  not slopes: the trapezoidal rule does not damp stiff components, whose slopes keep an
  alternating error of size ``h lambda e`` for an error ``e`` in ``y``; a slope-based predictor
  carries that noise into the estimate and into Newton's starting guess (Robertson then stalls
  at ``h = 60``, or Newton fails every few steps).
* A simplified Newton iteration with ``M - (h/2) J``, started at ``ypred``; the Jacobian is
  formed once and refreshed only when the iteration fails to converge, the matrix re-factored
  only when ``h`` changes; MATLAB's weighted max norm and ode15s's step-size rules for an error
  of order 3 (safety 1.2, at most 10x up, at least 0.1x down, 0.3x after a failed iteration, the
  step increased only when that pays).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from odelab.solvers import engine
from odelab.solvers.implicit.common import (SQRT_EPS, Newton, Output, QuadraticSteps, Work, clamp_step,
                                           consistent_slope, newton, quadratic_through)

__all__ = ["integrate_ode23t", "tr_attempt", "predict", "interpolant"]

POWER = 1.0 / 3.0


def predict(history, yp: np.ndarray, ypp: np.ndarray, h: float) -> tuple[np.ndarray, float]:
    """Extrapolate the solution to ``t_n + h`` from the last accepted points.

    ``history`` holds up to three ``(t, y)``, the newest last. Three points: the quadratic through
    them; two: the quadratic through both with the slope ``yp`` at the newest; one: Taylor's
    ``y + h y' + h^2 y''/2``. Returns ``(ypred, P)`` with ``ypred - y(t_n + h) = -P y''' / 6`` to
    leading order (``P`` is the product of the distances from ``t_n + h`` to the nodes).
    """
    tn, yn = history[-1]
    tnew = tn + h
    if len(history) == 1:
        return yn + h * (yp + 0.5 * h * ypp), abs(h) ** 3
    if len(history) == 2:
        t1, y1 = history[-2]
        dt = t1 - tn
        a = (y1 - yn - dt * yp) / (dt * dt)
        return yn + h * (yp + h * a), h * h * abs(tnew - t1)
    (t2, y2), (t1, y1) = history[-3], history[-2]
    l2 = (tnew - t1) * (tnew - tn) / ((t2 - t1) * (t2 - tn))
    l1 = (tnew - t2) * (tnew - tn) / ((t1 - t2) * (t1 - tn))
    l0 = (tnew - t2) * (tnew - t1) / ((tn - t2) * (tn - t1))
    return l2 * y2 + l1 * y1 + l0 * yn, abs((tnew - tn) * (tnew - t1) * (tnew - t2))


def interpolant(history, tnew: float, ynew: np.ndarray, z: np.ndarray, znew: np.ndarray):
    """The step's interpolant as ``(a1, a2)`` of ``y_n + s a1 + s^2 a2``, ``s = (t - t_n)/h``.

    On the first step the trapezoidal rule's free quadratic ``y_n + s z_n + s^2 (z_{n+1} - z_n)/2``;
    after it, the quadratic through the values ``y_{n-1}, y_n, y_{n+1}`` (as free, and as
    accurate, O(h^3)). The slopes' undamped error on stiff components (see the module's notes)
    would otherwise reach the output: Robertson's y2 at t = 4e8, between steps of 1e8, came out
    1e10 tolerances off with the slopes, within 1 with the values.
    """
    tn, yn = history[-1]
    if len(history) == 1:
        return z, 0.5 * (znew - z)
    t1, y1 = history[-2]
    return quadratic_through((t1 - tn) / (tnew - tn), yn, y1, ynew)


def tr_attempt(work: Work, lu, t: float, y: np.ndarray, yp: np.ndarray, ypred: np.ndarray, P: float, h: float,
               wt: np.ndarray, rtol: float, memory: Newton):
    """One trapezoidal step ``t -> t + h`` from ``y, y'`` and the prediction ``(ypred, P)`` of :func:`predict`.

    ``lu`` factors ``M - (h/2) J``. Returns ``(ynew, znew, est, converged)`` where ``est`` is the
    local-error estimate (a vector) and ``znew = h y'(t + h)``.
    """
    tnew = t + h
    z = h * yp
    zpred = 2.0 * (ypred - y) - z  # the slope that puts the trapezoidal rule's result at ypred

    def residual(zn):
        return h * work.f(tnew, y + 0.5 * (z + zn)) - work.mass_times(zn)

    znew, converged = newton(work, lu, residual, zpred, 0.5, wt, rtol, memory)
    ynew = y + 0.5 * (z + znew)
    h3 = abs(h) ** 3
    est = (h3 / (h3 + 2.0 * P)) * (ynew - ypred)  # (h^3/12) / (h^3/12 + P/6) of the difference
    return ynew, znew, est, converged


def integrate_ode23t(work: Work, tspan, y0, f0, rtol, atol, hmax, htry, refine, max_steps, events=None):
    """Integrate with ode23t; returns ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events), located on the step's quadratic interpolant (a
    terminal event cuts the step and its interpolant there); the events found are left in
    ``work.found``."""
    t0, tf = float(tspan[0]), float(tspan[-1])
    tdir = 1.0 if tf > t0 else -1.0
    threshold = atol / rtol
    out = Output(tspan, y0, refine, events)
    steps = QuadraticSteps()
    nsteps = nfailed = 0
    status, exception = engine.STATUS_SUCCESS, None
    t, y = t0, y0.copy()
    absh = 0.0
    M = work.M
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # singular iteration matrices show as failed Newton iterations
        try:
            J = work.jacobian(t, y, f0, threshold)
            Jcurrent = True
            yp = consistent_slope(work, t, y, f0, J)
            hmin = 16.0 * math.ulp(t)
            wt = np.maximum(np.abs(y), threshold)
            # The first step: MATLAB's 1.25 ||y'/wt|| / rtol^(1/3) rule; y'' = f_t + J y' (one
            # evaluation) serves the first prediction.
            absh = min(hmax, abs(float(tspan[1]) - t0))
            h = tdir * absh
            tdel = (t + tdir * min(SQRT_EPS * max(abs(t), abs(t + h)), absh)) - t
            ypp = (work.f(t + tdel, y) - f0) / tdel + (J @ yp)
            if work.mass is not None:
                ypp = np.linalg.lstsq(M.toarray() if hasattr(M, "toarray") else M, ypp, rcond=None)[0]
            if htry == htry:
                absh = min(hmax, max(hmin, htry))
            else:
                rh = 1.25 * float(np.max(np.abs(yp) / wt)) / rtol ** POWER
                if absh * rh > 1:
                    absh = 1.0 / rh
                absh = max(absh, hmin)
            history = [(t, y)]
            memory = Newton()
            lu, lu_h = None, None
            while True:
                hmin, absh, done = clamp_step(t, tf, absh, hmax)
                nofailed = True
                while True:  # attempts at this step
                    tnew = tf if done else t + tdir * absh
                    h = tnew - t
                    if lu is None or lu_h != h:
                        lu = work.factor(M - (0.5 * h) * J)
                        lu_h = h
                        memory.havrate = False
                    wt = np.maximum(np.abs(y), threshold)
                    ypred, P = predict(history, yp, ypp, h)
                    ynew, znew, est, converged = tr_attempt(work, lu, t, y, yp, ypred, P, h, wt, rtol, memory)
                    if not converged:
                        nfailed += 1
                        if not Jcurrent:
                            J = work.jacobian(t, y, None, threshold)
                            Jcurrent = True
                            lu = None
                            continue
                        if absh <= hmin:
                            status = engine.STATUS_STEP_UNDERFLOW
                            break
                        absh = max(0.3 * absh, hmin)
                        done = False
                        nofailed = False
                        continue
                    scale = np.maximum(np.maximum(np.abs(y), np.abs(ynew)), threshold)
                    err = float(np.max(np.abs(est) / scale))
                    if err > rtol:
                        nfailed += 1
                        if absh <= hmin:
                            status = engine.STATUS_STEP_UNDERFLOW
                            break
                        if nofailed:
                            absh = max(hmin, absh * max(0.1, 0.833 * (rtol / err) ** POWER))
                        else:
                            absh = max(hmin, 0.5 * absh)
                        done = False
                        nofailed = False
                        continue
                    if err != err:
                        status = engine.STATUS_NONFINITE
                    break
                if status != engine.STATUS_SUCCESS:
                    break

                nsteps += 1
                if out.step(t, tnew, ynew, steps.add(t, h, y, *interpolant(history, tnew, ynew, h * yp, znew))):
                    t, y = out.t[-1], out.y[-1]
                    steps.cut(t)
                    status = engine.STATUS_TERMINAL_EVENT
                    break
                t, y, yp = tnew, ynew, znew / h
                history = history[-2:] + [(t, y)]
                Jcurrent = False
                if done:
                    break
                if max_steps and nsteps >= max_steps:
                    status = engine.STATUS_MAX_STEPS
                    break
                if nofailed:
                    temp = 1.2 * (err / rtol) ** POWER
                    hopt = absh / temp if temp > 0.1 else 10.0 * absh
                    if hopt > absh:
                        absh = hopt
        except Exception as exc:  # the user's right-hand side (or Jacobian) failed
            status, exception = engine.STATUS_FUN_RAISED, exc
    t_out, y_out = out.arrays()
    work.found = out.found()
    work.dense = steps.dense(y)
    return t_out, y_out, nsteps, nfailed, status, t, absh, exception
