"""MATLAB's ``ode23s``: the modified Rosenbrock (2,3) pair.

Written from Shampine & Reichelt, *The MATLAB ODE Suite*, SIAM J. Sci. Comput. 18(1), 1997,
Section 3. With ``d = 1/(2 + sqrt 2)`` and ``W = M - h d J``:

    F0 = f(t, y)
    k1 = W \\ (F0 + h d T)                      T = df/dt
    F1 = f(t + h/2, y + h/2 k1)
    k2 = W \\ (F1 - M k1) + k1
    ynew = y + h k2                            (second order, the one propagated)
    F2 = f(t + h, ynew)
    k3 = W \\ (F2 - e32 (M k2 - F1) - 2 (M k1 - F0) + h d T)     e32 = 6 + sqrt 2
    err = h/6 ||k1 - 2 k2 + k3||               (the third-order estimate)

It is a W-method: the formula stays second order with any approximation to J, so J is formed
once per step (not per attempt) and kept through failed attempts. Its interpolant is the
paper's "free" one, ``y + h (s(1-s)/(1-2d) k1 + s(s-2d)/(1-2d) k2)``. One LU decomposition and
three linear solves per attempt, two function evaluations per attempt plus one for ``df/dt``
per step (unless the problem is autonomous in form); MATLAB's controller for a third-order
estimate: exponent 1/3, first failure ``max(0.5, 0.8 (rtol/err)^(1/3))``, then halving.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from odelab.solvers.status import Status
from odelab.solvers.controller import clamp_step, grow, shrink
from odelab.solvers.implicit.common import SQRT_EPS, Output, Work, initial_step

__all__ = ["integrate_ode23s", "D", "E32"]

D = 1.0 / (2.0 + math.sqrt(2.0))
E32 = 6.0 + math.sqrt(2.0)
POWER = 1.0 / 3.0


def integrate_ode23s(work: Work, tspan, y0, f0, rtol, atol, hmax, htry, refine, max_steps, events=None):
    """Integrate with ode23s; returns ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events), located on the step's interpolant; the events
    found are left in ``work.found``."""
    t0, tf = float(tspan[0]), float(tspan[-1])
    tdir = 1.0 if tf > t0 else -1.0
    threshold = atol / rtol
    out = Output(tspan, y0, refine, events)
    nsteps = nfailed = 0
    status, exception = Status.SUCCESS, None
    t, y, F0 = t0, y0.copy(), f0
    M = work.M
    absh = initial_step(f0, y0, threshold, rtol, POWER, hmax, abs(float(tspan[1]) - t0), t0, htry)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            while True:
                hmin, absh, done = clamp_step(t, tf, absh, hmax)
                h = tf - t if done else tdir * absh
                # Partial derivatives, once per step: J and T = df/dt by a forward difference.
                J = work.jacobian(t, y, F0, atol)  # numjac's thresh is AbsTol, as in MATLAB
                tdel = (t + tdir * min(SQRT_EPS * max(abs(t), abs(t + h)), absh)) - t
                T = (work.f(t + tdel, y) - F0) / tdel
                nofailed = True
                while True:
                    hd = h * D
                    W = M - hd * J
                    lu = work.factor(W)
                    k1 = work.solve(lu, F0 + hd * T)
                    F1 = work.f(t + 0.5 * h, y + 0.5 * h * k1)
                    k2 = work.solve(lu, F1 - work.mass_times(k1)) + k1
                    tnew = tf if done else t + h
                    h = tnew - t
                    ynew = y + h * k2
                    F2 = work.f(tnew, ynew)
                    k3 = work.solve(lu, F2 - E32 * (work.mass_times(k2) - F1) - 2.0 * (work.mass_times(k1) - F0)
                                    + hd * T)
                    scale = np.maximum(np.maximum(np.abs(y), np.abs(ynew)), threshold)
                    err = (absh / 6.0) * float(np.max(np.abs(k1 - 2.0 * k2 + k3) / scale))
                    if err > rtol:
                        nfailed += 1
                        if absh <= hmin:
                            status = Status.STEP_UNDERFLOW
                            break
                        absh = shrink(absh, hmin, err, rtol, POWER, 0.5, 0.8, nofailed)
                        nofailed = False
                        h = tdir * absh
                        done = False
                    elif err <= rtol:
                        break
                    else:
                        status = Status.NONFINITE
                        break
                if status != Status.SUCCESS:
                    break
                nsteps += 1

                def interp(times, _t=t, _h=h, _y=y, _k1=k1, _k2=k2):
                    s = (np.asarray(times)[:, None] - _t) / _h
                    return _y + _h * ((s * (1 - s) / (1 - 2 * D)) * _k1 + (s * (s - 2 * D) / (1 - 2 * D)) * _k2)

                if out.step(t, tnew, ynew, interp):
                    t = out.t[-1]
                    status = Status.TERMINAL_EVENT
                    break
                if done:
                    t = tnew
                    break
                if max_steps and nsteps >= max_steps:
                    t = tnew
                    status = Status.MAX_STEPS
                    break
                if nofailed:
                    absh = grow(absh, err, rtol, POWER, 1.25, 5.0)
                t, y, F0 = tnew, ynew, F2
        except Exception as exc:
            status, exception = Status.FUN_RAISED, exc
    t_out, y_out = out.arrays()
    work.found = out.found()
    return t_out, y_out, nsteps, nfailed, status, t, absh, exception
