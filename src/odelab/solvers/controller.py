"""MATLAB's step-size rules, written once for every driver (Python and compiled).

Shampine & Reichelt, *The MATLAB ODE Suite* (SIAM J. Sci. Comput. 18(1), 1997), and the
solvers' own sources, share these rules; each driver calls them (the explicit engine, ode113,
the stiff solvers, the delay solver) and the numba kernels compile the same functions (this
file's text heads their generated module, see :mod:`odelab.solvers.compiled.cache`). So
every function here is pure scalar arithmetic that numba compiles as it stands: floats and
bools in, floats out, no numpy, no objects.

The rules, with the names drivers call:

* :func:`min_step` - the smallest step at ``t``: ``hmin = 16 eps(t)``;
* :func:`given_step` and :func:`first_step` - the first step, from ``InitialStep`` or from
  the local error estimate ``rh`` a solver computes at ``t0`` (``rh * h`` is the estimate's
  ratio to the tolerance; each solver has its own ``rh``: ``||f0 / wt|| / (0.8 rtol^p)`` for
  the Runge-Kutta pairs, Shampine & Gordon's for ode113...), capped by ``MaxStep`` and the
  first output interval;
* :func:`clamp_step` - at the top of every step: ``hmin <= |h| <= hmax``, and the step
  stretched (or shrunk) to land on ``tf`` when within 10 % of it;
* :func:`shrink` - after a rejected step: the first failure scales by the error estimate
  (``max(least, safety (rtol/err)^p)``), later ones halve; never below ``hmin``;
* :func:`shrink_after_newton` - after a Newton iteration that did not converge: ``0.3 |h|``;
* :func:`grow` - after a step accepted without failure: ``|h| / (safety (err/rtol)^p)``,
  at most ``most`` times larger.

A driver stops with ``Status.STEP_UNDERFLOW`` when a step fails at ``|h| <= hmin``.
"""

from __future__ import annotations

import math

__all__ = ["min_step", "given_step", "first_step", "clamp_step", "shrink", "shrink_after_newton", "grow"]

#: The spacing of doubles at ``|t|``; the compiled kernels bind numpy's ``spacing(|t|)``, the same value.
_ulp = math.ulp


def min_step(t):
    """MATLAB's ``16*eps(t)``: 16 spacings of doubles at ``|t|`` (the smallest subnormal's 16 at 0)."""
    return 16.0 * _ulp(t)


def given_step(htry, t0, hmax):
    """The first step when the user gives one (``InitialStep``): within ``[hmin, hmax]``."""
    return min(hmax, max(min_step(t0), htry))


def first_step(rh, hspan, hmax, t0):
    """The first step chosen from the error estimate ``rh`` (per unit step) at ``t0``:
    ``min(hmax, hspan)``, reduced to ``1/rh`` when larger, and at least ``hmin``.
    ``hspan`` is the first output interval ``|tspan[1] - t0|``."""
    absh = min(hmax, hspan)
    if absh * rh > 1.0:
        absh = 1.0 / rh
    return max(absh, min_step(t0))


def clamp_step(t, tf, absh, hmax):
    """MATLAB's rule at the top of every step: ``absh`` within ``[hmin, hmax]`` with
    ``hmin = 16 eps(t)``, and stretched (or shrunk) to land on ``tf`` when within 10 % of it.

    Returns ``(hmin, absh, done)``; ``done`` means this step ends at ``tf`` (then
    ``absh = |tf - t|`` and the step is ``h = tf - t``).
    """
    hmin = min_step(t)
    if absh < hmin:  # min(hmax, max(hmin, absh)) in two tests: cheaper, and this runs every step
        absh = hmin
    if absh > hmax:
        absh = hmax
    if 1.1 * absh >= abs(tf - t):
        return hmin, abs(tf - t), True
    return hmin, absh, False


def shrink(absh, hmin, err, rtol, power, least, safety, first):
    """The step after a rejected attempt with error estimate ``err > rtol``.

    The first failure of a step scales by ``max(least, safety (rtol/err)^power)`` (ode23:
    least 0.5, safety 0.8; ode45 least 0.1); a later failure of the same step halves it.
    Never below ``hmin``.
    """
    if first:
        return max(hmin, absh * max(least, safety * (rtol / err) ** power))
    return max(hmin, 0.5 * absh)


def shrink_after_newton(absh, hmin):
    """The step after a Newton iteration that did not converge (the stiff solvers): ``0.3 |h|``."""
    return max(0.3 * absh, hmin)


def grow(absh, err, rtol, power, safety, most):
    """The next step after one accepted without failure: ``absh / (safety (err/rtol)^power)``,
    at most ``most`` times ``absh`` (MATLAB's ode23/ode45/ode23s/ode23tb: safety 1.25,
    most 5; ode15s: 1.2 and 10 at its order)."""
    temp = safety * (err / rtol) ** power
    if temp > 1.0 / most:
        return absh / temp
    return most * absh
