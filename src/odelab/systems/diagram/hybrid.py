"""The hybrid driver of diagrams: zero crossings and sample hits (Simulink's simulation loop).

A diagram with switching blocks (:mod:`~odelab.systems.diagram.zerocross`) or discrete blocks
(:mod:`~odelab.systems.diagram.discrete`) is integrated piece by piece:

- the pieces end at the sources' breakpoints (as :func:`odelab.systems.simulate.simulate`
  does) and at every sample hit of a discrete block (:mod:`~odelab.systems.diagram.schedule`),
  so the continuous solver stops exactly there;
- at a hit the discrete blocks hit then compute their outputs in evaluation order (each seeing
  the new outputs upstream), then update their states; their outputs are held until their next
  hit (they are states of the diagram with zero derivative, changed only at hits);
- inside a piece every switching block's mode is held and the switching functions that can
  leave it are the piece's events, located on the solver's interpolant; the piece ends at the
  first one and the run restarts there with the modes chosen afresh.

The rows at a restart appear twice in a run with the solver's own output points (before and
after the jump), so a sampled signal or a relay's output is drawn as steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from odelab.exceptions import InputError
from odelab.solution import Stats
from odelab.solvers.registry import DEFAULT_METHOD, get_method
from odelab.systems.simulate import Response, piece_window, whole_span_max_step

__all__ = ["HybridResponse", "simulate_hybrid", "needs_hybrid"]


@dataclass(frozen=True, eq=False)
class HybridResponse(Response):
    """A :class:`~odelab.systems.simulate.Response` with what the hybrid driver saw:
    ``crossings`` (block -> the times its located switches happened), ``hits`` (the sample
    instants) and ``notes`` (what the run should say: crossings per block, fallbacks)."""

    crossings: dict = field(default_factory=dict)
    hits: tuple = ()
    notes: tuple = ()
    te: np.ndarray = field(default_factory=lambda: np.empty(0))  # the user's events (``events``), as solve's
    ye: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    ie: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=int))


def needs_hybrid(diagram, zero_crossing: bool = True) -> bool:
    """Whether a compiled diagram needs this driver (switching blocks with detection on, a
    relay, or discrete blocks)."""
    blocks = diagram.wiring.blocks.values()
    return any(b.DISCRETE or b.STATEFUL_MODE or getattr(b, "STOPS", False) or (zero_crossing and b.zero_crossing)
               for b in blocks)


def _locates(method: str) -> bool:
    m = get_method(method)
    return m.events and not m.delays  # it locates zero crossings (ODE methods with Events)


def simulate_hybrid(diagram, tspan, x0=None, *, method: str = DEFAULT_METHOD, zero_crossing: bool = True,
                    events=None, **options) -> HybridResponse:
    """Integrate a compiled diagram with its switching and discrete blocks (see the module).

    ``tspan`` is ``[t0, tf]`` (the solver's own points, restarts shown twice) or output times.
    ``zero_crossing = False`` turns location off for every block. ``events`` is a MATLAB-form
    events function of (t, x), ``(value, isterminal, direction)`` (an [events] section's): its
    events are located with the blocks' and returned as ``te, ye, ie``, a terminal one ends the
    run there. A failure (a solver failure, a chattering switch) returns what was computed with
    ``status == "failed"``.
    """
    run = _HybridRun(diagram, tspan, x0, method, zero_crossing, events, options)
    try:
        run.integrate()
    except _Stop:
        pass
    finally:
        run.sw.release()
        diagram.slope_window = (-math.inf, math.inf)
    return run.response()


def _checked_tspan(tspan) -> np.ndarray:
    """``[t0, tf]`` or output times (a time listed twice asks for the rows before and after a jump)."""
    from odelab.solvers.options import as_tspan

    tspan = np.asarray(tspan, dtype=float)
    if tspan.size > 2:
        as_tspan(np.unique(tspan) if tspan[-1] > tspan[0] else np.unique(tspan)[::-1])
        step = np.sign(tspan[-1] - tspan[0]) * np.diff(tspan)
        if np.any(step < 0):
            as_tspan(tspan)  # its message: entries must increase
        return tspan
    return as_tspan(tspan)


def _inputs_at(signals, lo: float, hi: float):
    """u(t) with the sources read at t clamped to [lo, hi] (a piece reads its sources inside it)."""
    if not signals:
        empty = np.zeros(0)
        return lambda t: empty

    def u(t):
        tu = min(max(t, lo), hi)
        return np.array([s(tu) for s in signals])

    return u


class _HybridRun:
    """One run of :func:`simulate_hybrid`: the pieces between the sources' breakpoints and the
    sample hits, the stretches between located switches inside each piece, and the rows, counts
    and events they produce."""

    def __init__(self, diagram, tspan, x0, method, zero_crossing, events, options):
        from odelab.systems.diagram.schedule import hits as sample_hits
        from odelab.systems.diagram.zerocross import Switching

        tspan = _checked_tspan(tspan)
        self.diagram, self.method, self.events = diagram, method, events
        self.t0, self.tf = t0, tf = float(tspan[0]), float(tspan[-1])
        self.forward = forward = tf >= t0
        self.blocks = blocks = diagram.wiring.blocks
        self.signals = list(diagram.signals)
        self.x = np.array(diagram.x0 if x0 is None else x0, dtype=float).reshape(-1)
        self.notes: list[str] = []

        locate = zero_crossing and _locates(method)
        self.sw = sw = Switching(diagram, enabled=locate)
        if zero_crossing and not locate and any(blocks[n].zero_crossing for n in sw.blocks):
            self.notes.append(f"{method} locates no events: zero crossings are stepped over (use ode45, ode23, "
                              "ode15s...)")
        if sw.stepped and not _locates(method):
            raise InputError(f"the relay `{sw.stepped[0]}` switches at the end of a step, which {method} does not "
                             "report; use ode45, ode23, ode113 or a stiff solver.", key="solver.method")

        self.rates = {n: b.sample for n, b in blocks.items() if b.DISCRETE}
        self.hit_times, hit_who = sample_hits(self.rates, t0, tf)
        cuts = np.unique(np.concatenate([np.empty(0), *(s.breakpoints(t0, tf) for s in self.signals)]))
        self.cuts = cuts[(cuts > min(t0, tf)) & (cuts < max(t0, tf))]
        self.hit_map = {float(t): w for t, w in zip(self.hit_times, hit_who)}
        edges = sorted(set(self.cuts.tolist()) | {t for t in self.hit_map if min(t0, tf) < t < max(t0, tf)},
                       reverse=not forward)
        self.edges = [t0, *edges, tf]
        self.options = whole_span_max_step(options, method, t0, tf, cut=len(self.edges) > 2)

        self.dense = tspan.size == 2
        self.user = tspan
        self.user_te: list[float] = []
        self.user_ye: list[np.ndarray] = []
        self.user_ie: list[int] = []
        self.finished = False  # a terminal user event (or a stop block) ended the run
        self.stops = [n for n, b in blocks.items() if getattr(b, "STOPS", False)]
        self.stopped_by = ""
        self.rows_t: list[np.ndarray] = []
        self.rows_x: list[np.ndarray] = []
        self.nsteps = self.nfevals = 0
        self.nfailed = 0
        self.status, self.message, self.method_name = "success", "", method
        self.warns: list[str] = []
        self.consecutive = 0
        self.sol = None

    # --- small helpers ------------------------------------------------------------------------

    def add(self, t, xs) -> None:
        self.rows_t.append(np.atleast_1d(np.asarray(t, dtype=float)))
        self.rows_x.append(np.asarray(xs, dtype=float).reshape(-1, self.x.size))

    def fail(self, message: str):
        self.status, self.message = "failed", message
        raise _Stop

    def look(self, t, end):
        """How far ahead a switching function's departure from a zero at ``t`` is read: a
        relative sqrt(eps) of the span, inside the piece that ends at ``end``."""
        dt = _SQRT_EPS * max(abs(self.tf - self.t0), abs(t))
        if end != t:
            dt = min(dt, 0.5 * abs(end - t))
        return dt if self.forward else -dt

    def ahead(self, t, u, end):
        """The ``after`` rule of Switching.choose: the modes the functions move into from t."""
        return lambda xx: self.sw.ahead(t, xx, u, self.look(t, end))

    def settle(self, t, xs, u, end):
        """The modes at a piece's start once every switching function exactly zero there has
        left in the direction it goes (the solver ignores a zero at its initial point, as
        MATLAB does: the driver takes those crossings itself, counted like located ones)."""
        sw = self.sw
        if not sw.located:
            return xs
        from odelab.systems.diagram.zerocross import MAX_CONSECUTIVE

        dt = self.look(t, end)
        while True:
            hit, after = sw.departing(t, xs, u, dt)
            if not hit:
                return xs
            sw.record(t, hit)
            self.consecutive += 1
            if self.consecutive >= MAX_CONSECUTIVE:
                self.fail(_chatter_message(self.consecutive, hit[0], t))
            xs = sw.choose(t, xs, u(t), after=after)

    # --- the run ------------------------------------------------------------------------------

    def integrate(self) -> None:
        """Every piece in turn; the hit at t0 first (discrete outputs from their initial states
        and the inputs at t0), and a function zero at t0 takes the sign it moves into
        (Simulink's initialisation)."""
        t0, sw = self.t0, self.sw
        u_first = _inputs_at(self.signals, -math.inf, math.inf)
        if t0 in self.hit_map:
            self.x = _discrete_hit(self.diagram, t0, self.x, u_first(t0), self.hit_map[t0])
        if sw:
            self.x = sw.choose(t0, self.x, u_first(t0), after=self.ahead(t0, u_first, self.edges[1]))
        for i in range(len(self.edges) - 1):
            if self.piece(i):
                break
        self.message = self.message or self.sol.message

    def piece(self, i: int) -> bool:
        """The piece from edges[i] to edges[i + 1]; True when a terminal user event ended the run."""
        edges, sw, forward, dense, user = self.edges, self.sw, self.forward, self.dense, self.user
        a, b = edges[i], edges[i + 1]
        last = i == len(edges) - 2
        lo, hi = min(a, b), max(a, b)
        u_lo, u_hi = piece_window(edges, i)
        u = _inputs_at(self.signals, u_lo, u_hi)
        self.diagram.slope_window = (u_lo, u_hi)
        if i > 0 and sw:
            self.x = sw.choose(a, self.x, u(a), after=self.ahead(a, u, b))
        if sw:
            self.x = self.settle(a, self.x, u, b)
        if dense:
            grid_user = np.empty(0)
        else:
            grid_user = np.unique(user[(user > lo) & (user < hi)])
            if not forward:
                grid_user = grid_user[::-1]
        if dense or np.any(user == a):
            self.add(a, self.x)  # in a run with the solver's points, the row after the jump at a
        start = a
        while start is not None:
            start = self.stretch(start, b, u, grid_user)
        if self.finished:
            return True
        hits = self.hit_map.get(b)
        if hits is not None and not last:
            self.x = _discrete_hit(self.diagram, b, self.x, _inputs_at(self.signals, b, math.inf if forward else b)(b),
                                   hits)
        elif hits is not None:
            x_after = _discrete_hit(self.diagram, b, self.x, u(b), hits)
            if dense or np.any(user == b):
                self.add(b, x_after)
            self.x = x_after
        self.consecutive = 0
        return False

    def stretch(self, start, b, u, grid_user):
        """Solve from ``start`` towards the piece's end ``b`` with the modes held; the time the
        next stretch starts from (a located switch, a stepped relay), or None when the piece is done."""
        from odelab.solvers.api import solve

        sw, x, forward = self.sw, self.x, self.forward
        before = sw.raw(start, x, u(start), sw.located) if sw.located else None
        zc = sw.event_function(u) if sw.located else None  # (it sets sw.owners)
        n_zc = len(sw.owners) if sw.located else 0
        ev = _combined(zc, n_zc, self.events)
        opts = dict(self.options)
        if ev is not None:
            opts["events"] = ev
        if sw.stepped:
            opts["output_fcn"] = _stop_when_changed(sw.stepped_check(u), start, x)
        if self.stops:
            opts["output_fcn"] = _stop_block_watch(self.stop_check(u), opts.get("output_fcn"), x.size)
        rest = grid_user[(grid_user > start) if forward else (grid_user < start)]
        grid = np.concatenate([[start], rest, [b]])

        def rhs(t, xx, _u=u):
            return self.diagram._dynamics(t, xx, _u(t))

        self.sol = sol = solve(rhs, grid, x, method=self.method, **opts)
        self.nsteps += sol.stats.nsteps
        self.nfevals += sol.stats.nfevals
        self.nfailed = None if self.nfailed is None or sol.stats.nfailed is None else self.nfailed + sol.stats.nfailed
        self.method_name = sol.method or self.method
        self.warns.extend(w for w in sol.warnings if w not in self.warns)
        keep = (sol.t > start) if forward else (sol.t < start)
        if sol.status != "success":
            self.add(sol.t[keep], sol.y[keep])
            self.fail(sol.message)
        te = np.asarray(sol.te, dtype=float)
        ie_all = np.asarray(sol.ie, dtype=int)
        if self.user_events(sol, te, ie_all, n_zc, keep):
            return None
        zc_rows = [k for k in range(ie_all.size) if ie_all[k] < n_zc]
        if zc_rows:  # the first located switch ends the stretch (terminal or not)
            return self.switched(sol, zc_rows, ie_all, keep, start, b, u, before)
        t_end = float(sol.t[-1])
        if self.stops and self.stop_check(u)(t_end, sol.y[-1]):
            return self.stopped(sol, keep, t_end, u)
        if t_end != b:  # a stepped relay stopped the solver at a step's end
            return self.relay_stopped(sol, keep, t_end, b, u)
        at_b = keep & (sol.t == b)
        self.add(sol.t[keep & ~at_b], sol.y[keep & ~at_b])
        self.x = np.asarray(sol.y[-1], dtype=float)
        self.x = sw.sync(b, self.x, u(b)) if sw else self.x
        if self.dense or np.any(self.user == b):
            self.add(b, self.x)  # the row before the jump at b (or the last row)
        return None

    def user_events(self, sol, te, ie_all, n_zc, keep) -> bool:
        """Record the user's events up to the end of this stretch; True when a terminal one
        ended the run (its rows added, the state there kept)."""
        events = self.events
        user_terminal = [bool(np.asarray(events(float(tj), yj)[1]).reshape(-1)[j - n_zc])
                         if j >= n_zc else True for tj, yj, j in zip(te, sol.ye, ie_all)] if te.size else []
        first = next((k for k in range(te.size) if ie_all[k] < n_zc or user_terminal[k]), None)
        for k in range(te.size):
            if ie_all[k] >= n_zc and (first is None or te[k] <= te[first]):
                self.user_te.append(float(te[k]))
                self.user_ye.append(np.asarray(sol.ye[k], dtype=float))
                self.user_ie.append(int(ie_all[k] - n_zc))
        if first is None or ie_all[first] < n_zc:
            return False
        t_stop = float(te[first])
        inner = keep & ((sol.t < t_stop) if self.forward else (sol.t > t_stop))
        self.add(sol.t[inner], sol.y[inner])
        self.add(t_stop, sol.ye[first])
        self.x = np.asarray(sol.ye[first], dtype=float)
        self.message = sol.message
        self.finished = True
        return True

    def switched(self, sol, zc_rows, ie_all, keep, start, b, u, before):
        """A located switch at the first zero-crossing event: the rows up to it, the modes chosen
        afresh there; the time the next stretch starts from (None if it is the piece's end)."""
        from odelab.systems.diagram.zerocross import MAX_CONSECUTIVE

        sw = self.sw
        t_sw = float(sol.te[zc_rows[0]])
        y_sw = np.asarray(sol.ye[zc_rows[0]], dtype=float)
        inner = keep & ((sol.t < t_sw) if self.forward else (sol.t > t_sw))
        self.add(sol.t[inner], sol.y[inner])
        self.add(t_sw, y_sw)
        fired = [sw.owners[ie_all[k]] for k in zc_rows if float(sol.te[k]) == t_sw]
        sw.record(t_sw, fired)
        tol = 128 * max(math.ulp(t_sw), math.ulp(start))
        self.consecutive = self.consecutive + 1 if abs(t_sw - start) <= 10 * tol else 0
        if self.consecutive >= MAX_CONSECUTIVE:
            self.fail(_chatter_message(self.consecutive, fired[0], t_sw))
        x = sw.choose(t_sw, sw.sync(t_sw, y_sw, u(t_sw), fired), u(t_sw), before)
        self.x = self.settle(t_sw, x, u, b)
        if self.dense or (t_sw == b and np.any(self.user == b)):
            self.add(t_sw, self.x)
        return None if t_sw == b else t_sw

    def stop_check(self, u):
        """Whether a stop block's input is nonzero at (t, x): the run ends there (Simulink's Stop Simulation)."""
        diagram = self.diagram

        def check(t, x):
            x = np.asarray(x, dtype=float).reshape(-1)
            vals = diagram._ports(float(t), x, u(float(t)), False)
            for n in self.stops:
                if self.blocks[n].stopped([vals[p] for p in diagram.wiring.sources[n]]):
                    self.stopped_by = n
                    return True
            return False

        return check

    def stopped(self, sol, keep, t_end, u):
        """A stop block's input became nonzero in the step that ended at ``t_end``: the run ends there."""
        self.add(sol.t[keep], sol.y[keep])
        self.x = np.asarray(sol.y[-1], dtype=float)
        self.message = (f"stopped at t = {t_end:.10g} by the stop block `{self.stopped_by}` (its input became nonzero "
                        "in the step that ended there, as Simulink's Stop Simulation block)")
        self.finished = True
        return None

    def relay_stopped(self, sol, keep, t_end, b, u):
        """A stepped relay's output_fcn stopped the solver at a step's end: switch it there."""
        sw, diagram = self.sw, self.diagram
        self.add(sol.t[keep], sol.y[keep])
        y_end = np.asarray(sol.y[-1], dtype=float)
        x_before = y_end.copy()
        x = sw.choose(t_end, sw.sync(t_end, y_end, u(t_end)), u(t_end), after=self.ahead(t_end, u, b))
        self.x = self.settle(t_end, x, u, b)
        sw.record(t_end, [n for n in sw.stepped if not np.array_equal(
            self.x[diagram.slices[n]], x_before[diagram.slices[n]])])
        if self.dense:
            self.add(t_end, self.x)
        return t_end

    # --- the result ---------------------------------------------------------------------------

    def response(self) -> HybridResponse:
        diagram, blocks, signals, sw, x = self.diagram, self.blocks, self.signals, self.sw, self.x
        t = np.concatenate(self.rows_t) if self.rows_t else np.array([self.t0])
        X = np.concatenate(self.rows_x).reshape(t.size, x.size) if self.rows_x else x.reshape(1, -1)
        if not self.dense:
            t, X = _at_user_times(t, X, self.user, self.status == "success")
        notes, message = self.notes, self.message
        counts = {n: len(v) for n, v in sw.times.items()}
        if counts:  # a block that never crossed is said in words: a bare "0" reads as a fault
            crossed = {n: c for n, c in counts.items() if c}
            still = [f"{n} ({blocks[n].TYPE})" for n, c in counts.items() if not c]
            parts = [", ".join(f"{n} ({blocks[n].TYPE}) {c}" for n, c in crossed.items())] if crossed else []
            if still:
                parts.append(", ".join(still) + " never changed mode (no zero crossing)")
            notes.append(("zero crossings located: " if crossed else "") + "; ".join(parts))
        if self.hit_times.size:
            rates_txt = ", ".join(f"{n} every {blocks[n].sample}" for n in self.rates)
            notes.append(f"sample hits: {self.hit_times.size} ({rates_txt})")
        if self.status == "success" and not self.finished and notes:
            message = (message.split(" Integrated in")[0] + " " + "; ".join(notes) + ".").strip()
        U = np.zeros((t.size, len(signals)))
        for j, s in enumerate(signals):
            U[:, j] = s(t)
        # a breakpoint listed twice: the row before the jump reads the sources before it (their left
        # limits), so an input, and an output that feeds it through, is drawn as the step it is
        cuts = self.cuts
        twice = np.flatnonzero((t[:-1] == t[1:]) & np.isin(t[:-1], cuts)) if t.size > 1 and cuts.size else []
        for i in twice:
            before = float(np.nextafter(t[i], -math.inf if self.forward else math.inf))
            U[i] = [s(before) for s in signals]
        Y = diagram.output_many(t, X, U) if diagram.outputs else np.zeros((t.size, 0))
        for arr in (t, X, U, Y):
            arr.setflags(write=False)
        n_user = len(self.user_te)
        return HybridResponse(t=t, x=X, u=U, y=np.asarray(Y), states=diagram.states, inputs=diagram.inputs,
                              outputs=diagram.outputs, stats=Stats(self.nsteps, self.nfailed, self.nfevals),
                              status=self.status, message=message, method=self.method_name,
                              breakpoints=tuple(float(c) for c in cuts), warnings=tuple(self.warns),
                              crossings={n: tuple(v) for n, v in sw.times.items()},
                              hits=tuple(float(h) for h in self.hit_times), notes=tuple(notes),
                              te=np.array(self.user_te), ye=np.array(self.user_ye).reshape(n_user, x.size),
                              ie=np.array(self.user_ie, dtype=int))


_SQRT_EPS = math.sqrt(np.finfo(float).eps)


def _stop_when_changed(changed, start, x):
    """An OutputFcn that stops the solver at the end of the first step after which a stepped
    relay's mode changed (``changed`` is Switching.stepped_check's, primed at ``start``)."""
    changed(start, x)

    def stop_fcn(tt, yy, flag):
        if flag == "" and np.size(tt):
            return changed(float(np.atleast_1d(tt)[-1]), np.asarray(yy).reshape(-1, x.size)[-1])
        return False

    return stop_fcn


def _stop_block_watch(check, other, nx):
    """An OutputFcn that stops the solver at the end of the first step after which a stop block's input is nonzero
    (and also when ``other``, a stepped relay's, asks)."""
    def stop_fcn(tt, yy, flag):
        if flag == "" and np.size(tt):
            t_last = float(np.atleast_1d(tt)[-1])
            y_last = np.asarray(yy).reshape(-1, nx)[-1]
            return bool(check(t_last, y_last)) or bool(other(tt, yy, flag) if other else False)
        return bool(other(tt, yy, flag)) if other else False

    return stop_fcn


def _combined(zc, n_zc, events):
    """One events function: the blocks' switching functions, then the user's events."""
    if events is None:
        return zc
    if zc is None:
        return events

    def ev(t, x):
        v1, t1, d1 = zc(t, x)
        v2, t2, d2 = events(t, x)
        return (np.concatenate([v1, np.asarray(v2, dtype=float).reshape(-1)]),
                np.concatenate([t1, np.asarray(t2, dtype=bool).reshape(-1)]),
                np.concatenate([d1, np.asarray(d2, dtype=float).reshape(-1)]))

    return ev


def _chatter_message(count: int, block: str, t: float) -> str:
    return (f"{count} consecutive zero crossings of block `{block}` at t = {t:.10g} (the switch chatters: its mode "
            f"changes faster than time can advance); set zero_crossing = false on `{block}` or change the model.")


class _Stop(Exception):
    """Ends the run early (a failure recorded in status/message)."""


def _at_user_times(t, X, user, complete):
    """The rows at the user's output times: a time listed twice gets the rows before and after a
    jump there, a time listed once the row after it."""
    out_t, out_x = [], []
    uniq, counts = np.unique(user, return_counts=True)
    wanted = dict(zip(uniq.tolist(), counts.tolist()))
    seen = set()
    for tq in user.tolist():
        if tq in seen:
            continue
        seen.add(tq)
        rows = np.flatnonzero(t == tq)
        if not rows.size:
            continue
        if wanted[tq] >= 2 and rows.size >= 2:
            picks = [rows[0]] + [rows[-1]] * (wanted[tq] - 1)
        else:
            picks = [rows[-1]] * wanted[tq]
        out_t.extend([tq] * len(picks))
        out_x.extend(X[picks])
    return np.array(out_t), np.array(out_x).reshape(len(out_t), X.shape[1])


def _discrete_hit(diagram, t, x, u, names):
    """The state after the hit at ``t`` of the discrete blocks ``names``: their outputs in
    evaluation order (each seeing the new ones upstream), then their state updates."""
    blocks = diagram.wiring.blocks
    x = np.array(x, dtype=float)
    order = [n for n in diagram.wiring.order if n in names]
    pending = []
    for n in order:
        b = blocks[n]
        vals = diagram._ports(t, x, u, False)
        ins = [vals[p] for p in diagram.wiring.sources[n]]
        sl = diagram.slices[n]
        x[sl] = b.hit_output_at(t, x[sl], ins) if getattr(b, "TIMED", False) else b.hit_output(x[sl], ins)
        pending.append((n, ins))
    for n, ins in pending:
        sl = diagram.slices[n]
        x[sl] = blocks[n].hit_update(x[sl], ins)
    return x
