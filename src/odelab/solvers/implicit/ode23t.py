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

import numpy as np

from odelab.solution import Solution
from odelab.solvers.api import solve
from odelab.solvers.controller import first_step, given_step, shrink, shrink_after_newton
from odelab.solvers.implicit.common import (EPS, SQRT_EPS, Newton, QuadraticRecords, QuadraticSteps, Work,
                                           consistent_slope, jacobian_times, quadratic_through, rate_test)
from odelab.solvers.implicit.driver import Stepper, integrate, register_step

__all__ = ["integrate_ode23t", "TrapezoidalStep", "predict", "local_error", "rings", "interpolant", "solve_z",
           "hermite_midpoint", "ode23t"]

POWER = 1.0 / 3.0
MAX_NEWTON = 5
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
        verdict = rate_test(it, newnrm, oldnrm, minnrm, memory, rtol, MAX_NEWTON)  # to RelTol/2
        if verdict is not None:
            return y, z, verdict
        oldnrm = newnrm
    return y, z, False


@register_step("ode23t")
class TrapezoidalStep(QuadraticRecords, Stepper):
    """ode23t's own part of the step: ``z = h y'``, the last three accepted points (``history``:
    prediction, error estimate, interpolant), whether the step is BDF1 (``bdf1``: the first
    step, a restart, or damping a ringing component) or TR, and the LU of ``M - gamma h J``."""

    refresh_clears_nofailed = True

    def __init__(self, work: Work, tspan, rtol, atol, nonnegative=None):
        super().__init__(work, tspan, rtol, atol, nonnegative)
        self.steps = QuadraticSteps(work.n)
        self.memory = Newton()
        self.dae = False
        if work.mass is not None:
            M = work.M
            self.Md = M.toarray() if hasattr(M, "toarray") else np.asarray(M)
            self.dae = np.linalg.matrix_rank(self.Md) < work.n

    def start(self, t, y, f0, hmax, htry):
        work, rtol, tdir = self.work, self.rtol, self.tdir
        self.hmax = hmax
        self.J = work.jacobian(t, y, f0, self.atol)  # numjac's thresh is AbsTol, as in MATLAB
        self.jcurrent = True
        yp = consistent_slope(work, t, y, f0, self.J)
        wt = np.maximum(np.abs(y), self.threshold)
        self._bdf1(0)  # the first step is BDF1
        self.ringing = False
        if htry == htry:
            absh = given_step(htry, t, hmax)
        else:
            rh = 1.43 * float(np.max(np.abs(yp) / wt)) / rtol ** self.power
            absh = first_step(rh, self.htspan, hmax, t)
            if not self.dae:
                # BDF1's error is h^2 |y''| / 2 with y'' = f_t + J y' (one evaluation).
                h = tdir * absh
                tdel = (t + tdir * min(SQRT_EPS * max(abs(t), abs(t + h)), absh)) - t
                ypp = (work.f(t + tdel, y) - f0) / tdel + jacobian_times(self.J, yp)
                if work.mass is not None:
                    ypp = np.linalg.solve(self.Md, ypp)
                rh = 1.43 * math.sqrt(0.5 * float(np.max(np.abs(ypp) / wt)) / rtol)
                absh = first_step(rh, self.htspan, hmax, t)
        self.z = tdir * absh * yp
        self.history = [(t, y)]
        self.lu = None
        self.need_lu = True
        return absh

    def _bdf1(self, damping):
        """Take BDF1 steps (``damping`` of them to damp a ringing component, else until TR resumes)."""
        self.bdf1, self.gamma, self.power, self.damping = True, 1.0, 0.5, damping

    def begin_step(self, t, y, absh_before, absh, done):
        self.h = self.tf - t if done else self.tdir * absh
        if absh != absh_before:
            self.z = (absh / absh_before) * self.z
            self.need_lu = True
        self.itfailed = 0

    def jacobian_changed(self):
        self.need_lu = True

    def _rescaled(self, absh_old, absh):
        self.h = self.tdir * absh
        self.z = (absh / absh_old) * self.z
        self.need_lu = True
        return absh

    def attempt(self, t, y, absh, done):
        work, history, z = self.work, self.history, self.z
        self.wt = wt = np.maximum(np.abs(y), self.threshold)
        if self.need_lu:
            self.lu = work.factor(work.M - (self.gamma * self.h) * self.J)
            self.memory.havrate = False
            self.need_lu = False
        tnew = self.tf if done else t + self.h
        self.h = h = tnew - t
        if self.bdf1 and len(history) < 3:
            ynew, znew = y + z, z
        elif self.bdf1:  # damping a ringing component: z carries its error, the values less
            ynew = predict(history, tnew)
            znew = ynew - y
        else:
            ynew = predict(history, tnew)
            znew = 2.0 * (ynew - y) - z
        ynew, znew, converged = solve_z(work, self.lu, tnew, ynew, znew, self.gamma, h, wt, self.rtol, self.memory)
        if not converged:
            self.itfailed += 1
            return None
        wt = np.maximum(wt, np.abs(ynew))
        n = y.size
        if self.bdf1:
            err = float(np.max(np.abs(0.5 * (znew - z)) / wt)) if n else 0.0
        else:
            est = np.abs(local_error(history, tnew, ynew)) / wt
            err = float(np.max(est)) if n else 0.0
            self.ringing = err > 0.1 * self.rtol and rings(history, ynew, int(np.argmax(est)))
        self.tnew, self.znew = tnew, znew
        return ynew, err

    def after_newton_failure(self, absh, hmin):
        if self.itfailed == 3 and not self.bdf1:
            # Restart with BDF1, sized from y'' (the last three values).
            self._bdf1(self.damping)
            ypp2 = _divided_difference(self.history[-3:])  # y''/2
            e = float(np.max(np.abs(ypp2) / self.wt)) * absh * absh
            q = math.sqrt(e / self.rtol)
            ratio = self.hmax / absh
            if 0.7 < q * ratio:
                ratio = 0.7 / q
            return self._rescaled(absh, max(ratio * absh, hmin))
        return self._rescaled(absh, shrink_after_newton(absh, hmin))

    def after_error_failure(self, absh, hmin, err, nfails, nofailed):
        absh_new = shrink(absh, hmin, err, self.rtol, self.power, 0.1, 0.7, True)
        if not self.bdf1 and self.ringing:
            self._bdf1(DAMPING_STEPS)
        return self._rescaled(absh, absh_new)

    def accept(self, t, y, ynew):
        tnew, h, znew, history = self.tnew, self.h, self.znew, self.history
        ymid = hermite_midpoint(y, self.z, ynew, znew) if self.bdf1 else None
        interp = self.steps.add(t, h, y, *interpolant(history, tnew, ynew, ymid))
        if self.bdf1 and self.damping > 1:
            self.history = [(tnew, ynew)]  # damped: the next BDF1 step starts afresh from here
        elif self.bdf1:
            # The point before the step is "generated" at its midpoint.
            self.history = [(t, y), (t + 0.5 * h, ymid), (tnew, ynew)]
        else:
            self.history = history[-2:] + [(tnew, ynew)]
        self.z = znew
        return tnew, ynew, interp

    def next_step(self, absh, err, nofailed):
        if self.bdf1 and self.damping > 1:
            self.damping -= 1
        elif self.bdf1:
            # From BDF1 to TR: doubling h keeps gamma h, and so the LU.
            self.bdf1, self.gamma, self.power, self.damping = False, 0.5, POWER, 0
            absh *= 2.0
            self.z = 2.0 * self.z
        elif self.ringing:
            self._bdf1(DAMPING_STEPS)
            self.need_lu = True
        elif nofailed:
            q = (err / self.rtol) ** self.power
            ratio = self.hmax / absh
            if 0.7 < q * ratio:
                ratio = 0.7 / q
            ratio = min(5.0, max(0.2, ratio))
            if abs(ratio - 1.0) > 0.2:
                absh *= ratio
                self.z = ratio * self.z
                self.need_lu = True
        return absh


def integrate_ode23t(work: Work, tspan, y0, f0, rtol, atol, hmax, htry, refine, max_steps, events=None,
                     nonnegative=None):
    """Integrate with ode23t; returns ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events), located on the step's quadratic interpolant (a
    terminal event cuts the step and its interpolant there); the events found are left in
    ``work.found``. ``nonnegative``: the indices kept >= 0 (MATLAB's NonNegative), or None."""
    stepper = TrapezoidalStep(work, tspan, rtol, atol, nonnegative)
    return integrate(stepper, tspan, y0, f0, hmax, htry, refine, max_steps, events)


def ode23t(fun, tspan, y0, **options) -> Solution:
    """MATLAB's ``ode23t`` name (trapezoidal rule, moderately stiff problems and DAEs)."""
    return solve(fun, tspan, y0, method="ode23t", **options)
