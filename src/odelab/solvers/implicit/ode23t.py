"""MATLAB's ``ode23t``: the trapezoidal rule with its "free" interpolant, for moderately stiff
problems and index-1 DAEs.

Written from Shampine, Reichelt & Kierzenka, *Solving index-1 DAEs in MATLAB and Simulink*,
SIAM Review 41(3), 1999, and Shampine & Hosea, *Analysis and implementation of TR-BDF2*,
Applied Numerical Mathematics 20 (1996) (the trapezoidal rule in ``z = h y'``, the restart with
the backward Euler formula), with the Jacobian and Newton machinery of Shampine & Reichelt,
*The MATLAB ODE Suite*, SIAM J. Sci. Comput. 18(1), 1997 (shared with :mod:`ode15s`).

With ``z = h y'`` a step solves ``M z_{n+1} = h f(t_{n+1}, y_{n+1})`` with

* ``y_{n+1} = y_n + (z_n + z_{n+1}) / 2`` (the trapezoidal rule, TR), or
* ``y_{n+1} = y_n + z_{n+1}`` (backward Euler, BDF1) on the **first step and on a restart**.

An algebraic equation (a zero row of ``M``) is imposed at every step, which makes the rule
usable for index-1 DAEs with a singular mass matrix (the slope of the algebraic states starts
consistent, see :func:`~odelab.solvers.implicit.common.consistent_slope`).

* Prediction: BDF1 starts Newton at ``y_n + z_n``; TR at the quadratic through the last three
  solution values (``znew = 2 (ypred - y_n) - z_n``). After a BDF1 step the point before it is
  "generated" at its midpoint from the step's cubic Hermite interpolant.
* Local error: BDF1 ``h^2 y''/2`` as ``(z_{n+1} - z_n)/2``; TR ``h^3 y'''/12`` with ``y'''``
  from the cubic through ``y_{n+1}, y_n, y_{n-1}, y_{n-2}`` (half its third divided difference,
  times ``|h|^3``), in MATLAB's weighted max norm ``max(|y_n|, |y_{n+1}|, AbsTol/RelTol)``.
* Newton (simplified, on ``z``, iteration matrix ``M - gamma h J``, ``gamma = 1/2`` for TR and
  ``1`` for BDF1): at most 5 iterations to ``RelTol/2`` (``RelTol/20`` on the first with a rate
  kept from earlier steps), each correction weighted by ``max(wt, |y|)``, abandoned as soon as
  it does not contract by 10% or cannot converge in the iterations left. A failure refreshes a
  stale Jacobian; with a current one the step is cut to 0.3 h, and **after three failures the
  integration restarts with BDF1** at a step size from ``y''`` (the second divided difference of
  the last three values). The trapezoidal rule does not damp stiff components: an error there
  survives, alternating in sign, step after step (in Robertson's y2 once it falls below AbsTol);
  extrapolated over a longer step it spoils Newton's starting guess, and one damped BDF1 step
  is what clears it (without the restart ode23t thrashed on Robertson: 286,956 failed attempts
  in 200,000 steps, reaching t = 3.8e9 of 4e10 at RelTol 1e-4).
* Step size: exponent ``1/3`` (``1/2`` for BDF1), safety ``0.7``; after a success the step
  changes only by more than 20% (so the LU is kept), by ``0.2x`` to ``5x``; a failed error test
  takes ``max(0.1, 0.7 (RelTol/err)^p)``. The first step from the BDF1 error ``h^2 |y''|/2``
  with ``y'' = f_t + J y'``; after the first (BDF1) step the step is doubled (``gamma h`` and so
  the LU unchanged).
* Output between steps is the quadratic through ``y_{n-1}, y_n, y_{n+1}`` (free, O(h^3)); on a
  BDF1 step the quadratic through ``y_n``, the Hermite midpoint and ``y_{n+1}``. The slopes'
  undamped error on stiff components would otherwise reach the output (see :func:`interpolant`).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from odelab.solvers.status import Status
from odelab.solvers.controller import clamp_step, first_step, given_step, shrink, shrink_after_newton
from odelab.solvers.implicit.common import (EPS, SQRT_EPS, Newton, NonNegative, Output, QuadraticSteps, Work,
                                           consistent_slope, quadratic_through)

__all__ = ["integrate_ode23t", "predict", "local_error", "rings", "interpolant", "solve_z", "hermite_midpoint"]

POWER = 1.0 / 3.0
MAX_NEWTON = 5
KAPPA = 0.5  # Newton converges to KAPPA * RelTol
DAMPING_STEPS = 2  # BDF1 steps taken to damp a ringing component


def predict(history, tnew: float) -> np.ndarray:
    """The quadratic through the last three accepted ``(t, y)`` (the newest last), at ``tnew``."""
    (t2, y2), (t1, y1), (tn, yn) = history[-3:]
    l2 = (tnew - t1) * (tnew - tn) / ((t2 - t1) * (t2 - tn))
    l1 = (tnew - t2) * (tnew - tn) / ((t1 - t2) * (t1 - tn))
    l0 = (tnew - t2) * (tnew - t1) / ((tn - t2) * (tn - t1))
    return l2 * y2 + l1 * y1 + l0 * yn


def _divided_difference(points) -> np.ndarray:
    """The highest divided difference through ``points`` = [(t, y), ...]."""
    total = 0.0
    for i, (ti, yi) in enumerate(points):
        denominator = 1.0
        for j, (tj, _) in enumerate(points):
            if j != i:
                denominator *= ti - tj
        total = total + yi / denominator
    return total


def rings(history, ynew: np.ndarray, i: int) -> bool:
    """Does component ``i`` alternate over the last steps (``y_{n-2}, y_{n-1}, y_n, y_{n+1}``
    going up, down, up or down, up, down)? The trapezoidal rule's undamped stiff error does; a
    solution resolved by accurate steps does not (it would need two steps per period)."""
    if len(history) < 3:
        return False
    v = [p[1][i] for p in history[-3:]] + [ynew[i]]
    d = np.diff(v)
    return bool(d[0] * d[1] < 0 and d[1] * d[2] < 0)


def local_error(history, tnew: float, ynew: np.ndarray) -> np.ndarray:
    """The trapezoidal rule's local error ``h^3 y'''/12`` (a vector, before weighting), with
    ``y'''`` from the cubic through ``ynew`` and the last three values: half the third divided
    difference times ``|h|^3``, ``h = tnew - t_n``."""
    dd3 = _divided_difference([(tnew, ynew)] + list(history[-3:]))
    return 0.5 * dd3 * abs(tnew - history[-1][0]) ** 3


def hermite_midpoint(y: np.ndarray, z: np.ndarray, ynew: np.ndarray, znew: np.ndarray) -> np.ndarray:
    """The cubic Hermite interpolant through ``(y, z)`` and ``(ynew, znew)`` (``z = h y'``) at the
    middle of the step."""
    return 0.5 * (y + ynew) - 0.125 * (znew - z)


def interpolant(history, tnew: float, ynew: np.ndarray, ymid=None):
    """The step's interpolant as ``(a1, a2)`` of ``y_n + s a1 + s^2 a2``, ``s = (t - t_n)/h``.

    A TR step: the quadratic through the values ``y_{n-1}, y_n, y_{n+1}`` (free and O(h^3)); the
    slopes' undamped error on stiff components would otherwise reach the output (Robertson's y2
    at t = 4e8, between steps of 1e8, came out 1e10 tolerances off with the slopes' free
    quadratic, within 1 with the values). A BDF1 step (``ymid`` given): the quadratic through
    ``y_n``, the Hermite midpoint ``ymid`` and ``y_{n+1}``.
    """
    tn, yn = history[-1]
    if ymid is not None:
        return quadratic_through(0.5, yn, ymid, ynew)
    t1, y1 = history[-2]
    return quadratic_through((t1 - tn) / (tnew - tn), yn, y1, ynew)


def solve_z(work: Work, lu, tnew: float, ynew: np.ndarray, znew: np.ndarray, gamma: float, h: float,
            wt: np.ndarray, rtol: float, memory: Newton):
    """Simplified Newton for ``M z = h f(tnew, v + gamma z)`` from the prediction ``(ynew, znew)``
    (``ynew = v + gamma znew``); ``lu`` factors ``M - gamma h J``. Returns ``(ynew, znew, converged)``;
    ``memory`` carries the rate of convergence to the next call (reset it when ``lu`` changes).
    """
    y, z = ynew.copy(), znew.copy()
    minnrm = 100 * EPS * float(np.max(np.abs(y) / wt)) if y.size else 0.0
    oldnrm = 0.0
    for it in range(1, MAX_NEWTON + 1):
        dz = work.solve(lu, h * work.f(tnew, y) - work.mass_times(z))
        z = z + dz
        y = y + gamma * dz
        newnrm = float(np.max(np.abs(dz) / np.maximum(wt, np.abs(y)))) if y.size else 0.0
        if not math.isfinite(newnrm):
            return y, z, False
        if newnrm <= minnrm:
            return y, z, True
        if it == 1:
            if memory.havrate:
                if newnrm * memory.rate / (1 - memory.rate) <= 0.1 * KAPPA * rtol:
                    return y, z, True
            else:
                memory.rate = 0.0
        elif newnrm > 0.9 * oldnrm:
            return y, z, False
        else:
            memory.rate = max(0.9 * memory.rate, newnrm / oldnrm)
            memory.havrate = True
            errit = newnrm * memory.rate / (1 - memory.rate)
            if errit <= KAPPA * rtol:
                return y, z, True
            if it == MAX_NEWTON or KAPPA * rtol < errit * memory.rate ** (MAX_NEWTON - it):
                return y, z, False
        oldnrm = newnrm
    return y, z, False


def integrate_ode23t(work: Work, tspan, y0, f0, rtol, atol, hmax, htry, refine, max_steps, events=None,
                     nonnegative=None):
    """Integrate with ode23t; returns ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events), located on the step's quadratic interpolant (a
    terminal event cuts the step and its interpolant there); the events found are left in
    ``work.found``."""
    t0, tf = float(tspan[0]), float(tspan[-1])
    tdir = 1.0 if tf > t0 else -1.0
    threshold = atol / rtol
    nn = None if nonnegative is None else NonNegative(nonnegative, threshold)
    out = Output(tspan, y0, refine, events, nn)
    steps = QuadraticSteps()
    nsteps = nfailed = 0
    status, exception = Status.SUCCESS, None
    t, y = t0, y0.copy()
    absh = 0.0
    M = work.M
    n = y0.size
    dae = False
    if work.mass is not None:
        Md = M.toarray() if hasattr(M, "toarray") else np.asarray(M)
        dae = np.linalg.matrix_rank(Md) < n
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # singular iteration matrices show as failed Newton iterations
        try:
            J = work.jacobian(t, y, f0, atol)  # numjac's thresh is AbsTol, as in MATLAB
            Jcurrent = True
            yp = consistent_slope(work, t, y, f0, J)
            wt = np.maximum(np.abs(y), threshold)
            start, gamma, power = True, 1.0, 0.5  # the first step is BDF1
            damping = 0  # BDF1 steps left to damp a ringing component
            ringing = False
            if htry == htry:
                absh = given_step(htry, t0, hmax)
            else:
                rh = 1.43 * float(np.max(np.abs(yp) / wt)) / rtol ** power
                absh = first_step(rh, abs(float(tspan[1]) - t0), hmax, t0)
                if not dae:
                    # BDF1's error is h^2 |y''| / 2 with y'' = f_t + J y' (one evaluation).
                    h = tdir * absh
                    tdel = (t + tdir * min(SQRT_EPS * max(abs(t), abs(t + h)), absh)) - t
                    ypp = (work.f(t + tdel, y) - f0) / tdel + (J @ yp)
                    if work.mass is not None:
                        ypp = np.linalg.solve(Md, ypp)
                    rh = 1.43 * math.sqrt(0.5 * float(np.max(np.abs(ypp) / wt)) / rtol)
                    absh = first_step(rh, abs(float(tspan[1]) - t0), hmax, t0)
            z = tdir * absh * yp
            history = [(t, y)]
            memory = Newton()
            lu = None
            need_lu, need_j = True, False
            done = False
            err = 0.0
            while not done:
                absh_last = absh
                hmin, absh, done = clamp_step(t, tf, absh, hmax)
                h = tf - t if done else tdir * absh
                if absh != absh_last:
                    z = (absh / absh_last) * z
                    need_lu = True
                nofailed = True
                itfailed = 0
                while True:  # attempts at this step
                    wt = np.maximum(np.abs(y), threshold)
                    if need_j:
                        J = work.jacobian(t, y, None, atol)
                        Jcurrent, need_j, need_lu = True, False, True
                    if need_lu:
                        lu = work.factor(M - (gamma * h) * J)
                        memory.havrate = False
                        need_lu = False
                    tnew = tf if done else t + h
                    h = tnew - t
                    if start and len(history) < 3:
                        ynew, znew = y + z, z
                    elif start:  # damping a ringing component: z carries its error, the values less
                        ynew = predict(history, tnew)
                        znew = ynew - y
                    else:
                        ynew = predict(history, tnew)
                        znew = 2.0 * (ynew - y) - z
                    ynew, znew, converged = solve_z(work, lu, tnew, ynew, znew, gamma, h, wt, rtol, memory)
                    if not converged:
                        nfailed += 1
                        nofailed = False
                        itfailed += 1
                        if not Jcurrent:
                            need_j = True
                            continue
                        if absh <= hmin:
                            status = Status.STEP_UNDERFLOW
                            break
                        absh_last = absh
                        if itfailed == 3 and not start:
                            # Restart with BDF1, sized from y'' (the last three values).
                            start, gamma, power = True, 1.0, 0.5
                            ypp2 = _divided_difference(history[-3:])  # y''/2
                            e = float(np.max(np.abs(ypp2) / wt)) * absh * absh
                            q = math.sqrt(e / rtol)
                            ratio = hmax / absh
                            if 0.7 < q * ratio:
                                ratio = 0.7 / q
                            absh = max(ratio * absh, hmin)
                        else:
                            absh = shrink_after_newton(absh, hmin)
                        h = tdir * absh
                        z = (absh / absh_last) * z
                        need_lu = True
                        done = False
                        continue
                    wt = np.maximum(wt, np.abs(ynew))
                    if start:
                        err = float(np.max(np.abs(0.5 * (znew - z)) / wt)) if n else 0.0
                    else:
                        est = np.abs(local_error(history, tnew, ynew)) / wt
                        err = float(np.max(est)) if n else 0.0
                        ringing = err > 0.1 * rtol and rings(history, ynew, int(np.argmax(est)))
                    if nn is not None:
                        err = nn.error(err, ynew, rtol)
                    if err > rtol:
                        nfailed += 1
                        if absh <= hmin:
                            status = Status.STEP_UNDERFLOW
                            break
                        nofailed = False
                        absh_last = absh
                        absh = shrink(absh_last, hmin, err, rtol, power, 0.1, 0.7, True)
                        if not start and ringing:
                            start, gamma, power, damping = True, 1.0, 0.5, DAMPING_STEPS
                        h = tdir * absh
                        z = (absh / absh_last) * z
                        need_lu = True
                        done = False
                        continue
                    if err != err:
                        status = Status.NONFINITE
                    break
                if status != Status.SUCCESS:
                    break

                nsteps += 1
                if nn is not None:
                    ynew = nn.clip(ynew)
                ymid = hermite_midpoint(y, z, ynew, znew) if start else None
                if out.step(t, tnew, ynew, steps.add(t, h, y, *interpolant(history, tnew, ynew, ymid))):
                    t, y = out.t[-1], out.y[-1]
                    steps.cut(t)
                    status = Status.TERMINAL_EVENT
                    break
                if start and damping > 1:
                    history = [(tnew, ynew)]  # damped: the next BDF1 step starts afresh from here
                elif start:
                    # The point before the step is "generated" at its midpoint.
                    history = [(t, y), (t + 0.5 * h, ymid), (tnew, ynew)]
                else:
                    history = history[-2:] + [(tnew, ynew)]
                t, y, z = tnew, ynew, znew
                Jcurrent = False
                if done:
                    break
                if max_steps and nsteps >= max_steps:
                    status = Status.MAX_STEPS
                    break
                if start and damping > 1:
                    damping -= 1
                elif start:
                    # From BDF1 to TR: doubling h keeps gamma h, and so the LU.
                    start, gamma, power, damping = False, 0.5, POWER, 0
                    absh *= 2.0
                    z = 2.0 * z
                elif ringing:
                    start, gamma, power, damping = True, 1.0, 0.5, DAMPING_STEPS
                    need_lu = True
                elif nofailed:
                    q = (err / rtol) ** power
                    ratio = hmax / absh
                    if 0.7 < q * ratio:
                        ratio = 0.7 / q
                    ratio = min(5.0, max(0.2, ratio))
                    if abs(ratio - 1.0) > 0.2:
                        absh *= ratio
                        z = ratio * z
                        need_lu = True
        except Exception as exc:  # the user's right-hand side (or Jacobian) failed
            status, exception = Status.FUN_RAISED, exc
    t_out, y_out = out.arrays()
    work.found = out.found()
    work.dense = steps.dense(y, nn)
    return t_out, y_out, nsteps, nfailed, status, t, absh, exception
