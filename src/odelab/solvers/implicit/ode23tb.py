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

import numpy as np

from odelab.solution import Solution
from odelab.solvers.api import solve
from odelab.solvers.controller import grow, shrink, shrink_after_newton
from odelab.solvers.implicit.common import (Newton, QuadraticRecords, QuadraticSteps, Work, initial_step, newton,
                                           quadratic_through)
from odelab.solvers.implicit.driver import Stepper, integrate, register_step

__all__ = ["integrate_ode23tb", "TRBDF2Step", "trbdf2_attempt", "GAMMA", "D", "W", "B", "BHAT", "ode23tb"]

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


@register_step("ode23tb")
class TRBDF2Step(QuadraticRecords, Stepper):
    """ode23tb's own part of the step: ``y'`` and ``y''`` at the step's start (FSAL; the first
    stage's starting guess), the LU of ``M - d h J`` keyed on ``h``, and the accepted steps'
    quadratics (output and ``deval``)."""

    def __init__(self, work: Work, tspan, rtol, atol, nonnegative=None):
        super().__init__(work, tspan, rtol, atol, nonnegative)
        self.steps = QuadraticSteps(work.n)  # the quadratic through y_n, y_g, y_n+1: Refine, tspan output and deval
        self.memory = Newton()
        self.lu, self.lu_h = None, None

    def start(self, t, y, f0, hmax, htry):
        work = self.work
        self.J = work.jacobian(t, y, f0, self.atol)  # numjac's thresh is AbsTol, as in MATLAB
        self.jcurrent = True
        M = work.M
        self.yp = f0 if work.mass is None else np.linalg.solve(M.toarray() if hasattr(M, "toarray") else M, f0)
        self.ypp = np.zeros_like(self.yp)  # y'' from the last step, for the first stage's starting guess
        return initial_step(self.yp, y, self.threshold, self.rtol, POWER, hmax, self.htspan, t, htry)

    def jacobian_changed(self):
        self.lu = None

    def attempt(self, t, y, absh, done):
        work = self.work
        tnew = self.tf if done else t + self.tdir * absh
        h = tnew - t
        if self.lu is None or self.lu_h != h:
            self.lu = work.factor(work.M - (D * h) * self.J)
            self.lu_h = h
            self.memory.havrate = False
        wt = np.maximum(np.abs(y), self.threshold)
        ynew, yg, znew, est, converged = trbdf2_attempt(work, self.lu, t, y, h * self.yp, h * h * self.ypp, h, wt,
                                                        self.rtol, self.memory)
        if not converged:
            return None
        scale = np.maximum(np.maximum(np.abs(y), np.abs(ynew)), self.threshold)
        self.tnew, self.h, self.yg, self.znew = tnew, h, yg, znew
        return ynew, float(np.max(np.abs(est) / scale))

    def after_newton_failure(self, absh, hmin):
        return shrink_after_newton(absh, hmin)

    def after_error_failure(self, absh, hmin, err, nfails, nofailed):
        return shrink(absh, hmin, err, self.rtol, POWER, 0.5, 0.8, nofailed)

    def accept(self, t, y, ynew):
        h = self.h
        interp = self.steps.add(t, h, y, *quadratic_through(GAMMA, y, self.yg, ynew))
        ypnew = self.znew / h
        self.ypp = (ypnew - self.yp) / h
        self.yp = ypnew
        return self.tnew, ynew, interp

    def next_step(self, absh, err, nofailed):
        return grow(absh, err, self.rtol, POWER, 1.25, 5.0) if nofailed else absh


def integrate_ode23tb(work: Work, tspan, y0, f0, rtol, atol, hmax, htry, refine, max_steps, events=None,
                      nonnegative=None):
    """Integrate with ode23tb; returns ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events), located on the step's quadratic interpolant (a
    terminal event cuts the step and its interpolant there); the events found are left in
    ``work.found``. ``nonnegative``: the indices kept >= 0 (MATLAB's NonNegative), or None."""
    return integrate(TRBDF2Step(work, tspan, rtol, atol, nonnegative), tspan, y0, f0, hmax, htry, refine, max_steps,
                     events)


def ode23tb(fun, tspan, y0, **options) -> Solution:
    """MATLAB's ``ode23tb`` name (TR-BDF2, stiff problems at crude tolerances)."""
    return solve(fun, tspan, y0, method="ode23tb", **options)
