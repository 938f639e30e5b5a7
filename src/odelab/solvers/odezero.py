"""MATLAB's ``odezero`` rule for one event, written once for both event locators (Python and compiled).

:func:`odelab.solvers.events.locate_events` (the Python engines) and the compiled loop's
``_locate`` (``solvers/compiled/loops/events.py.txt``) walk the same bracket; what they
decide at each point of it is here: the tolerance on t, whether an event is bracketed (sign
change, direction), where regula falsi (Illinois, secant through the last point tried when an
end is exactly zero) tries next, the Illinois halving, and whether a terminal event stops.
Like :mod:`odelab.solvers.controller`, every function is pure scalar arithmetic that numba
compiles as it stands: the compiled backend's module begins with controller.py's and this
file's text (see :mod:`odelab.solvers.compiled.cache`), so both take the same decisions bit
for bit.
"""

import math

_TINY = 2.2250738585072014e-308  # realmin: Illinois halving keeps values above it
#: The spacing of doubles at ``|t|``; the compiled kernels bind numpy's ``spacing(|t|)``, the same value.
_ulp = math.ulp


def event_tolerance(t, tnew):
    """How narrow the bracket of a step (t, tnew] must get: ``min(128 max(eps(t), eps(tnew)), |tnew - t|)``."""
    return min(128.0 * max(_ulp(t), _ulp(tnew)), abs(tnew - t))


def _sign(x):
    return (x > 0) - (x < 0)


def crosses(a, b, direction):
    """Whether an event's value changes sign from ``a`` to ``b`` (zero is a sign of its own) in a
    direction it accepts (``direction`` 1, -1 or 0 for both). A NaN value fails the direction test."""
    return _sign(a) != _sign(b) and direction * (b - a) >= 0


def root_fraction(vL, vR, vtry, tL, tR, ttry, delta, tdir):
    """Where one bracketed event's zero is estimated in [tL, tR], as a fraction of ``delta = tR - tL``:
    regula falsi, or, when an end value is exactly zero, the secant through the last point tried
    (``ttry``, ``vtry``) when that lies beyond the other end, else the midpoint."""
    if vL == 0:
        maybe = 0.5
        if tdir * ttry > tdir * tR and vtry != vR:
            maybe = 1.0 - vR * (ttry - tR) / ((vtry - vR) * delta)
            if maybe < 0 or maybe > 1:
                maybe = 0.5
        return maybe
    if vR == 0:
        maybe = 0.5
        if tdir * ttry < tdir * tL and vtry != vL:
            maybe = vL * (tL - ttry) / ((vtry - vL) * delta)
            if maybe < 0 or maybe > 1:
                maybe = 0.5
        return maybe
    return -vL / (vR - vL)  # regula falsi; vR != vL here


def next_try(change, tL, delta, tol, tdir):
    """The point tried: ``change`` (the least root fraction of the bracketed events) of the
    bracket from tL, never less than tol/2 from either end."""
    return tL + tdir * max(0.5 * tol, min(change * abs(delta), abs(delta) - 0.5 * tol))


def just_off(tq, tol, tdir):
    """tol/2 past ``tq``: where the search starts after a zero at the initial point or an event found."""
    return tq + tdir * 0.5 * tol


def halved(v):
    """Illinois: the value at the end that stayed twice, halved, unless that falls below realmin."""
    half = 0.5 * v
    return half if abs(half) >= _TINY else v


def stops(t, t0, tL, search_start):
    """Whether a terminal event found with the bracket's left end at tL stops the integration: not
    while the first step's search is still at its start (MATLAB registers that one as non-terminal)."""
    return t != t0 or tL != search_start
