"""``dde23``: delay differential equations with constant lags, MATLAB's method.

Solves ``y'(t) = f(t, y(t), y(t - tau_1), ..., y(t - tau_k))`` for constant lags
``tau_j > 0`` on ``[t0, tf]``, with the history ``y(t) = S(t)`` for ``t <= t0``, the way
MATLAB's ``dde23`` does (L. F. Shampine and S. Thompson, *Solving DDEs in MATLAB*, Appl.
Numer. Math. 37, 2001, 441-458):

* **The Bogacki-Shampine 3(2) pair** of ``ode23`` with its cubic Hermite interpolant (the
  pair's own continuous extension: the end values and slopes of each step determine it), the
  same error norm (weighted by the larger of ``|y|`` and ``|ynew|``, ``AbsTol/RelTol`` below)
  and the same step-size rules as :func:`odelab.ode23` (:mod:`odelab.solvers.controller`'s
  ``min_step``, ``first_step``, ``clamp_step``, ``shrink`` and ``grow``), with ``RelTol = 1e-3``
  and ``AbsTol = 1e-6``.
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

import dataclasses
import difflib
import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.exceptions import InputError, SolverWarning
from odelab.solution import Solution, Stats
from odelab.solvers.controller import clamp_step, first_step, given_step, grow, shrink
from odelab.solvers.dense import query_times
from odelab.solvers.events import CallbackError, as_event_function, locate_events
from odelab.solvers.optionset import DEFAULT_ATOL, DEFAULT_RTOL, canonical
from odelab.solvers.options import SolverOptions, as_tspan, as_y0, given_options, normalize_options

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


# dde23's options: odeset's (spelled as the option registry accepts them, optionset.canonical) and ddeset's own
# two, InitialY (the solution's jump at t0) and Jumps (known discontinuities).
_ODESET_OPTIONS = ("rtol", "atol", "max_step", "initial_step", "events", "norm_control", "max_steps")
_DDESET_OPTIONS = {"initialy": "initial_y", "jumps": "jumps"}


def _normalize(options: dict) -> dict:
    out = {}
    for key, value in options.items():
        spelled = str(key).lower().replace("-", "_")
        name = _DDESET_OPTIONS.get(spelled.replace("_", ""))
        if name is None:
            name = canonical(spelled)
            name = name if name in _ODESET_OPTIONS else None
        if name is None:
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
    run = _Run(ddefun, _setup(lags, history, tspan, opts))
    try:
        run.integrate()
    except CallbackError as exc:
        raise InputError(f"the {exc.what} raised {type(exc.original).__name__}: {exc.original} at t = {exc.t:g}.",
                         key="Events" if exc.what.startswith("events") else "history") from None
    return run.solution()


@dataclass(eq=False)
class _Setup:
    """A dde23 problem as checked: the span, the initial state, the lags and history, the points
    of low smoothness, the tolerances and step limits."""

    t0: float
    tf: float
    y0: np.ndarray
    lags: np.ndarray
    hist: _History
    discont: np.ndarray  # the points of (t0, tf] stepped onto, tf last
    old_discont: np.ndarray  # a continued solution's points before t0 - maxlag
    new_discont: np.ndarray  # the points of this integration (t0, seeds, propagated)
    minlag: float
    rtol: float
    threshold: np.ndarray
    norm_control: bool
    hmax: float
    htry: float | None
    max_steps: Any
    events: Any
    warns: list


def _setup(lags, history, tspan, opts: dict) -> _Setup:
    """Check dde23's arguments and options; track the points of low smoothness."""
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

    rtol = float(_positive("RelTol", opts.get("rtol", DEFAULT_RTOL))[0])
    warns: list[str] = []
    if rtol < 100 * np.finfo(float).eps:
        rtol = 100 * float(np.finfo(float).eps)
        warns.append(f"RelTol raised to {rtol:g}, MATLAB's smallest.")
    atol = _positive("AbsTol", opts.get("atol", DEFAULT_ATOL), n)
    norm_control = bool(opts.get("norm_control", False))
    if norm_control and atol.size != 1:
        raise InputError("with NormControl on, AbsTol must be a scalar.", key="AbsTol")
    tlen = tf - t0
    hmax = min(tlen, float(_positive("MaxStep", opts["max_step"])[0])) if opts.get("max_step") is not None \
        else 0.1 * tlen
    htry = float(_positive("InitialStep", opts["initial_step"])[0]) if opts.get("initial_step") is not None else None
    events = opts.get("events")
    if events is not None and not callable(events):
        raise InputError(f"`Events` must be a function ev(t, y, Z) returning (value, isterminal, direction); "
                         f"got {events!r}.", key="Events")
    return _Setup(t0, tf, y0, lags_arr, hist, tracked, old_discont, new_discont, minlag, rtol, atol / rtol,
                  norm_control, hmax, htry, opts.get("max_steps"), events, warns)


def _norm(v) -> float:
    return float(np.linalg.norm(v))


class _Run:
    """One dde23 integration: the method of steps on the growing Hermite mesh, with MATLAB's
    ode23 step rules (:mod:`odelab.solvers.controller`) and dde23's own (onto the points of low
    smoothness; the short-lag iteration)."""

    def __init__(self, ddefun, setup: _Setup):
        self.ddefun, self.s = ddefun, setup
        self.n = n = setup.y0.size
        self.nfevals = self.nsteps = self.nfailed = 0
        self.status, self.message = "success", "The solver reached the end of the time span."
        self.Z0 = self.delayed(setup.t0, _Mesh(setup.t0, setup.y0, np.zeros(n))) if setup.lags.size \
            else np.empty((n, 0))
        self.f0 = self.evaluate(setup.t0, setup.y0, self.Z0)
        self.mesh = _Mesh(setup.t0, setup.y0, self.f0)
        self.ev = self.valt = None
        self.te: list[float] = []
        self.ye: list[np.ndarray] = []
        self.ie: list[int] = []
        if setup.events is not None:
            user = setup.events

            def events_now(t, y):
                return user(t, y, self.delayed(t, self.mesh) if setup.lags.size else np.empty((n, 0)))

            self.ev, self.valt = as_event_function(events_now, (), setup.t0, setup.y0.copy(), name="Events")

    def delayed(self, tnow: float, mesh: _Mesh) -> np.ndarray:
        """``Z``: the state at ``tnow - lag_j`` for each lag, from the history or the mesh."""
        n, hist = self.n, self.s.hist
        Z = np.empty((n, self.s.lags.size))
        first = mesh.t[0]
        for j, lag in enumerate(self.s.lags):
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

    def evaluate(self, t: float, y: np.ndarray, Z: np.ndarray) -> np.ndarray:
        self.nfevals += 1
        out = np.asarray(self.ddefun(t, y.copy(), Z), dtype=float).ravel()
        if out.size != self.n:
            raise InputError(f"ddefun returned {out.size} values at t = {t:g}; the system has {self.n} states "
                             "(the history's length).", key="ddefun")
        return out

    def first_step(self) -> float:
        """ode23's initial step, then at most half the shortest lag (the first step is explicit)."""
        s, f0, y0 = self.s, self.f0, self.s.y0
        if s.htry is not None:
            return min(given_step(s.htry, s.t0, s.hmax), 0.5 * s.minlag)
        if s.norm_control:
            rh = (_norm(f0) / max(_norm(y0), float(s.threshold[0]))) / (0.8 * s.rtol ** _POW)
        else:
            rh = float(np.max(np.abs(f0) / np.maximum(np.abs(y0), s.threshold))) / (0.8 * s.rtol ** _POW)
        return min(first_step(rh, s.tf - s.t0, s.hmax, s.t0), 0.5 * s.minlag)

    def step_size(self, t: float, h: float, target: float):
        """``(hmin, h, hitdsc)`` at the top of a step: ``h`` within ``[hmin, hmax]``, stretched onto
        the next point of low smoothness ``target`` (tf the last) when within 10 % of it and of
        MaxStep (MATLAB's dde23: ``min(1.1 h, hmax) >= distance``), halved when two equal steps
        reach it rather than one and a sliver; a step between one and two shortest lags is cut to
        the lag."""
        s = self.s
        distance = target - t
        hmin, h, hitdsc = clamp_step(t, target if distance <= s.hmax else math.inf, h, s.hmax)
        if hitdsc:
            return hmin, distance, True
        if 2.0 * h >= distance:  # two equal steps onto it rather than one and a sliver
            h = 0.5 * distance
        if s.minlag < h < 2.0 * s.minlag:
            h = s.minlag
        return hmin, h, False

    def stages(self, t, y, f1, h, tnew):
        """The Bogacki-Shampine stages of the step ``t -> tnew``, with the short-lag iteration
        when ``h`` exceeds the shortest lag: ``(ynew, f2, f3, f4, itfail)``."""
        s, mesh = self.s, self.mesh
        lagged = s.lags.size > 0
        t1, t2 = t + _C2 * h, t + _C3 * h
        maxit = _MAXIT if s.minlag < h else 1
        mesh.discard()
        itfail = False
        last_y = None
        for it in range(maxit):
            f2 = self.evaluate(t1, y + (h * _A21) * f1, self.delayed(t1, mesh) if lagged else self.Z0)
            f3 = self.evaluate(t2, y + (h * _A32) * f2, self.delayed(t2, mesh) if lagged else self.Z0)
            ynew = y + h * (_B[0] * f1 + _B[1] * f2 + _B[2] * f3)
            f4 = self.evaluate(tnew, ynew, self.delayed(tnew, mesh) if lagged else self.Z0)
            if maxit > 1:
                if it > 0 and self.scaled(ynew - last_y, y, ynew) <= 0.1 * s.rtol:
                    break
                # the next pass interpolates the delayed values on this tentative step
                mesh.propose(tnew, ynew, f4)
                last_y = ynew
                itfail = it == maxit - 1
        return ynew, f2, f3, f4, itfail

    def scaled(self, v, y, ynew) -> float:
        """``v`` in the error norm: weighted by ``max(|y|, |ynew|, atol/rtol)``, or relative to
        ``max(||y||, ||ynew||, atol/rtol)`` with NormControl."""
        s = self.s
        if s.norm_control:
            return _norm(v) / max(_norm(y), _norm(ynew), float(s.threshold[0]))
        return float(np.max(np.abs(v) / np.maximum(np.maximum(np.abs(y), np.abs(ynew)), s.threshold)))

    def stop_with(self, status: str, message: str) -> None:
        self.status, self.message = status, message

    def attempt_step(self, t, y, f1, h, hmin, hitdsc, nextdsc):
        """Attempts from ``(t, y)`` until one is accepted: ``(tnew, ynew, f4, h, err, smooth)``
        (``smooth``: accepted at the first attempt, so the step may grow), or None when the
        integration failed (``self.status``)."""
        s = self.s
        nofailed = True
        while True:
            tnew = s.discont[nextdsc] if hitdsc else t + h
            h = tnew - t
            ynew, f2, f3, f4, itfail = self.stages(t, y, f1, h, tnew)
            if not (np.all(np.isfinite(ynew)) and np.all(np.isfinite(f4))):
                self.stop_with("failed", f"The solution or its derivative became NaN or infinite at t = {tnew:g}: check "
                                    "the equations (a division by zero, a blow-up) near there.")
                return None
            if itfail:
                self.nfailed += 1
                if h <= hmin:
                    self.stop_with(*_tolerance_failure(t, hmin))
                    return None
                h = 0.5 * h
                if h < 2.0 * s.minlag:
                    h = s.minlag
                hitdsc = False
                continue
            err = h * self.scaled(_E[0] * f1 + _E[1] * f2 + _E[2] * f3 + _E[3] * f4, y, ynew)
            if err <= s.rtol:
                return tnew, ynew, f4, h, err, nofailed, hitdsc
            self.nfailed += 1
            if h <= hmin:
                self.stop_with(*_tolerance_failure(t, hmin))
                return None
            h = shrink(h, hmin, err, s.rtol, _POW, 0.5, 0.8, nofailed)
            nofailed = False
            hitdsc = False

    def locate(self, t, y, f1, tnew, ynew, f4):
        """The events of the accepted step on its own cubic; ``(te, ye, slope)`` of a terminal one."""
        mesh = self.mesh
        mesh.propose(tnew, ynew, f4)  # delayed values inside the step come from the step's own cubic

        def interpolate(tq):
            return _hermite(tq, t, y, f1, tnew, ynew, f4)

        te, ye, ie, self.valt, stop = locate_events(interpolate, self.ev, self.valt, t, y, tnew, ynew, self.s.t0)
        mesh.discard()
        self.te += te
        self.ye += ye
        self.ie += ie
        if not stop:
            return None
        _, slope = _hermite(te[-1], t, y, f1, tnew, ynew, f4, derivative=True)
        return te[-1], np.array(ye[-1], dtype=float), slope

    def integrate(self) -> None:
        s = self.s
        t, y, f1 = s.t0, s.y0, self.f0
        h = self.first_step()
        nextdsc = 0
        while True:
            hmin, h, hitdsc = self.step_size(t, h, s.discont[nextdsc])
            accepted = self.attempt_step(t, y, f1, h, hmin, hitdsc, nextdsc)
            if accepted is None:
                return
            tnew, ynew, f4, h, err, smooth, hitdsc = accepted
            self.nsteps += 1
            self.mesh.discard()
            done = False
            if self.ev is not None:
                cut = self.locate(t, y, f1, tnew, ynew, f4)
                if cut is not None:
                    tnew, ynew, f4 = cut
                    self.stop_with("success", f"A terminal event stopped the integration at t = {tnew:g}.")
                    done = True
            self.mesh.accept(tnew, ynew, f4)
            if not done and hitdsc:
                nextdsc += 1
                done = nextdsc >= s.discont.size
            if not done and s.max_steps is not None and self.nsteps >= int(s.max_steps):
                self.stop_with("failed", f"Stopped after max_steps = {int(s.max_steps)} steps, at t = {tnew:g}.")
                done = True
            if done:
                return
            t, y, f1 = tnew, ynew, f4
            if smooth:
                h = min(max(hmin, grow(h, err, s.rtol, _POW, 1.25, 5.0)), s.hmax)

    def solution(self) -> DDESolution:
        """The mesh as a :class:`DDESolution` (continuing a previous solution: both merged)."""
        s, mesh, n = self.s, self.mesh, self.n
        m = mesh.size
        t_arr, y_arr, yp_arr = mesh.t[:m].copy(), mesh.y[:m].copy(), mesh.yp[:m].copy()
        te_arr = np.array(self.te, dtype=float)
        ye_arr = np.array(self.ye, dtype=float).reshape(-1, n)
        ie_arr = np.array(self.ie, dtype=int)
        stats = Stats(nsteps=self.nsteps, nfailed=self.nfailed, nfevals=self.nfevals)
        discont_all = np.concatenate([s.old_discont, s.new_discont])
        if s.hist.previous is not None:  # the result continues the previous solution (MATLAB merges them)
            p = s.hist.previous
            t_arr = np.concatenate([p.t, t_arr[1:]])
            y_arr = np.concatenate([p.y, y_arr[1:]])
            yp_arr = np.concatenate([p.yp, yp_arr[1:]])
            te_arr = np.concatenate([p.te, te_arr])
            ye_arr = np.concatenate([p.ye.reshape(-1, n), ye_arr])
            ie_arr = np.concatenate([p.ie, ie_arr])
            stats = Stats(nsteps=p.stats.nsteps + self.nsteps, nfailed=p.stats.nfailed + self.nfailed,
                          nfevals=p.stats.nfevals + self.nfevals)
        if self.status == "failed":
            warnings.warn(self.message, SolverWarning, stacklevel=3)
        return DDESolution(
            t=t_arr, y=y_arr, stats=stats, status=self.status, message=self.message, method="dde23",
            warnings=tuple(s.warns), te=te_arr, ye=ye_arr, ie=ie_arr, interpolant=HermiteMesh(t_arr, y_arr, yp_arr),
            setup=None, yp=yp_arr, lags=s.lags, history=s.hist.given, discont=discont_all,
        )


def _tolerance_failure(t: float, hmin: float) -> tuple[str, str]:
    return "failed", (f"Unable to meet integration tolerances without reducing the step size below the smallest "
                      f"value allowed ({hmin:e}) at time t = {t:e} (MATLAB's dde23 stops there too). Loosen "
                      "RelTol/AbsTol, or check the equations for a singularity near that time.")


def drive_delay(fun, tspan, y0, m, options) -> DDESolution:
    """The driver of the methods of kind ``"delay"`` (:data:`odelab.solvers.registry.DRIVERS`): the arrays
    checked and the options normalised once (a resolved :class:`~odelab.solvers.options.SolverOptions`' as they
    were given), then :func:`solve_delay`, which evaluates the delayed states."""
    tspan_arr, y0_arr = as_tspan(tspan), as_y0(y0)
    if isinstance(options, SolverOptions) and options.method == m.name:  # normalised for it at load
        return solve_delay(fun, tspan_arr, y0_arr, given_options(options))
    return solve_delay(fun, tspan_arr, y0_arr, normalize_options(given_options(options), m))


def solve_delay(fun, tspan, y0, options: dict) -> DDESolution:
    """``odelab.solve(fun, tspan, y0, method="dde23", ...)``.

    ``fun`` is a delay system (an object with ``ddefun(t, y, Z)``, ``lags`` and ``history(y0)``,
    such as :class:`odelab.systems.delay.DelayEquations`) or a plain ``f(t, y)``, solved as a
    delay equation without lags. ``options`` are :func:`odelab.solve`'s canonical names. A
    history whose value at ``t0`` differs from ``y0`` makes ``y0`` MATLAB's ``InitialY``.
    With a ``tspan`` of more than two times the result holds the solution at those times
    (interpolated on the Hermite cubics) and the statistics of the whole mesh.
    """
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
