"""Event location: zeros of event functions on a step's continuous extension (MATLAB's ``odezero``).

The algorithm is the one the MATLAB ODE Suite documents and ships (L. F. Shampine, M. W. Reichelt,
*The MATLAB ODE Suite*, SIAM J. Sci. Comput. 18(1), 1997, Sec. 4; L. F. Shampine, S. Thompson,
*Event location for ordinary differential equations*, Comput. Math. Appl. 39, 2000): after each
accepted step from ``t`` to ``tnew`` the event functions are evaluated at ``tnew``; an event
``j`` is *bracketed* when its value changes sign between the bracket ends (a value of exactly
zero counts as a sign of its own) in a direction it accepts. The bracket is narrowed by regula
falsi on the step's interpolant, using the leftmost root estimate of all bracketed events, with
the Illinois modification (after two moves of the same end the value at the other end is
halved), never moving by less than ``tol/2`` nor closer than ``tol/2`` to the far end, until
it is no wider than ``tol = min(128 * max(eps(t), eps(tnew)), |tnew - t|)``. The events found
are reported at the right end of the final bracket. Then the search goes on in
``[tR + tol/2, tnew]`` for later events of the step, unless one found is terminal (all events
found with it are reported, the step is cut there) or the bracket reached ``tnew``.

An event function that is exactly zero at the initial time ``t0`` is not an event there, as
MATLAB's ``odezero`` ignores a zero at the initial point: a ball released from the floor, or a
crossing function that starts at zero, reports nothing at ``t0``. The first step's search
starts just off ``t0`` (``t0 + tol/2`` on the interpolant), so a function that leaves zero and
comes back is still located where it returns. A restart after an event with a reset is a new
``t0`` (MATLAB's loop around the solver), so a function zero there does not fire again. A
terminal event located while the bracket's left end is still where the first step's search
began does not stop the integration (MATLAB registers such an event as non-terminal).

This module is plain array code called by the driver between steps; it keeps no state.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from odelab.exceptions import InputError
from odelab.solvers.odezero import crosses, event_tolerance, halved, just_off, next_try, root_fraction, stops

__all__ = ["locate_events", "as_event_function", "CallbackError"]

class CallbackError(Exception):
    """A user function other than ``fun`` raised during integration; carries what and the original."""

    def __init__(self, what: str, t: float, original: BaseException):
        super().__init__(str(original))
        self.what = what
        self.t = t
        self.original = original


_NONE = np.empty(0, dtype=np.intp)
_NONE.setflags(write=False)
#: Up to this many events the bracket test runs on Python floats: it runs after every step, and
#: for a few values the numpy expression's eight calls cost more than the arithmetic.
_FEW_EVENTS = 8


def _bracketed(vL: np.ndarray, vR: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Indices of the events whose value changes sign (zero is a sign of its own) between the two
    ends in a direction they accept: :func:`odelab.solvers.odezero.crosses` for each, or its
    vectorised form for many events. (With a NaN value the direction test fails in both forms.)"""
    if vL.size <= _FEW_EVENTS:
        hits = [j for j, (a, b, d) in enumerate(zip(vL.tolist(), vR.tolist(), direction.tolist())) if crosses(a, b, d)]
        return np.array(hits, dtype=np.intp) if hits else _NONE
    return np.flatnonzero((np.sign(vL) != np.sign(vR)) & (direction * (vR - vL) >= 0))


def locate_events(interpolate: Callable[[float], np.ndarray], events: Callable, v: np.ndarray,
                  t: float, y: np.ndarray, tnew: float, ynew: np.ndarray, t0: float):
    """Find the events of one step ``(t, tnew]``.

    Parameters
    ----------
    interpolate
        ``interpolate(tq)``: the step's continuous extension at a time inside the step.
    events
        ``events(t, y) -> (value, isterminal, direction)`` as float/bool arrays of equal length.
    v
        Event values at ``t`` (from the previous step, or at ``t0``).
    t, y, tnew, ynew
        The accepted step.
    t0
        The initial time of the integration.

    Returns
    -------
    tuple
        ``(te, ye, ie, vnew, stop)``: lists of event times, states and 0-based indices in the
        order found, the event values at ``tnew`` (for the next step) and whether a terminal
        event stops the integration.
    """
    tol = event_tolerance(t, tnew)
    tdir = 1.0 if tnew > t else -1.0
    te: list[float] = []
    ye: list[np.ndarray] = []
    ie: list[int] = []
    stop = False

    vnew, isterminal, direction = events(tnew, ynew)
    tL, yL, vL = t, y, v
    if t == t0 and np.any(v == 0):
        # MATLAB ignores a zero at the initial point: search from just off it
        tL = just_off(t, tol, tdir)
        yL = interpolate(tL)
        vL = events(tL, yL)[0]
    search_start = tL
    tR, yR, vR = tnew, ynew, vnew
    # ttry/vtry remember the last point tried, for extrapolation when an end value is zero.
    ttry, vtry = tR, vR

    while True:
        lastmoved = 0
        while True:
            found = _bracketed(vL, vR, direction)
            if found.size == 0:
                if lastmoved != 0:
                    raise RuntimeError("odelab: an event disappeared during location (internal error)")
                return te, ye, ie, vnew, stop
            delta = tR - tL
            if abs(delta) <= tol:
                break
            if tL == t and np.any((vL[found] == 0) & (vR[found] != 0)):
                # A zero at the step's left end: step just off it to see where the value goes.
                ttry = just_off(tL, tol, tdir)
            else:
                change = 1.0
                for j in found:
                    change = min(change, root_fraction(vL[j], vR[j], vtry[j], tL, tR, ttry, delta, tdir))
                ttry = next_try(change, tL, delta, tol, tdir)

            ytry = interpolate(ttry)
            vtry = events(ttry, ytry)[0]
            if _bracketed(vL, vtry, direction).size:
                # A crossing in [tL, ttry]: move the right end left, keep the old one as "try".
                tR, ttry = ttry, tR
                yR, ytry = ytry, yR
                vR, vtry = vtry, vR
                if lastmoved == 2:  # Illinois: the left end stayed twice, halve its value
                    vL = np.array([halved(x) for x in vL.tolist()])
                lastmoved = 2
            else:
                tL, ttry = ttry, tL
                yL, ytry = ytry, yL
                vL, vtry = vtry, vL
                if lastmoved == 1:
                    vR = np.array([halved(x) for x in vR.tolist()])
                lastmoved = 1

        for j in found:
            te.append(tR)
            ye.append(yR)
            ie.append(int(j))
        if np.any(isterminal[found]):
            if stops(t, t0, tL, search_start):
                stop = True
            break
        if abs(tnew - tR) <= tol:
            break  # no later event can be told apart from this one
        # Look for later events of the same step in [tR + tol/2, tnew].
        ttry, ytry, vtry = tR, yR, vR
        tL = just_off(tR, tol, tdir)
        yL = interpolate(tL)
        vL = events(tL, yL)[0]
        tR, yR, vR = tnew, ynew, vnew
    return te, ye, ie, vnew, stop


# --- the user's events function ---------------------------------------------------------------


def _as_flags(raw, name: str, k: int, what: str) -> np.ndarray:
    arr = np.asarray(raw, dtype=float).ravel()
    if arr.size == 1 and k > 1:
        arr = np.full(k, float(arr[0]))
    if arr.size != k:
        raise InputError(
            f"the events function returned {k} value{'s' if k != 1 else ''} but {arr.size} {what}: "
            f"return (value, isterminal, direction) with one entry per event each.",
            key=name,
        )
    return arr


_PLAIN = (int, float, bool)


def _plain_list(x) -> bool:
    return type(x) is list and all(type(v) in _PLAIN for v in x)


def _same_list(x: list, plain: list) -> bool:
    """``x == plain`` for a list of plain numbers ``plain``, False where the comparison fails."""
    try:
        return bool(x == plain)
    except (TypeError, ValueError):  # e.g. an array inside the list: converted afresh
        return False


def as_event_function(events, args: tuple, t0: float, y0: np.ndarray, name: str = "events"):
    """Check the user's events and return ``(events(t, y) -> (value, isterminal, direction), v0)``.

    Accepts MATLAB's form, one function returning ``(value, isterminal, direction)``, and SciPy's
    ``solve_ivp`` form, a function or list of functions each returning one value, with optional
    attributes ``terminal`` (bool; SciPy's integer counts are not supported) and ``direction``.
    """
    scipy_form = isinstance(events, Sequence) and not isinstance(events, str)
    if scipy_form:
        funcs = list(events)
        if not funcs or not all(callable(f) for f in funcs):
            raise InputError(f"`{name}` must be a function ev(t, y) returning (value, isterminal, direction), "
                             f"or a list of functions (SciPy's form); got {events!r}.", key=name)
    elif not callable(events):
        raise InputError(f"`{name}` must be a function ev(t, y) returning (value, isterminal, direction); "
                         f"got {events!r}.", key=name)
    elif hasattr(events, "terminal") or hasattr(events, "direction"):
        funcs, scipy_form = [events], True

    if scipy_form:
        terminal = []
        for f in funcs:
            flag = getattr(f, "terminal", False)
            if not isinstance(flag, (bool, np.bool_)):
                raise InputError(
                    f"the `terminal` attribute of event {getattr(f, '__name__', f)!r} is {flag!r}; odelab "
                    "takes True/False (stop at the first such event), not SciPy's count of occurrences.",
                    key=name)
            terminal.append(bool(flag))
        isterminal = np.array(terminal)
        direction = np.array([float(np.sign(getattr(f, "direction", 0.0))) for f in funcs])

        def values(t, y):
            return np.array([float(f(t, y, *args)) for f in funcs])

        def raw(t, y):
            return values(t, y), isterminal, direction
    else:
        def raw(t, y):
            return events(t, y, *args)

    try:
        first = raw(t0, y0.copy())
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"the events function raised {type(exc).__name__}: {exc} at t = {t0:g} "
                         "(the first call).", key=name) from None
    if not (isinstance(first, tuple) and len(first) == 3):
        raise InputError(f"the events function must return three arrays (value, isterminal, direction), "
                         f"as MATLAB's does; it returned {first!r}.", key=name)
    value = np.asarray(first[0])
    if np.iscomplexobj(value) or not np.issubdtype(value.dtype, np.number):
        raise InputError(f"the events function's values must be real numbers; got {first[0]!r}.", key=name)
    k = value.size
    isterminal = _as_flags(first[1], name, k, "isterminal flags") != 0
    direction = np.sign(_as_flags(first[2], name, k, "directions"))

    # MATLAB reads isterminal and direction from every call, so they may change in time; a call
    # that returns lists of plain numbers equal to the previous call's reuses their conversion
    # (the common case, constant flags; this runs after every step).
    last = [None, None, None, None]  # the previous plain lists, and their arrays

    def ev(t, y):
        try:
            out = raw(t, y)
            if scipy_form:
                return out[0], isterminal, direction
            value = np.asarray(out[0], dtype=float).reshape(k)
            flags, dirs = out[1], out[2]
            if not (last[0] is not None and type(flags) is list and type(dirs) is list
                    and _same_list(flags, last[0]) and _same_list(dirs, last[1])):
                last[2] = _as_flags(flags, name, k, "isterminal flags") != 0
                last[3] = np.sign(_as_flags(dirs, name, k, "directions"))
                last[2].setflags(write=False)
                last[3].setflags(write=False)
                plain = _plain_list(flags) and _plain_list(dirs)
                last[0], last[1] = (flags[:], dirs[:]) if plain else (None, None)
            return value, last[2], last[3]
        except Exception as exc:
            raise CallbackError("events function", t, exc) from exc

    return ev, np.asarray(value, dtype=float).reshape(k)
