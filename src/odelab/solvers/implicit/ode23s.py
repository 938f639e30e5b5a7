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

import numpy as np

from odelab.solution import Solution
from odelab.solvers.api import solve
from odelab.solvers.controller import grow, shrink
from odelab.solvers.implicit.common import SQRT_EPS, Work, initial_step
from odelab.solvers.implicit.driver import Stepper, integrate, register_step

__all__ = ["integrate_ode23s", "RosenbrockStep", "D", "E32", "ode23s"]

D = 1.0 / (2.0 + math.sqrt(2.0))
E32 = 6.0 + math.sqrt(2.0)
POWER = 1.0 / 3.0


@register_step("ode23s")
class RosenbrockStep(Stepper):
    """ode23s's own part of the step: ``F0 = f(t, y)`` (FSAL), the Jacobian and ``T = df/dt``
    formed once per step (kept through its failed attempts; a W-method needs no Newton
    iteration, so an attempt never fails to converge), and the stages ``k1, k2``."""

    compile_seconds = 8.0

    @classmethod
    def for_run(cls, work, tspan, rtol, atol, extra, nonnegative=None):
        return cls(work, tspan, rtol, atol)  # as MATLAB's ode23s: no NonNegative

    def start(self, t, y, f0, hmax, htry):
        self.F0 = f0
        return initial_step(f0, y, self.threshold, self.rtol, POWER, hmax, self.htspan, t, htry)

    def begin_step(self, t, y, absh_before, absh, done):
        tdir = self.tdir
        self.h = h = self.tf - t if done else tdir * absh
        # Partial derivatives, once per step: J and T = df/dt by a forward difference.
        self.J = self.work.jacobian(t, y, self.F0, self.atol)  # numjac's thresh is AbsTol, as in MATLAB
        tdel = (t + tdir * min(SQRT_EPS * max(abs(t), abs(t + h)), absh)) - t
        self.T = (self.work.f(t + tdel, y) - self.F0) / tdel

    def attempt(self, t, y, absh, done):
        work, F0, T, h = self.work, self.F0, self.T, self.h
        hd = h * D
        lu = work.factor(work.M - hd * self.J)
        k1 = work.solve(lu, F0 + hd * T)
        F1 = work.f(t + 0.5 * h, y + 0.5 * h * k1)
        k2 = work.solve(lu, F1 - work.mass_times(k1)) + k1
        tnew = self.tf if done else t + h
        self.h = h = tnew - t
        ynew = y + h * k2
        F2 = work.f(tnew, ynew)
        k3 = work.solve(lu, F2 - E32 * (work.mass_times(k2) - F1) - 2.0 * (work.mass_times(k1) - F0) + hd * T)
        scale = np.maximum(np.maximum(np.abs(y), np.abs(ynew)), self.threshold)
        self.tnew, self.k1, self.k2, self.F2 = tnew, k1, k2, F2
        return ynew, (absh / 6.0) * float(np.max(np.abs(k1 - 2.0 * k2 + k3) / scale))

    def after_error_failure(self, absh, hmin, err, nfails, nofailed):
        absh = shrink(absh, hmin, err, self.rtol, POWER, 0.5, 0.8, nofailed)
        self.h = self.tdir * absh
        return absh

    def accept(self, t, y, ynew):
        h, k1, k2 = self.h, self.k1, self.k2

        def interp(times):
            s = (np.asarray(times)[:, None] - t) / h
            return y + h * ((s * (1 - s) / (1 - 2 * D)) * k1 + (s * (s - 2 * D) / (1 - 2 * D)) * k2)

        self.F0 = self.F2
        return self.tnew, ynew, interp

    def next_step(self, absh, err, nofailed):
        return grow(absh, err, self.rtol, POWER, 1.25, 5.0) if nofailed else absh


def integrate_ode23s(work: Work, tspan, y0, f0, rtol, atol, hmax, htry, refine, max_steps, events=None):
    """Integrate with ode23s; returns ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events), located on the step's interpolant; the events
    found are left in ``work.found``."""
    return integrate(RosenbrockStep(work, tspan, rtol, atol), tspan, y0, f0, hmax, htry, refine, max_steps, events)


def ode23s(fun, tspan, y0, **options) -> Solution:
    """Solve a stiff ODE with MATLAB's ``ode23s``: a modified Rosenbrock (2,3) W-method.

    One Jacobian per step, no Newton iteration: effective at crude tolerances. Options as
    :func:`ode15s` without ``max_order``/``bdf``; ``mass`` must be nonsingular.
    """
    return solve(fun, tspan, y0, method="ode23s", **options)
