"""MATLAB's ``ode23tb``: TR-BDF2, an implicit Runge-Kutta formula with a trapezoidal-rule stage
and a BDF2 stage, for stiff problems at crude tolerances.

Written from Hosea & Shampine, *Analysis and implementation of TR-BDF2*, Applied Numerical
Mathematics 20 (1996), with the Jacobian and Newton machinery of Shampine & Reichelt, *The
MATLAB ODE Suite*, SIAM J. Sci. Comput. 18(1), 1997 (shared with :mod:`ode15s`).

With ``gamma = 2 - sqrt 2``, ``d = gamma / 2`` and ``w = sqrt(2) / 4`` the step ``t -> t + h``
is, in terms of ``z = h y'``:

    y_g    = y_n + d (z_n + z_g)                   TR from t_n to t_n + gamma h
    y_n+1  = y_n + w (z_n + z_g) + d z_n+1          BDF2 through y_n, y_g, y_n+1

with ``M z = h f(t, y)`` solved for ``z_g`` and then ``z_n+1``. Both stages have the iteration
matrix ``M - d h J`` (the reason for this gamma), so one LU serves the step. As a Runge-Kutta
formula it is stiffly accurate and L-stable with ``c = (0, gamma, 1)`` and weights
``b = (w, w, d)``; the companion third-order weights ``bhat = ((1-w)/3, (3w+1)/3, d/3)`` give
the local-error estimate of the second-order result,

    est = (M - d h J)^-1 M ((1-4w)/3 z_n + 1/3 z_g - 2d/3 z_n+1)

The factor ``(M - d h J)^-1 M`` (one more linear solve) tends to the identity as ``h -> 0`` —
the estimate stays asymptotically correct (tested) — and keeps it bounded on stiff components,
where the raw difference grows like ``h lambda``. The interpolant is the quadratic through
``y_n``, ``y_g`` and ``y_n+1``, free of evaluations. ``z_n+1`` is the next step's ``z_n``
(first same as last). The step-size rules are MATLAB's for its one-step order-3 estimates
(those of ode23s): exponent 1/3, safety 1.25 and at most 5x up after a success, ``max(0.5,
0.8 (rtol/err)^(1/3))`` after a first failure and halving after more; a failed Newton iteration
refreshes a stale Jacobian, or else cuts the step by 0.3, as in ode15s.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from odelab.solvers.status import Status
from odelab.solvers.controller import clamp_step, grow, shrink, shrink_after_newton
from odelab.solvers.implicit.common import (Newton, NonNegative, Output, QuadraticSteps, Work, initial_step, newton,
                                           quadratic_through)

__all__ = ["integrate_ode23tb", "trbdf2_attempt", "GAMMA", "D", "W", "B", "BHAT"]

GAMMA = 2.0 - math.sqrt(2.0)
D = GAMMA / 2.0  # = (1 - gamma) / (2 - gamma): the same diagonal for both stages
W = math.sqrt(2.0) / 4.0  # = (1 - d) / 2
B = np.array([W, W, D])
BHAT = np.array([(1.0 - W) / 3.0, (3.0 * W + 1.0) / 3.0, D / 3.0])
E = BHAT - B  # (1 - 4w)/3, 1/3, -2d/3
POWER = 1.0 / 3.0


def trbdf2_attempt(work: Work, lu, t: float, y: np.ndarray, z: np.ndarray, zslope: np.ndarray, h: float,
                   wt: np.ndarray, rtol: float, memory: Newton):
    """One TR-BDF2 step ``t -> t + h`` from ``y`` and ``z = h y'(t)``.

    ``lu`` factors ``M - d h J``; ``zslope`` (``h^2 y''`` or zeros) extrapolates the TR stage's
    starting guess. Returns ``(ynew, y_g, znew, est, converged)`` with ``est`` the local-error
    estimate (a vector).
    """
    tg, tnew = t + GAMMA * h, t + h

    def tr_residual(zg):
        return h * work.f(tg, y + D * (z + zg)) - work.mass_times(zg)

    zg, converged = newton(work, lu, tr_residual, z + GAMMA * zslope, D, wt, rtol, memory)
    if not converged:
        return None, None, None, None, False
    yg = y + D * (z + zg)
    base = y + W * (z + zg)

    def bdf_residual(zn):
        return h * work.f(tnew, base + D * zn) - work.mass_times(zn)

    zpred = z + (zg - z) / GAMMA  # the slope extrapolated linearly through t_n and t_n + gamma h
    znew, converged = newton(work, lu, bdf_residual, zpred, D, wt, rtol, memory)
    if not converged:
        return None, None, None, None, False
    ynew = base + D * znew
    est = work.solve(lu, work.mass_times(E[0] * z + E[1] * zg + E[2] * znew))
    return ynew, yg, znew, est, True


def integrate_ode23tb(work: Work, tspan, y0, f0, rtol, atol, hmax, htry, refine, max_steps, events=None,
                      nonnegative=None):
    """Integrate with ode23tb; returns ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events), located on the step's quadratic interpolant (a
    terminal event cuts the step and its interpolant there); the events found are left in
    ``work.found``."""
    t0, tf = float(tspan[0]), float(tspan[-1])
    tdir = 1.0 if tf > t0 else -1.0
    threshold = atol / rtol
    nn = None if nonnegative is None else NonNegative(nonnegative, threshold)
    out = Output(tspan, y0, refine, events, nn)
    steps = QuadraticSteps()  # the quadratic through y_n, y_g, y_n+1: Refine, tspan output and deval
    nsteps = nfailed = 0
    status, exception = Status.SUCCESS, None
    t, y = t0, y0.copy()
    M = work.M
    absh = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # singular iteration matrices show as failed Newton iterations
        try:
            J = work.jacobian(t, y, f0, atol)  # numjac's thresh is AbsTol, as in MATLAB
            Jcurrent = True
            yp = f0 if work.mass is None else np.linalg.solve(M.toarray() if hasattr(M, "toarray") else M, f0)
            absh = initial_step(yp, y0, threshold, rtol, POWER, hmax, abs(float(tspan[1]) - t0), t0, htry)
            ypp = np.zeros_like(yp)  # y'' from the last step, for the first stage's starting guess
            memory = Newton()
            lu, lu_h = None, None
            while True:
                hmin, absh, done = clamp_step(t, tf, absh, hmax)
                nofailed = True
                while True:  # attempts at this step
                    tnew = tf if done else t + tdir * absh
                    h = tnew - t
                    if lu is None or lu_h != h:
                        lu = work.factor(M - (D * h) * J)
                        lu_h = h
                        memory.havrate = False
                    wt = np.maximum(np.abs(y), threshold)
                    ynew, yg, znew, est, converged = trbdf2_attempt(work, lu, t, y, h * yp, h * h * ypp, h, wt,
                                                                    rtol, memory)
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
                        absh = shrink_after_newton(absh, hmin)
                        done = False
                        nofailed = False
                        continue
                    scale = np.maximum(np.maximum(np.abs(y), np.abs(ynew)), threshold)
                    err = float(np.max(np.abs(est) / scale))
                    if nn is not None:
                        err = nn.error(err, ynew, rtol)
                    if err > rtol:
                        nfailed += 1
                        if absh <= hmin:
                            status = Status.STEP_UNDERFLOW
                            break
                        absh = shrink(absh, hmin, err, rtol, POWER, 0.5, 0.8, nofailed)
                        done = False
                        nofailed = False
                        continue
                    if err != err:
                        status = Status.NONFINITE
                    break
                if status != Status.SUCCESS:
                    break

                nsteps += 1
                if nn is not None:
                    ynew = nn.clip(ynew)
                if out.step(t, tnew, ynew, steps.add(t, h, y, *quadratic_through(GAMMA, y, yg, ynew))):
                    t, y = out.t[-1], out.y[-1]
                    steps.cut(t)
                    status = Status.TERMINAL_EVENT
                    break
                ypnew = znew / h
                ypp = (ypnew - yp) / h
                t, y, yp = tnew, ynew, ypnew
                Jcurrent = False
                if done:
                    break
                if max_steps and nsteps >= max_steps:
                    status = Status.MAX_STEPS
                    break
                if nofailed:
                    absh = grow(absh, err, rtol, POWER, 1.25, 5.0)
        except Exception as exc:  # the user's right-hand side (or Jacobian) failed
            status, exception = Status.FUN_RAISED, exc
    t_out, y_out = out.arrays()
    work.found = out.found()
    work.dense = steps.dense(y, nn)
    return t_out, y_out, nsteps, nfailed, status, t, absh, exception
