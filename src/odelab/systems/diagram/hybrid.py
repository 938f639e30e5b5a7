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

from odelab.solution import Stats
from odelab.systems.simulate import Response

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
    return any(b.DISCRETE or b.STATEFUL_MODE or (zero_crossing and b.zero_crossing) for b in blocks)


def _locates(method: str) -> bool:
    from odelab.solvers.registry import get_method

    return get_method(method).kind in ("adaptive", "implicit", "multistep")


def simulate_hybrid(diagram, tspan, x0=None, *, method: str = "ode45", zero_crossing: bool = True,
                    events=None, **options) -> HybridResponse:
    """Integrate a compiled diagram with its switching and discrete blocks (see the module).

    ``tspan`` is ``[t0, tf]`` (the solver's own points, restarts shown twice) or output times.
    ``zero_crossing = False`` turns location off for every block. ``events`` is a MATLAB-form
    events function of (t, x), ``(value, isterminal, direction)`` (an [events] section's): its
    events are located with the blocks' and returned as ``te, ye, ie``, a terminal one ends the
    run there. A failure (a solver failure, a chattering switch) returns what was computed with
    ``status == "failed"``.
    """
    from odelab.solvers.api import solve
    from odelab.solvers.events import locate_events  # noqa: F401 - the locator the solver runs
    from odelab.solvers.options import as_tspan
    from odelab.systems.diagram.schedule import hits as sample_hits
    from odelab.systems.diagram.zerocross import MAX_CONSECUTIVE, Switching

    tspan = np.asarray(tspan, dtype=float)
    if tspan.size > 2:  # output times; a time listed twice asks for the rows before and after a jump
        as_tspan(np.unique(tspan) if tspan[-1] > tspan[0] else np.unique(tspan)[::-1])
        step = np.sign(tspan[-1] - tspan[0]) * np.diff(tspan)
        if np.any(step < 0):
            as_tspan(tspan)  # its message: entries must increase
    else:
        tspan = as_tspan(tspan)
    t0, tf = float(tspan[0]), float(tspan[-1])
    forward = tf >= t0
    blocks = diagram.wiring.blocks
    signals = list(diagram.signals)
    x = np.array(diagram.x0 if x0 is None else x0, dtype=float).reshape(-1)
    notes: list[str] = []

    locate = zero_crossing and _locates(method)
    sw = Switching(diagram, enabled=locate)
    if zero_crossing and not locate and any(blocks[n].zero_crossing for n in sw.blocks):
        notes.append(f"{method} locates no events: zero crossings are stepped over (use ode45, ode23, ode15s...)")
    if sw.stepped and not _locates(method):
        from odelab.exceptions import InputError

        raise InputError(f"the relay `{sw.stepped[0]}` switches at the end of a step, which {method} does not "
                         "report; use ode45, ode23, ode113 or a stiff solver.", key="solver.method")

    rates = {n: b.sample for n, b in blocks.items() if b.DISCRETE}
    hit_times, hit_who = sample_hits(rates, t0, tf)
    cuts = np.unique(np.concatenate([np.empty(0), *(s.breakpoints(t0, tf) for s in signals)]))
    inside = lambda c: (c > min(t0, tf)) & (c < max(t0, tf))  # noqa: E731
    cuts = cuts[inside(cuts)]
    hit_map = {float(t): w for t, w in zip(hit_times, hit_who)}
    edges = sorted(set(cuts.tolist()) | {t for t in hit_map if min(t0, tf) < t < max(t0, tf)},
                   reverse=not forward)
    edges = [t0, *edges, tf]
    if len(edges) > 2 and not any(k.lower().replace("_", "") == "maxstep" and v is not None
                                  for k, v in options.items()):
        from odelab.solvers.registry import get_method

        if get_method(method).kind in ("adaptive", "implicit", "multistep"):
            options = {**options, "max_step": 0.1 * abs(tf - t0)}

    dense = tspan.size == 2
    user = tspan
    user_te: list[float] = []
    user_ye: list[np.ndarray] = []
    user_ie: list[int] = []
    finished = False  # a terminal user event ended the run
    rows_t: list[np.ndarray] = []
    rows_x: list[np.ndarray] = []
    nsteps = nfevals = 0
    nfailed = 0
    status, message, method_name = "success", "", method
    warns: list[str] = []

    def inputs_at(lo, hi):
        if not signals:
            empty = np.zeros(0)
            return lambda t: empty

        def u(t):
            tu = min(max(t, lo), hi)
            return np.array([s(tu) for s in signals])

        return u

    def add(t, xs):
        rows_t.append(np.atleast_1d(np.asarray(t, dtype=float)))
        rows_x.append(np.asarray(xs, dtype=float).reshape(-1, x.size))

    consecutive = 0
    sqrt_eps = math.sqrt(np.finfo(float).eps)

    def look(t, end):
        """How far ahead a switching function's departure from a zero at ``t`` is read: a
        relative sqrt(eps) of the span, inside the piece that ends at ``end``."""
        dt = sqrt_eps * max(abs(tf - t0), abs(t))
        if end != t:
            dt = min(dt, 0.5 * abs(end - t))
        return dt if forward else -dt

    def settle(t, xs, u, end):
        """The modes at a piece's start once every switching function exactly zero there has
        left in the direction it goes (the solver ignores a zero at its initial point, as
        MATLAB does: the driver takes those crossings itself, counted like located ones)."""
        nonlocal consecutive, status, message
        if not sw.located:
            return xs
        dt = look(t, end)
        while True:
            hit, after = sw.departing(t, xs, u, dt)
            if not hit:
                return xs
            sw.record(t, hit)
            consecutive += 1
            if consecutive >= MAX_CONSECUTIVE:
                status, message = "failed", _chatter_message(consecutive, hit[0], t)
                raise _Stop
            xs = sw.choose(t, xs, u(t), after=after)

    try:
        # the hit at t0 (discrete outputs from their initial states and the inputs at t0)
        u_first = inputs_at(-math.inf if len(edges) == 2 else -math.inf, math.inf)
        if t0 in hit_map:
            x = _discrete_hit(diagram, t0, x, u_first(t0), hit_map[t0])
        if sw:  # a function zero at t0 takes the sign it moves into (Simulink's initialisation)
            x = sw.choose(t0, x, u_first(t0), after=lambda xx: sw.ahead(t0, xx, u_first, look(t0, edges[1])))
        for i in range(len(edges) - 1):
            a, b = edges[i], edges[i + 1]
            last = i == len(edges) - 2
            lo, hi = min(a, b), max(a, b)
            u_lo = lo if ((lo == a and i > 0) or (lo == b and not last)) else -math.inf
            u_hi = float(np.nextafter(hi, -math.inf)) if ((hi == a and i > 0) or (hi == b and not last)) else math.inf
            u = inputs_at(u_lo, u_hi)
            diagram.slope_window = (u_lo, u_hi)
            if i > 0 and sw:
                x = sw.choose(a, x, u(a), after=lambda xx, _a=a, _b=b, _u=u: sw.ahead(_a, xx, _u, look(_a, _b)))
            if sw:
                x = settle(a, x, u, b)
            start = a
            if dense:
                grid_user = np.empty(0)
            else:
                grid_user = np.unique(user[(user > lo) & (user < hi)])
                if not forward:
                    grid_user = grid_user[::-1]
            if i == 0 or not dense:
                add(a, x) if (dense or np.any(user == a)) else None
            else:
                add(a, x)  # the row after the jump (the one before ended the previous piece)
            while True:
                before = sw.raw(start, x, u(start), sw.located) if sw.located else None
                ev = _combined(sw.event_function(u) if sw.located else None, len(sw.owners) if sw.located else 0,
                               events)
                n_zc = len(sw.owners) if sw.located else 0
                stop_fcn = None
                if sw.stepped:
                    changed = sw.stepped_check(u)
                    changed(start, x)

                    def stop_fcn(tt, yy, flag, _c=changed):
                        if flag == "" and np.size(tt):
                            return _c(float(np.atleast_1d(tt)[-1]), np.asarray(yy).reshape(-1, x.size)[-1])
                        return False

                rest = grid_user[(grid_user > start) if forward else (grid_user < start)]
                grid = np.concatenate([[start], rest, [b]])

                def rhs(t, xx, _u=u):
                    return diagram._dynamics(t, xx, _u(t))

                opts = dict(options)
                if ev is not None:
                    opts["events"] = ev
                if stop_fcn is not None:
                    opts["output_fcn"] = stop_fcn
                sol = solve(rhs, grid, x, method=method, **opts)
                nsteps += sol.stats.nsteps
                nfevals += sol.stats.nfevals
                nfailed = None if nfailed is None or sol.stats.nfailed is None else nfailed + sol.stats.nfailed
                method_name = sol.method or method
                warns.extend(w for w in sol.warnings if w not in warns)
                t_end = float(sol.t[-1])
                te = np.asarray(sol.te, dtype=float)
                keep = (sol.t > start) if forward else (sol.t < start)
                if sol.status != "success":
                    if dense or True:
                        add(sol.t[keep], sol.y[keep])
                    status, message = "failed", sol.message
                    raise _Stop
                ie_all = np.asarray(sol.ie, dtype=int)
                user_terminal = [bool(np.asarray(events(float(tj), yj)[1]).reshape(-1)[j - n_zc])
                                 if j >= n_zc else True for tj, yj, j in zip(te, sol.ye, ie_all)] if te.size else []
                first = next((k for k in range(te.size) if ie_all[k] < n_zc or user_terminal[k]), None)
                for k in range(te.size):  # the user's events up to the end of this stretch
                    if ie_all[k] >= n_zc and (first is None or te[k] <= te[first]):
                        user_te.append(float(te[k]))
                        user_ye.append(np.asarray(sol.ye[k], dtype=float))
                        user_ie.append(int(ie_all[k] - n_zc))
                if first is not None and ie_all[first] >= n_zc:  # a terminal user event ends the run
                    t_stop = float(te[first])
                    inner = keep & ((sol.t < t_stop) if forward else (sol.t > t_stop))
                    add(sol.t[inner], sol.y[inner])
                    add(t_stop, sol.ye[first])
                    x = np.asarray(sol.ye[first], dtype=float)
                    message = sol.message
                    finished = True
                    break
                te = te[[k for k in range(te.size) if ie_all[k] < n_zc]]
                if te.size:  # the first located switch ends the piece (terminal or not)
                    zc_rows = [k for k in range(ie_all.size) if ie_all[k] < n_zc]
                    t_sw = float(te[0])
                    y_sw = np.asarray(sol.ye[zc_rows[0]], dtype=float)
                    inner = keep & ((sol.t < t_sw) if forward else (sol.t > t_sw))
                    add(sol.t[inner], sol.y[inner])
                    add(t_sw, y_sw)
                    fired = [sw.owners[ie_all[k]] for k in zc_rows if float(sol.te[k]) == t_sw]
                    sw.record(t_sw, fired)
                    tol = 128 * max(math.ulp(t_sw), math.ulp(start))
                    consecutive = consecutive + 1 if abs(t_sw - start) <= 10 * tol else 0
                    if consecutive >= MAX_CONSECUTIVE:
                        status, message = "failed", _chatter_message(consecutive, fired[0], t_sw)
                        raise _Stop
                    x = sw.choose(t_sw, sw.sync(t_sw, y_sw, u(t_sw), fired), u(t_sw), before)
                    x = settle(t_sw, x, u, b)
                    add(t_sw, x) if dense or (t_sw == b and np.any(user == b)) else None
                    start = t_sw
                    if t_sw == b:
                        break
                    continue
                if t_end != b:  # a stepped relay stopped the solver at a step's end
                    add(sol.t[keep], sol.y[keep])
                    y_end = np.asarray(sol.y[-1], dtype=float)
                    x_before = y_end.copy()
                    x = sw.choose(t_end, sw.sync(t_end, y_end, u(t_end)), u(t_end),
                                  after=lambda xx: sw.ahead(t_end, xx, u, look(t_end, b)))
                    x = settle(t_end, x, u, b)
                    sw.record(t_end, [n for n in sw.stepped if not np.array_equal(
                        x[diagram.slices[n]], x_before[diagram.slices[n]])])
                    if dense:
                        add(t_end, x)
                    start = t_end
                    continue
                at_b = keep & (sol.t == b)
                body = keep & ~at_b
                add(sol.t[body], sol.y[body])
                x = np.asarray(sol.y[-1], dtype=float)
                x = sw.sync(b, x, u(b)) if sw else x
                if dense or np.any(user == b):
                    add(b, x)  # the row before the jump at b (or the last row)
                break
            if finished:
                break
            if b in hit_map and not last:
                x = _discrete_hit(diagram, b, x, inputs_at(b, math.inf if forward else b)(b), hit_map[b])
            elif b in hit_map and last:
                x_after = _discrete_hit(diagram, b, x, u(b), hit_map[b])
                if dense or np.any(user == b):
                    add(b, x_after)
                x = x_after
            consecutive = 0
        message = message or sol.message
    except _Stop:
        pass
    finally:
        sw.release()
        diagram.slope_window = (-math.inf, math.inf)

    t = np.concatenate(rows_t) if rows_t else np.array([t0])
    X = np.concatenate(rows_x).reshape(t.size, x.size) if rows_x else x.reshape(1, -1)
    if not dense:
        t, X = _at_user_times(t, X, user, status == "success")
    counts = {n: len(v) for n, v in sw.times.items()}
    if counts:
        notes.append("zero crossings located: " + ", ".join(f"{n} ({blocks[n].TYPE}) {c}" for n, c in counts.items()))
    if hit_times.size:
        rates_txt = ", ".join(f"{n} every {blocks[n].sample}" for n in rates)
        notes.append(f"sample hits: {hit_times.size} ({rates_txt})")
    if status == "success" and not finished:
        message = (message.split(" Integrated in")[0] + " " + "; ".join(notes) + ".").strip() if notes else message
    U = np.zeros((t.size, len(signals)))
    for j, s in enumerate(signals):
        U[:, j] = s(t)
    # a breakpoint listed twice: the row before the jump reads the sources before it (their left
    # limits), so an input, and an output that feeds it through, is drawn as the step it is
    twice = np.flatnonzero((t[:-1] == t[1:]) & np.isin(t[:-1], cuts)) if t.size > 1 and cuts.size else []
    for i in twice:
        before = float(np.nextafter(t[i], -math.inf if forward else math.inf))
        U[i] = [s(before) for s in signals]
    Y = diagram.output_many(t, X, U) if diagram.outputs else np.zeros((t.size, 0))
    for arr in (t, X, U, Y):
        arr.setflags(write=False)
    return HybridResponse(t=t, x=X, u=U, y=np.asarray(Y), states=diagram.states, inputs=diagram.inputs,
                          outputs=diagram.outputs, stats=Stats(nsteps, nfailed, nfevals), status=status,
                          message=message, method=method_name, breakpoints=tuple(float(c) for c in cuts),
                          warnings=tuple(warns), crossings={n: tuple(v) for n, v in sw.times.items()},
                          hits=tuple(float(h) for h in hit_times), notes=tuple(notes),
                          te=np.array(user_te), ye=np.array(user_ye).reshape(len(user_te), x.size),
                          ie=np.array(user_ie, dtype=int))


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
        x[sl] = b.hit_output(x[sl], ins)
        pending.append((n, ins))
    for n, ins in pending:
        sl = diagram.slices[n]
        x[sl] = blocks[n].hit_update(x[sl], ins)
    return x
