"""``dde23``: delay differential equations with constant lags, MATLAB's method.

Solves ``y'(t) = f(t, y(t), y(t - tau_1), ..., y(t - tau_k))`` for constant lags
``tau_j > 0`` on ``[t0, tf]``, with the history ``y(t) = S(t)`` for ``t <= t0``, the way
MATLAB's ``dde23`` does (L. F. Shampine and S. Thompson, *Solving DDEs in MATLAB*, Appl.
Numer. Math. 37, 2001, 441-458):

* **The Bogacki-Shampine 3(2) pair** of ``ode23`` with its cubic Hermite interpolant (the
  pair's own continuous extension: the end values and slopes of each step determine it), the
  same error norm (weighted by the larger of ``|y|`` and ``|ynew|``, ``AbsTol/RelTol`` below)
  and the same step-size rules as :func:`odelab.ode23`, with ``RelTol = 1e-3`` and
  ``AbsTol = 1e-6``.
* **The method of steps**: a delayed value ``y(t - tau)`` in a stage is the history before
  ``t0``, and afterwards the Hermite interpolant of the mesh already computed.
* **Discontinuity tracking**: the slope of the solution jumps at ``t0`` (the history's slope
  is not ``f``); the jump propagates to ``t0 + tau_i`` (in ``y''``), ``t0 + tau_i + tau_j``
  (``y'''``) and ``t0 + tau_i + tau_j + tau_k``, beyond which a third-order method does not
  see it. The solver steps exactly onto every such point up to ``tf`` (one level more with
  ``InitialY`` or ``Jumps``, whose jumps are in the solution itself). A step that would end
  just short of one is stretched onto it; one that would end within two steps of it is
  halved, so that no step ends a sliver short.
* **Short lags**: a step longer than the shortest lag needs ``y(t - tau)`` inside the step
  itself. The first pass takes it from the previous step's Hermite cubic extrapolated; each
  further pass uses the cubic of the tentative step ``(t, y, f) -> (tnew, ynew, fnew)``,
  until two passes agree to ``0.1 * RelTol`` (at most 5 passes; otherwise the step is
  halved, and never below the shortest lag). A step between one and two shortest lags is
  cut to that lag (it would need the iteration for little gain). The first step is at most
  half the shortest lag, so that it is explicit and the interpolant has a first piece.
* **Events** ``ev(t, y, Z) -> (value, isterminal, direction)`` are located on each step's
  Hermite cubic as :func:`odelab.ode23` locates them (MATLAB's ``odezero``); a terminal event
  ends the mesh at the event, with the slope of the cubic there.

The result is a :class:`DDESolution`: the mesh ``t`` (MATLAB's ``sol.x``), the states ``y``
and slopes ``yp`` there, and :meth:`~odelab.solution.Solution.deval` (MATLAB's
``deval(sol, t)``) on the same Hermite cubics. A solution can be the history of a new call,
which continues it (MATLAB's ``dde23(ddefun, lags, sol, [sol.x(end), tf])``).

Limits: constant lags only (MATLAB's ``ddesd`` handles state-dependent ones), no neutral
equations (``y'`` delayed; MATLAB's ``ddensd``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.exceptions import InputError, SolverWarning
from odelab.solution import Solution, Stats
from odelab.solvers.dense import query_times
from odelab.solvers.events import CallbackError, as_event_function, locate_events

__all__ = ["dde23", "DDESolution", "HermiteMesh", "discontinuities"]

# Bogacki-Shampine 3(2): nodes, the propagated third-order weights and the error weights
# (the same numbers as odelab's ode23 tableau; Shampine & Reichelt 1997).
_C2, _C3 = 0.5, 0.75
_A21 = 0.5
_A32 = 0.75
_B = (2.0 / 9.0, 1.0 / 3.0, 4.0 / 9.0)
_E = np.array([-5.0 / 72.0, 1.0 / 12.0, 1.0 / 9.0, -1.0 / 8.0])
_POW = 1.0 / 3.0
_MAXIT = 5  # passes of the short-lag iteration


def _hermite(tq, ta: float, ya: np.ndarray, fa: np.ndarray, tb: float, yb: np.ndarray, fb: np.ndarray,
             derivative: bool = False):
    """The cubic with values ``ya, yb`` and slopes ``fa, fb`` at ``ta, tb``, at the times ``tq``.

    ``tq`` a float gives shape (n,); an array (k,) gives (k, n). Outside ``[ta, tb]`` the cubic is
    extrapolated (the short-lag iteration's first pass needs that).
    """
    h = tb - ta
    s = (np.asarray(tq, dtype=float) - ta) / h
    delta = yb - ya
    c2 = 3.0 * delta - h * (2.0 * fa + fb)  # coefficient of s^2 (times 1)
    c3 = h * (fa + fb) - 2.0 * delta  # coefficient of s^3
    hfa = h * fa
    if np.ndim(s) == 0:
        value = ya + s * (hfa + s * (c2 + s * c3))
        if derivative:
            return value, fa + s * (2.0 * c2 + 3.0 * s * c3) / h
        return value
    s = s[:, None]
    value = ya + s * (hfa + s * (c2 + s * c3))
    if derivative:
        return value, fa + s * (2.0 * c2 + 3.0 * s * c3) / h
    return value


@dataclass(frozen=True, eq=False)
class HermiteMesh:
    """The piecewise cubic Hermite interpolant of a mesh (``t``, ``y``, ``yp``): dde23's ``deval``.

    ``t`` (N,) increasing, ``y`` and ``yp`` (N, n). Piece i covers ``[t_i, t_(i+1)]``; a time on
    a mesh point gives that point's stored value exactly.
    """

    t: np.ndarray
    y: np.ndarray
    yp: np.ndarray

    @property
    def t_start(self) -> float:
        return float(self.t[0])

    @property
    def t_end(self) -> float:
        return float(self.t[-1])

    def __call__(self, tq, derivative: bool = False):
        times, scalar = query_times(tq, self.t_start, self.t_end)
        n = self.y.shape[1]
        values = np.empty((times.size, n))
        slopes = np.empty((times.size, n))
        if self.t.size == 1:
            values[:] = self.y[0]
            slopes[:] = self.yp[0]
        else:
            i = np.clip(np.searchsorted(self.t, times, side="right") - 1, 0, self.t.size - 2)
            ta, tb = self.t[i], self.t[i + 1]
            h = (tb - ta)[:, None]
            s = ((times - ta) / (tb - ta))[:, None]
            ya, yb, fa, fb = self.y[i], self.y[i + 1], self.yp[i], self.yp[i + 1]
            delta = yb - ya
            c2 = 3.0 * delta - h * (2.0 * fa + fb)
            c3 = h * (fa + fb) - 2.0 * delta
            values = ya + s * (h * fa + s * (c2 + s * c3))
            slopes = fa + s * (2.0 * c2 + 3.0 * s * c3) / h
            exact = np.searchsorted(self.t, times, side="left")
            on_mesh = (exact < self.t.size) & (self.t[np.minimum(exact, self.t.size - 1)] == times)
            values[on_mesh] = self.y[exact[on_mesh]]
            slopes[on_mesh] = self.yp[exact[on_mesh]]
        if derivative:
            return (values[0], slopes[0]) if scalar else (values, slopes)
        return values[0] if scalar else values


@dataclass(frozen=True)
class DDESolution(Solution):
    """The result of :func:`dde23`: a :class:`~odelab.solution.Solution` on the solver's mesh.

    Extra attributes (MATLAB's ``sol`` fields): ``yp`` the slopes at the mesh points (N, n),
    ``lags`` the lags, ``history`` the history this integration started from (kept when the
    solution continues a previous one), and ``discont`` the points of low smoothness that
    were tracked (from ``t0`` and ``Jumps``; ``tf`` is not among them unless it is one).
    """

    yp: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    lags: np.ndarray = field(default_factory=lambda: np.empty(0))
    history: Any = field(default=None, repr=False)
    discont: np.ndarray = field(default_factory=lambda: np.empty(0))


def _purged(points: np.ndarray) -> np.ndarray:
    """Sorted points with near-duplicates (within 10 spacings of doubles) dropped."""
    points = np.sort(points)
    if points.size > 1:
        spacing = 10.0 * np.spacing(np.abs(points[:-1]))
        keep = np.concatenate([[True], np.abs(np.diff(points)) > spacing])
        points = points[keep]
    return points


#: Propagated points beyond this many are refused (lags tiny against the span: thousands of
#: lags' sums would be tracked; MATLAB's message points to ddesd).
_MAX_DISCONT = 200_000


def _propagated(t0: float, tf: float, lags, levels: int, seeds) -> np.ndarray:
    """``t0`` and ``seeds`` plus their sums with up to ``levels`` lags, inside ``(t0, tf]``, sorted,
    near-duplicates (10 spacings of doubles) merged."""
    lags = np.sort(np.asarray(lags, dtype=float).ravel())
    level = np.unique(np.concatenate([[t0], np.asarray(seeds, dtype=float).ravel()]))
    found = [level]
    for _ in range(levels):
        if lags.size == 0:
            break
        nxt = (level[:, None] + lags[None, :]).ravel()
        nxt = nxt[nxt <= tf]
        if nxt.size == 0:
            break
        level = _purged(nxt)
        if level.size > _MAX_DISCONT:
            raise InputError(
                f"the lags {lags.tolist()} are too short for the span [{t0:g}, {tf:g}]: more than "
                f"{_MAX_DISCONT:,} points of low smoothness would be tracked. Shorten the span or lengthen the lags.",
                key="lags")
        found.append(level)
    points = _purged(np.concatenate(found))
    return points[points > t0]


def discontinuities(t0: float, tf: float, lags, levels: int = 3, seeds=()) -> np.ndarray:
    """The points of ``(t0, tf]`` onto which dde23 steps: ``t0`` and ``seeds`` plus sums of up to
    ``levels`` lags, duplicates (to 10 spacings of doubles) merged, ``tf`` last.

    ``levels`` is 3 for a history whose value at ``t0`` is the solution's (the slope jumps there:
    y'' jumps at ``t0 + tau``, y''' at ``t0 + 2 tau``, y'''' at ``t0 + 3 tau``), and 4 with
    ``InitialY`` or ``Jumps`` (the solution itself jumps).
    """
    points = _propagated(t0, tf, lags, levels, seeds)
    if points.size and abs(tf - points[-1]) <= 10.0 * math.ulp(tf):
        points[-1] = tf
    else:
        points = np.append(points, tf)
    return points


_OPTION_NAMES = {
    "reltol": "rtol", "rtol": "rtol",
    "abstol": "atol", "atol": "atol",
    "maxstep": "max_step", "max_step": "max_step",
    "initialstep": "initial_step", "initial_step": "initial_step",
    "events": "events",
    "normcontrol": "norm_control", "norm_control": "norm_control",
    "initialy": "initial_y", "initial_y": "initial_y",
    "jumps": "jumps",
    "max_steps": "max_steps", "maxsteps": "max_steps",
}


def _normalize(options: dict) -> dict:
    out = {}
    for key, value in options.items():
        name = _OPTION_NAMES.get(str(key).lower().replace("-", "_"))
        if name is None:
            import difflib

            valid = sorted({"RelTol", "AbsTol", "MaxStep", "InitialStep", "Events", "NormControl", "InitialY",
                            "Jumps", "max_steps"})
            close = difflib.get_close_matches(str(key), valid, n=1, cutoff=0.5)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise InputError(f"dde23 has no option {key!r}.{hint} Its options are {', '.join(valid)} "
                             "(or rtol, atol, max_step, initial_step, events, norm_control, initial_y, jumps).",
                             key=str(key))
        if name in out:
            raise InputError(f"the option {name} is given twice (as {key!r} and another spelling); give it once.",
                             key=str(key))
        if isinstance(value, str) and name == "norm_control":
            value = value.lower() == "on"
        out[name] = value
    return out


def _positive(name: str, value, size: int | None = None) -> np.ndarray:
    arr = np.asarray(value, dtype=float).ravel()
    if arr.size == 0 or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise InputError(f"`{name}` must be positive; got {value!r}.", key=name)
    if size is not None and arr.size not in (1, size):
        raise InputError(f"`{name}` must be a scalar or have one entry per state ({size}); got {arr.size}.", key=name)
    return arr


class _History:
    """``y(t)`` for ``t < t0``: a constant, a function of t, or a previous :class:`DDESolution`."""

    def __init__(self, history, n: int | None):
        self.given = history  # what the solution keeps as its history
        self.constant = None
        self.function = None
        self.previous = None
        if isinstance(history, DDESolution):
            self.previous = history
            self.given = history.history
            inner = history.history
            self.before = _History(inner, history.y.shape[1]) if inner is not None else None
            self.start = float(history.t[0])
        elif callable(history):
            self.function = history
        else:
            arr = np.asarray(history)
            if np.iscomplexobj(arr) or not np.issubdtype(arr.dtype, np.number) or arr.dtype == bool:
                raise InputError("`history` must be a constant vector, a function history(t) returning one, or a "
                                 f"previous dde23 solution; got {history!r}.", key="history")
            self.constant = np.atleast_1d(arr.astype(float)).ravel()

    def __call__(self, tq: float) -> np.ndarray:
        if self.constant is not None:
            return self.constant
        if self.previous is not None:
            if tq < self.start:
                return self.before(tq)
            return self.previous.interpolant(tq)
        try:
            value = self.function(tq)
        except Exception as exc:
            raise CallbackError("history function", tq, exc) from exc
        return np.atleast_1d(np.asarray(value, dtype=float)).ravel()


class _Mesh:
    """The growing mesh (t, y, yp) the delayed values are interpolated from, with room for a
    tentative step at its end."""

    def __init__(self, t0: float, y0: np.ndarray, f0: np.ndarray):
        n = y0.size
        self.cap = 256
        self.t = np.empty(self.cap)
        self.y = np.empty((self.cap, n))
        self.yp = np.empty((self.cap, n))
        self.t[0], self.y[0], self.yp[0] = t0, y0, f0
        self.size = 1  # accepted points
        self.tentative = False  # whether row `size` holds a tentative step end

    def _room(self) -> None:
        if self.size + 1 >= self.cap:
            self.cap *= 2
            for name in ("t", "y", "yp"):
                arr = getattr(self, name)
                grown = np.empty((self.cap,) + arr.shape[1:])
                grown[: arr.shape[0]] = arr
                setattr(self, name, grown)

    def propose(self, t: float, y: np.ndarray, f: np.ndarray) -> None:
        self._room()
        k = self.size
        self.t[k], self.y[k], self.yp[k] = t, y, f
        self.tentative = True

    def discard(self) -> None:
        self.tentative = False

    def accept(self, t: float, y: np.ndarray, f: np.ndarray) -> None:
        self._room()
        k = self.size
        self.t[k], self.y[k], self.yp[k] = t, y, f
        self.size += 1
        self.tentative = False

    def value(self, tq: float) -> np.ndarray:
        """The solution at ``tq >= t[0]`` from the mesh: the Hermite piece that covers it, the last
        piece extrapolated beyond the end (the tentative step counts when there is one)."""
        m = self.size + (1 if self.tentative else 0)
        if m < 2:  # not reached: the first step is at most half the shortest lag
            return self.y[0].copy()
        t = self.t
        # piece n with t[n] <= tq, n <= m - 2 (MATLAB's lagvals)
        n = int(np.searchsorted(t[: m - 1], tq, side="right")) - 1
        n = min(max(n, 0), m - 2)
        return _hermite(tq, t[n], self.y[n], self.yp[n], t[n + 1], self.y[n + 1], self.yp[n + 1])


def dde23(ddefun, lags, history, tspan, options=None, **kwargs) -> DDESolution:
    """Solve delay differential equations with constant lags (MATLAB's ``dde23``).

    Parameters
    ----------
    ddefun : callable
        ``ddefun(t, y, Z)`` returning dy/dt (n,), with ``y`` the state at ``t`` (n,) and ``Z``
        the delayed states, shape (n, k): ``Z[:, j]`` is ``y(t - lags[j])``.
    lags : float or sequence of float
        The constant lags, all positive (their order is the order of ``Z``'s columns).
    history : array-like, callable or DDESolution
        The solution for ``t <= t0``: a constant vector, a function ``history(t)`` returning
        one, or the solution of a previous call ending at ``t0`` (which this one continues;
        the result then covers both).
    tspan : sequence of float
        ``[t0, tf]`` with ``t0 < tf`` (as MATLAB, only the first and last entries are used;
        evaluate the solution anywhere with ``sol.deval(t)``).
    options : dict, optional
        MATLAB's ``ddeset`` names: ``RelTol`` (1e-3), ``AbsTol`` (1e-6, scalar or per state),
        ``MaxStep`` (0.1 of the span), ``InitialStep``, ``Events``
        (``ev(t, y, Z) -> (value, isterminal, direction)``), ``NormControl``, ``InitialY``
        (``y(t0)`` when it differs from the history's value there), ``Jumps`` (times of known
        discontinuities of the history or of ``ddefun``). The same can be given as keywords,
        also in lower case (``rtol``, ``atol``, ``max_step``, ``initial_step``, ``events``,
        ``norm_control``, ``initial_y``, ``jumps``); ``max_steps`` stops after that many steps.

    Returns
    -------
    DDESolution
        ``t`` the mesh (MATLAB's ``sol.x``), ``y`` (N, n), ``yp`` (N, n), ``stats``, ``te``,
        ``ye``, ``ie`` (events), ``deval``. A failed integration returns the mesh so far with
        ``status == "failed"`` and a :class:`~odelab.exceptions.SolverWarning`.

    Examples
    --------
    >>> import odelab
    >>> sol = odelab.dde23(lambda t, y, Z: -Z[:, 0], [1.0], [1.0], [0, 5])
    >>> bool(abs(sol.deval(1.0)[0]) < 1e-12)  # y = 1 - t on [0, 1]: t = 1 is a mesh point
    True
    """
    opts = _normalize({**(dict(options) if options else {}), **kwargs})
    if not callable(ddefun):
        raise InputError(f"`ddefun` must be a function ddefun(t, y, Z); got {ddefun!r}.", key="ddefun")
    lags_arr = np.atleast_1d(np.asarray(lags, dtype=float)).ravel() if np.size(lags) else np.empty(0)
    if lags_arr.size and (not np.all(np.isfinite(lags_arr)) or np.any(lags_arr <= 0)):
        raise InputError(f"the lags must be positive constants; got {np.asarray(lags).tolist()!r}. "
                         "A lag of 0 is the current state y itself.", key="lags")
    span = np.asarray(tspan, dtype=float).ravel()
    if span.size < 2 or not np.all(np.isfinite(span)):
        raise InputError(f"`tspan` must be [t0, tf]; got {tspan!r}.", key="tspan")
    t0, tf = float(span[0]), float(span[-1])
    if not tf > t0:
        raise InputError(f"dde23 integrates forward in time: tspan = [{t0:g}, {tf:g}] needs tf > t0.", key="tspan")

    hist = _History(history, None)
    if hist.previous is not None and float(hist.previous.t[-1]) != t0:
        raise InputError(f"a previous solution continues from where it ends (t = {float(hist.previous.t[-1]):g}); "
                         f"tspan starts at {t0:g}.", key="tspan")
    y0 = np.array(hist.previous.y[-1] if hist.previous is not None else hist(t0), dtype=float)
    levels = 3
    if opts.get("initial_y") is not None:
        y0 = np.atleast_1d(np.asarray(opts["initial_y"], dtype=float)).ravel().copy()
        levels = 4
    n = y0.size
    if hist.constant is not None and hist.constant.size != n:
        raise InputError(f"the history has {hist.constant.size} entries but InitialY has {n}.", key="history")

    # points of low smoothness
    seeds: list[float] = []
    old_discont = np.empty(0)
    if lags_arr.size:
        maxlag = float(lags_arr.max())
        if hist.previous is not None:
            prev = np.asarray(hist.previous.discont, dtype=float)
            old_discont = prev[prev < t0 - maxlag]
            seeds += prev[prev >= t0 - maxlag].tolist()
        jumps = np.atleast_1d(np.asarray(opts.get("jumps", []), dtype=float)).ravel()
        jumps = jumps[(jumps >= t0 - maxlag) & (jumps <= tf)]
        if jumps.size:
            seeds += jumps.tolist()
            levels = 4
        tracked = discontinuities(t0, tf, lags_arr, levels, seeds)
        start_points = _purged(np.concatenate([[t0], seeds]))
        new_discont = np.concatenate([start_points, _propagated(t0, tf, lags_arr, levels, seeds)])
        minlag = float(lags_arr.min())
    else:
        tracked = np.array([tf])
        new_discont = np.array([t0])
        minlag = math.inf
    discont = tracked  # (t0, tf], tf last

    rtol = float(_positive("RelTol", opts.get("rtol", 1e-3))[0])
    warns: list[str] = []
    if rtol < 100 * np.finfo(float).eps:
        rtol = 100 * float(np.finfo(float).eps)
        warns.append(f"RelTol raised to {rtol:g}, MATLAB's smallest.")
    atol = _positive("AbsTol", opts.get("atol", 1e-6), n)
    norm_control = bool(opts.get("norm_control", False))
    if norm_control and atol.size != 1:
        raise InputError("with NormControl on, AbsTol must be a scalar.", key="AbsTol")
    threshold = atol / rtol
    tlen = tf - t0
    hmax = min(tlen, float(_positive("MaxStep", opts["max_step"])[0])) if opts.get("max_step") is not None \
        else 0.1 * tlen
    htry = float(_positive("InitialStep", opts["initial_step"])[0]) if opts.get("initial_step") is not None else None
    max_steps = opts.get("max_steps")

    def delayed(tnow: float, mesh: _Mesh) -> np.ndarray:
        Z = np.empty((n, lags_arr.size))
        first = mesh.t[0]
        for j, lag in enumerate(lags_arr):
            tq = tnow - lag
            if tq < first:
                value = hist(tq)
                if value.size != n:
                    raise InputError(f"the history returned {value.size} values at t = {tq:g}; the system has "
                                     f"{n} states.", key="history")
                Z[:, j] = value
            else:
                Z[:, j] = mesh.value(tq)
        return Z

    nfevals = 0

    def evaluate(t: float, y: np.ndarray, Z: np.ndarray) -> np.ndarray:
        nonlocal nfevals
        nfevals += 1
        out = np.asarray(ddefun(t, y.copy(), Z), dtype=float).ravel()
        if out.size != n:
            raise InputError(f"ddefun returned {out.size} values at t = {t:g}; the system has {n} states "
                             "(the history's length).", key="ddefun")
        return out

    Z0 = delayed(t0, _Mesh(t0, y0, np.zeros(n))) if lags_arr.size else np.empty((n, 0))
    f0 = evaluate(t0, y0, Z0)
    mesh = _Mesh(t0, y0, f0)

    events = opts.get("events")
    ev = None
    if events is not None:
        if not callable(events):
            raise InputError(f"`Events` must be a function ev(t, y, Z) returning (value, isterminal, direction); "
                             f"got {events!r}.", key="Events")

        def events_now(t, y):
            return events(t, y, delayed(t, mesh) if lags_arr.size else np.empty((n, 0)))

        ev, valt = as_event_function(events_now, (), t0, y0.copy(), name="Events")
    te_out: list[float] = []
    ye_out: list[np.ndarray] = []
    ie_out: list[int] = []

    def norm_of(v):
        return float(np.linalg.norm(v))

    # initial step (ode23's rule, then at most half the shortest lag: the first step is explicit)
    hmin = 16.0 * math.ulp(t0)
    if htry is None:
        h = min(hmax, tf - t0)
        if norm_control:
            rh = (norm_of(f0) / max(norm_of(y0), float(threshold[0]))) / (0.8 * rtol ** _POW)
        else:
            rh = float(np.max(np.abs(f0) / np.maximum(np.abs(y0), threshold))) / (0.8 * rtol ** _POW)
        if h * rh > 1:
            h = 1.0 / rh
        h = max(h, hmin)
    else:
        h = min(hmax, max(hmin, htry))
    h = min(h, 0.5 * minlag)

    t, y, f1 = t0, y0, f0
    normy = norm_of(y0) if norm_control else 0.0
    nsteps = nfailed = 0
    nextdsc = 0
    status, message = "success", "The solver reached the end of the time span."
    done = False
    try:
        while not done:
            hmin = 16.0 * math.ulp(t)
            h = min(hmax, max(hmin, h))
            hitdsc = False
            distance = discont[nextdsc] - t
            if min(1.1 * h, hmax) >= distance:  # stretch onto the next point of low smoothness
                h = distance
                hitdsc = True
            elif 2.0 * h >= distance:  # two equal steps onto it rather than one and a sliver
                h = 0.5 * distance
            if not hitdsc and minlag < h < 2.0 * minlag:
                h = minlag

            nofailed = True
            while True:
                tnew = discont[nextdsc] if hitdsc else t + h
                h = tnew - t
                t1, t2 = t + _C2 * h, t + _C3 * h
                maxit = _MAXIT if minlag < h else 1
                mesh.discard()
                itfail = False
                last_y = None
                for it in range(maxit):
                    Z = delayed(t1, mesh) if lags_arr.size else Z0
                    f2 = evaluate(t1, y + (h * _A21) * f1, Z)
                    Z = delayed(t2, mesh) if lags_arr.size else Z0
                    f3 = evaluate(t2, y + (h * _A32) * f2, Z)
                    ynew = y + h * (_B[0] * f1 + _B[1] * f2 + _B[2] * f3)
                    Z = delayed(tnew, mesh) if lags_arr.size else Z0
                    f4 = evaluate(tnew, ynew, Z)
                    if maxit > 1:
                        if it > 0:
                            if norm_control:
                                errit = norm_of(ynew - last_y) / max(normy, norm_of(ynew), float(threshold[0]))
                            else:
                                errit = float(np.max(np.abs(ynew - last_y)
                                                     / np.maximum(np.maximum(np.abs(y), np.abs(ynew)), threshold)))
                            if errit <= 0.1 * rtol:
                                break
                        # the next pass interpolates the delayed values on this tentative step
                        mesh.propose(tnew, ynew, f4)
                        last_y = ynew
                        itfail = it == maxit - 1
                if not (np.all(np.isfinite(ynew)) and np.all(np.isfinite(f4))):
                    status = "failed"
                    message = (f"The solution or its derivative became NaN or infinite at t = {tnew:g}: check the "
                               "equations (a division by zero, a blow-up) near there.")
                    done = True
                    break
                if itfail:
                    nfailed += 1
                    if h <= hmin:
                        status, message = _tolerance_failure(t, hmin)
                        done = True
                        break
                    h = 0.5 * h
                    if h < 2.0 * minlag:
                        h = minlag
                    hitdsc = False
                    continue
                fE = _E[0] * f1 + _E[1] * f2 + _E[2] * f3 + _E[3] * f4
                if norm_control:
                    normynew = norm_of(ynew)
                    err = h * (norm_of(fE) / max(normy, normynew, float(threshold[0])))
                else:
                    err = h * float(np.max(np.abs(fE) / np.maximum(np.maximum(np.abs(y), np.abs(ynew)), threshold)))
                if err > rtol:
                    nfailed += 1
                    if h <= hmin:
                        status, message = _tolerance_failure(t, hmin)
                        done = True
                        break
                    if nofailed:
                        nofailed = False
                        h = max(hmin, h * max(0.5, 0.8 * (rtol / err) ** _POW))
                    else:
                        h = max(hmin, 0.5 * h)
                    hitdsc = False
                    continue
                break
            if done:
                break
            nsteps += 1
            mesh.discard()

            if ev is not None:
                # delayed values inside the step come from the step's own cubic
                mesh.propose(tnew, ynew, f4)
                ta, ya, fa = t, y, f1

                def interpolate(tq, ta=ta, ya=ya, fa=fa, tb=tnew, yb=ynew, fb=f4):
                    return _hermite(tq, ta, ya, fa, tb, yb, fb)

                te, ye, ie, valt, stop = locate_events(interpolate, ev, valt, t, y, tnew, ynew, t0)
                mesh.discard()
                if te:
                    te_out += te
                    ye_out += ye
                    ie_out += ie
                    if stop:
                        _, f4 = _hermite(te[-1], t, y, f1, tnew, ynew, f4, derivative=True)
                        tnew, ynew = te[-1], np.array(ye[-1], dtype=float)
                        status, message = "success", f"A terminal event stopped the integration at t = {tnew:g}."
                        done = True

            mesh.accept(tnew, ynew, f4)
            if not done and hitdsc:
                nextdsc += 1
                done = nextdsc >= discont.size
            if not done and max_steps is not None and nsteps >= int(max_steps):
                status = "failed"
                message = f"Stopped after max_steps = {int(max_steps)} steps, at t = {tnew:g}."
                done = True
            if not done:
                t, y, f1 = tnew, ynew, f4
                if norm_control:
                    normy = normynew
                if nofailed and not itfail:
                    temp = 1.25 * (err / rtol) ** _POW
                    h = h / temp if temp > 0.2 else 5.0 * h
                    h = min(max(hmin, h), hmax)
    except CallbackError as exc:
        raise InputError(f"the {exc.what} raised {type(exc.original).__name__}: {exc.original} at t = {exc.t:g}.",
                         key="Events" if exc.what.startswith("events") else "history") from None

    m = mesh.size
    t_arr, y_arr, yp_arr = mesh.t[:m].copy(), mesh.y[:m].copy(), mesh.yp[:m].copy()
    te_arr = np.array(te_out, dtype=float)
    ye_arr = np.array(ye_out, dtype=float).reshape(-1, n)
    ie_arr = np.array(ie_out, dtype=int)
    stats = Stats(nsteps=nsteps, nfailed=nfailed, nfevals=nfevals)
    discont_all = np.concatenate([old_discont, new_discont])
    if hist.previous is not None:  # the result continues the previous solution (MATLAB merges them)
        p = hist.previous
        t_arr = np.concatenate([p.t, t_arr[1:]])
        y_arr = np.concatenate([p.y, y_arr[1:]])
        yp_arr = np.concatenate([p.yp, yp_arr[1:]])
        te_arr = np.concatenate([p.te, te_arr])
        ye_arr = np.concatenate([p.ye.reshape(-1, n), ye_arr])
        ie_arr = np.concatenate([p.ie, ie_arr])
        stats = Stats(nsteps=p.stats.nsteps + nsteps, nfailed=p.stats.nfailed + nfailed,
                      nfevals=p.stats.nfevals + nfevals)
    if status == "failed":
        warnings.warn(message, SolverWarning, stacklevel=2)
    return DDESolution(
        t=t_arr, y=y_arr, stats=stats, status=status, message=message, method="dde23", warnings=tuple(warns),
        te=te_arr, ye=ye_arr, ie=ie_arr, interpolant=HermiteMesh(t_arr, y_arr, yp_arr),
        setup=None, yp=yp_arr, lags=lags_arr, history=hist.given, discont=discont_all,
    )


def _tolerance_failure(t: float, hmin: float) -> tuple[str, str]:
    return "failed", (f"Unable to meet integration tolerances without reducing the step size below the smallest "
                      f"value allowed ({hmin:e}) at time t = {t:e} (MATLAB's dde23 stops there too). Loosen "
                      "RelTol/AbsTol, or check the equations for a singularity near that time.")


def solve_delay(fun, tspan, y0, options: dict) -> DDESolution:
    """``odelab.solve(fun, tspan, y0, method="dde23", ...)``.

    ``fun`` is a delay system (an object with ``ddefun(t, y, Z)``, ``lags`` and ``history(y0)``,
    such as :class:`odelab.systems.delay.DelayEquations`) or a plain ``f(t, y)``, solved as a
    delay equation without lags. ``options`` are :func:`odelab.solve`'s canonical names. A
    history whose value at ``t0`` differs from ``y0`` makes ``y0`` MATLAB's ``InitialY``.
    With a ``tspan`` of more than two times the result holds the solution at those times
    (interpolated on the Hermite cubics) and the statistics of the whole mesh.
    """
    import dataclasses

    tspan = np.asarray(tspan, dtype=float)
    y0 = np.atleast_1d(np.asarray(y0, dtype=float)).ravel()
    opts = {k: v for k, v in options.items() if v is not None}
    args = tuple(opts.pop("args", None) or ())
    events = opts.pop("events", None)
    if hasattr(fun, "ddefun") and hasattr(fun, "lags"):
        ddefun, lags = fun.ddefun, fun.lags
        history = fun.history(y0) if callable(getattr(fun, "history", None)) else y0
    else:
        def ddefun(t, y, Z, _f=fun):
            return _f(t, y, *args)

        lags, history = [], y0
    if callable(history):
        start = np.asarray(history(float(tspan[0])), dtype=float).ravel()
        if start.shape != y0.shape or np.any(start != y0):
            opts["initial_y"] = y0
    elif np.any(np.asarray(history, dtype=float).ravel() != y0):
        opts["initial_y"] = y0
    if callable(getattr(fun, "jumps", None)):  # known discontinuities (a diagram's sources, a delay's start)
        opts["jumps"] = fun.jumps(float(tspan[0]), float(tspan[-1]))
    if events is not None:
        ev, _ = as_event_function(events, args, float(tspan[0]), y0.copy())
        opts["events"] = lambda t, y, Z: ev(t, y)
    sol = dde23(ddefun, lags, history, [tspan[0], tspan[-1]], opts)
    if callable(getattr(fun, "remember", None)):  # a system whose outputs need the solution's past
        fun.remember(sol)
    if tspan.size > 2:
        end = float(sol.t[-1])
        times = tspan[tspan <= end]
        if times[-1] != end:
            times = np.append(times, end)
        sol = dataclasses.replace(sol, t=times, y=sol.deval(times).reshape(times.size, -1))
    return sol
