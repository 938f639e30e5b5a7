"""[events] in experiment files: zero-crossing events, resets (hybrid systems) and a Zeno guard.

```toml
[events]
max_events = 100              # stop the case after this many events (default 100)
[events.floor]
when = "h"                    # the event is a zero of this expression (t, states, parameters)
direction = "falling"         # "rising", "falling" or "both" (MATLAB's 1, -1, 0 also work)
terminal = true               # MATLAB's isterminal (1 and 0 also work)
reset = { v = "-e*v" }        # restart with these states changed
exact = "t1*(1 + 2*e*(1 - e^k)/(1 - e))"   # optional: exact time of occurrence k = 0, 1, ...
```

Events are located by the solver (:mod:`odelab.solvers.events`, MATLAB's ``odezero``). Without
``reset`` a terminal event stops the case. With ``reset`` the case restarts at ``te`` from the
reset state, a fresh start of the MATLAB algorithm, as a MATLAB user does by hand in a loop
around ``ode45``; the pieces are joined, the event time appearing twice (before and after the
jump). ``max_events`` ends a Zeno cascade (a bouncing ball's bounces piling up) cleanly, with a
note.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from odelab.exceptions import ExperimentError
from odelab.experiment.fields import check_keys, expr
from odelab.solution import Stats
from odelab.systems.fields import EventReset, EventValues, ExactTime

__all__ = ["EventSet", "compile_events", "solve_with_events", "DEFAULT_MAX_EVENTS"]

DEFAULT_MAX_EVENTS = 100
EVENT_KEYS = ("when", "direction", "terminal", "reset", "exact")
_DIRECTIONS = {"rising": 1, "falling": -1, "both": 0}


@dataclass(frozen=True, eq=False)
class EventSet:
    """The compiled [events] section of a case."""

    names: tuple[str, ...]
    terminal: np.ndarray  # bool per event
    direction: np.ndarray  # 1, -1, 0 per event
    values: Callable  # values(t, x) -> (k,)
    resets: dict[int, Callable]  # event index -> reset(t, x) -> new x
    exact: dict[int, Callable]  # event index -> exact time of occurrence k (0-based)
    max_events: int
    whens: tuple = ()  # (text, TOML key) of each event's `when`: the compiled backend generates them
    max_events_given: bool = False  # the file set `events.max_events` (a planned stop, not a Zeno guard)

    def function(self, t, x):
        """MATLAB's events function: (value, isterminal, direction)."""
        return self.values(t, x), self.terminal, self.direction


def _direction(value, key: str) -> int:
    if isinstance(value, str) and value.lower() in _DIRECTIONS:
        return _DIRECTIONS[value.lower()]
    if isinstance(value, int) and not isinstance(value, bool) and value in (1, -1, 0):
        return value
    raise ExperimentError(f"`{key}` is {value!r}; use \"rising\", \"falling\" or \"both\" (MATLAB's 1, -1, 0 also "
                          "work).", key=key)


def compile_events(section: dict[str, Any], states: tuple[str, ...], params: dict[str, float],
                   limits=None) -> tuple[EventSet, dict]:
    """Check and compile an [events] section; returns the event set and its resolved form.

    ``events.max_events`` is held to the run's ``events`` budget (each event restarts the
    solver: a Zeno cascade allowed a million events runs for hours)."""
    from odelab.experiment.limits import DEFAULT_LIMITS, check_count

    ex = expr()
    max_events = section.get("max_events", DEFAULT_MAX_EVENTS)
    if isinstance(max_events, bool) or not isinstance(max_events, int) or max_events < 1:
        raise ExperimentError(f"`events.max_events` must be a whole number >= 1; got {max_events!r}.",
                              key="events.max_events")
    check_count("events", max_events, "events.max_events", "", limits or DEFAULT_LIMITS,
                asked=f"is {max_events:,}")
    names: list[str] = []
    whens: list[Any] = []
    terminal: list[bool] = []
    direction: list[int] = []
    reset_texts: dict[int, dict] = {}
    exact_texts: dict[int, Any] = {}
    resolved: dict[str, Any] = {"max_events": max_events}
    for name, spec in section.items():
        if name == "max_events":
            continue
        key = f"events.{name}"
        if not isinstance(spec, dict):
            raise ExperimentError(f"`{key}` must be a table such as [events.{name}] with when = \"...\" (or set "
                                  "`events.max_events`); got {spec!r}.".replace("{spec!r}", repr(spec)), key=key)
        for k in spec:
            if k not in EVENT_KEYS:
                close = difflib.get_close_matches(k, EVENT_KEYS, n=1)
                hint = f" Did you mean `{close[0]}`?" if close else ""
                raise ExperimentError(f"`{key}.{k}` is not an event key ({', '.join(EVENT_KEYS)}).{hint}",
                                      key=f"{key}.{k}")
        if "when" not in spec:
            raise ExperimentError(f"`{key}` needs `when`: the expression whose zero is the event, e.g. when = "
                                  f"\"{states[0]}\".", key=f"{key}.when")
        if isinstance(spec["when"], bool) or not isinstance(spec["when"], (str, int, float)):
            raise ExperimentError(f"`{key}.when` must be an expression string; got {spec['when']!r}.",
                                  key=f"{key}.when")
        i = len(names)
        names.append(name)
        whens.append(spec["when"])
        direction.append(_direction(spec.get("direction", "both"), f"{key}.direction"))
        reset = spec.get("reset")
        is_terminal = spec.get("terminal", reset is not None)
        if not isinstance(is_terminal, bool) and is_terminal in (0, 1):  # MATLAB's isterminal: 1 or 0
            is_terminal = bool(is_terminal)
        if not isinstance(is_terminal, bool):
            raise ExperimentError(f"`{key}.terminal` must be true or false (MATLAB's isterminal 1 or 0); got "
                                  f"{is_terminal!r}.", key=f"{key}.terminal")
        terminal.append(is_terminal)
        entry: dict[str, Any] = {"when": spec["when"], "direction": {1: "rising", -1: "falling", 0: "both"}[direction[-1]],
                                 "terminal": is_terminal}
        if reset is not None:
            if not isinstance(reset, dict) or not reset:
                raise ExperimentError(f"`{key}.reset` must be a table of new state values, e.g. reset = "
                                      f"{{ {states[-1]} = \"-{states[-1]}\" }}; got {reset!r}.", key=f"{key}.reset")
            if not is_terminal:
                raise ExperimentError(f"`{key}.reset` restarts the integration, so the event must be terminal: "
                                      "remove `terminal = false`.", key=f"{key}.terminal")
            check_keys(reset, states, f"{key}.reset", "states", require_all=False)
            reset_texts[i] = reset
            entry["reset"] = dict(reset)
        if "exact" in spec:
            exact_texts[i] = spec["exact"]
            entry["exact"] = spec["exact"]
        resolved[name] = entry
    if not names:
        raise ExperimentError("[events] defines no event: add a table such as [events.floor] with when = \"...\".",
                              key="events")

    args = ["t", *states]
    values_fn = ex.compile_vector(whens, args=args, constants=params, keys=[f"events.{n}.when" for n in names])

    values = EventValues(values_fn)

    resets: dict[int, Callable] = {}
    for i, reset in reset_texts.items():
        order = [s for s in states if s in reset]
        fn = ex.compile_vector([reset[s] for s in order], args=args, constants=params,
                               keys=[f"events.{names[i]}.reset.{s}" for s in order])
        resets[i] = EventReset(fn, np.array([states.index(s) for s in order]))
    exact: dict[int, Callable] = {}
    for i, text in exact_texts.items():
        if "k" in params:
            raise ExperimentError(f"`events.{names[i]}.exact` is the time of occurrence `k` (k = 0, 1, 2, ...), and "
                                  "[parameters] also defines `k`: rename the parameter (e.g. `k_spring`) so that "
                                  "`k` in the expression is the occurrence.", key=f"events.{names[i]}.exact")
        exact_time = ExactTime(ex.compile_expression(text, names=["k", *params], key=f"events.{names[i]}.exact"),
                               params)
        exact_time(0)  # evaluate once now: a bad expression fails at load time
        exact[i] = exact_time
    events = EventSet(names=tuple(names), terminal=np.array(terminal), direction=np.array(direction, dtype=float),
                      values=values, resets=resets, exact=exact, max_events=max_events,
                      whens=tuple((str(w), f"events.{n}.when") for w, n in zip(whens, names)),
                      max_events_given="max_events" in section)
    return events, resolved


def solve_with_events(fun, tspan: np.ndarray, x0: np.ndarray, method: str, options: dict, events: EventSet,
                      states: tuple[str, ...], solve_piece=None):
    """Integrate with events, restarting after each terminal event that has a reset.

    ``solve_piece(tspan, x0, options)`` solves one piece, locating the events (default:
    :func:`odelab.solvers.api.solve` with ``fun`` and ``events.function``; the compiled backend
    passes its own, which locates the same events in the compiled loop).

    Returns ``(t, x, stats, status, message, warnings, records, marks)``: ``records`` lists the
    events in time order (name, index, occurrence, t, state, exact time, reset state), ``marks``
    holds per output row the 1-based number of the event recorded at that row (0 for none).
    """
    from odelab.solvers.api import solve

    tfinal = float(tspan[-1])
    tdir = 1.0 if tfinal > tspan[0] else -1.0
    vector = tspan.size > 2
    t_parts: list[np.ndarray] = []
    x_parts: list[np.ndarray] = []
    mark_parts: list[np.ndarray] = []
    records: list[dict] = []
    occurrences = [0] * len(events.names)
    nsteps = nfailed = nfevals = 0
    linear = None
    warnings: list[str] = []
    piece_tspan = tspan
    x = np.asarray(x0, dtype=float)
    restarts = 0
    restarted_by = None
    scale = float(np.max(np.abs(events.values(float(tspan[0]), x)))) if x.size else 0.0
    status, message = "success", f"{method} reached t = {tfinal:g}."
    while True:
        if solve_piece is None:
            sol = solve(fun, piece_tspan, x, method=method, events=events.function, **options)
        else:
            sol = solve_piece(piece_tspan, x, options)
        nsteps, nfevals = nsteps + sol.stats.nsteps, nfevals + sol.stats.nfevals
        nfailed += sol.stats.nfailed or 0
        if sol.stats.npds is not None:  # a stiff solver's Jacobians, LU decompositions, linear solves
            linear = [a + (b or 0) for a, b in zip(linear or (0, 0, 0),
                                                   (sol.stats.npds, sol.stats.ndecomps, sol.stats.nsolves))]
        warnings.extend(w for w in sol.warnings if w not in warnings)
        t_piece, x_piece = sol.t, sol.y
        if vector and piece_tspan.size == 2:
            # the last piece of a vector tspan: output at te and tfinal only, not Refine points
            t_piece, x_piece = t_piece[[0, -1]], x_piece[[0, -1]]
        if restarted_by is not None and _missed_crossing(events, restarted_by, sol, t_piece, x_piece, scale):
            # The solver's first step after the restart covered the next crossing and its
            # return (two zeros in one step): the events pile up faster than the steps.
            t_parts.append(t_piece[:1])
            x_parts.append(x_piece[:1])
            mark_parts.append(np.zeros(1, dtype=int))
            message = (f"{method} stopped at t = {t_piece[0]:.10g} after {len(records)} events: events of "
                       f"{events.names[restarted_by]!r} pile up (a Zeno cascade).")
            warnings.append(f"the case stopped at t = {t_piece[0]:.6g}: after {len(records)} events, event "
                            f"{events.names[restarted_by]!r} recurs faster than the solver's first step after a "
                            "restart can resolve (a Zeno cascade); the solution beyond would cross it unseen.")
            break
        new = []
        for te, ye, ie in zip(sol.te, sol.ye, sol.ie):
            ie = int(ie)
            record = {"name": events.names[ie], "index": ie, "occurrence": occurrences[ie], "t": float(te),
                      "state": {s: float(v) for s, v in zip(states, ye)}}
            if ie in events.exact:
                record["exact_t"] = events.exact[ie](occurrences[ie])
            occurrences[ie] += 1
            new.append(record)
        stopped_by = None
        if (sol.status == "success" and sol.te.size and events.terminal[int(sol.ie[-1])]
                and sol.t[-1] == sol.te[-1]):
            stopped_by = int(sol.ie[-1])
        unheeded = _unheeded_terminal(events, sol, stopped_by) if restarted_by is not None else None
        if unheeded is not None:
            # A terminal event located within odezero's tolerance of the restart (MATLAB counts
            # it non-terminal there): the next bounce came before the solver could leave the
            # last one, so the piece went on past it. Keep the piece up to that event and stop.
            new = new[: unheeded + 1]
            t_last, y_last = float(sol.te[unheeded]), np.asarray(sol.ye[unheeded], dtype=float)
            keep = tdir * (t_piece - t_last) < 0
            t_piece = np.concatenate([t_piece[keep], [t_last]])
            x_piece = np.concatenate([x_piece[keep], y_last[None, :]])
            mark = np.zeros(t_piece.size, dtype=int)
            mark[-1] = len(records) + len(new)
            records.extend(new)
            t_parts.append(t_piece)
            x_parts.append(x_piece)
            mark_parts.append(mark)
            name = events.names[int(sol.ie[unheeded])]
            message = (f"{method} stopped at t = {t_last:.10g} after {len(records)} events: events of "
                       f"{name!r} pile up (a Zeno cascade).")
            warnings.append(f"the case stopped at t = {t_last:.6g}: after {len(records)} events, event {name!r} "
                            "recurs within the event tolerance of the last restart (a Zeno cascade); the "
                            "solution beyond would pass through it.")
            break
        restart = (stopped_by is not None and stopped_by in events.resets and sol.te[-1] != tfinal)
        total = len(records) + len(new)
        over = total > events.max_events or (total == events.max_events and restart)
        if over:
            new = new[: events.max_events - len(records)]
            t_last = new[-1]["t"]
            keep = tdir * (t_piece - t_last) <= 0
            t_piece, x_piece = t_piece[keep], x_piece[keep]
        mark = np.zeros(t_piece.size, dtype=int)
        for number, record in enumerate(new, start=len(records) + 1):
            rows = np.flatnonzero(t_piece == record["t"])
            if rows.size:
                mark[rows[-1]] = number
        records.extend(new)
        t_parts.append(t_piece)
        x_parts.append(x_piece)
        mark_parts.append(mark)
        scale = max(scale, float(np.max(np.abs(events.values(float(t_piece[-1]), x_piece[-1])))))
        if sol.status != "success":
            status, message = sol.status, sol.message
            break
        if over:
            t_last = records[-1]["t"]
            message = (f"{method} stopped at t = {t_last:.10g} after max_events = {events.max_events} events "
                       f"({restarts} restart{'s' if restarts != 1 else ''}).")
            why = ("as the file's `events.max_events` asks" if events.max_events_given
                   else "(a Zeno cascade of events piling up?)")
            warnings.append(f"the case stopped after max_events = {events.max_events} events, at t = {t_last:.6g} "
                            f"{why}; raise `events.max_events` to go further.")
            break
        if stopped_by is None or (stopped_by in events.resets and not restart):
            if restarts:
                message = f"{method} reached t = {tfinal:g} after {restarts} restart{'s' if restarts != 1 else ''}."
            break
        te = float(sol.te[-1])
        if not restart:
            message = f"{method} stopped at t = {te:.10g}: terminal event {events.names[stopped_by]!r}."
            break
        x = events.resets[stopped_by](te, sol.ye[-1])
        records[-1]["reset"] = {s: float(v) for s, v in zip(states, x)}
        if not np.all(np.isfinite(x)):
            status = "failed"
            message = f"the reset of event {events.names[stopped_by]!r} at t = {te:.10g} gave a state that is not finite."
            break
        restarts += 1
        restarted_by = stopped_by
        later = tspan[tdir * (tspan - te) > 0] if vector else tspan[-1:]
        piece_tspan = np.concatenate([[te], later])
    npds, ndecomps, nsolves = linear or (None, None, None)
    return (np.concatenate(t_parts), np.concatenate(x_parts),
            Stats(nsteps=nsteps, nfailed=nfailed, nfevals=nfevals, npds=npds, ndecomps=ndecomps, nsolves=nsolves),
            status, message, warnings, records, np.concatenate(mark_parts))


def _unheeded_terminal(events: EventSet, sol, stopped_by) -> int | None:
    """The index in ``sol.te`` of the first terminal event that did not stop the piece, if any.

    The solver (as MATLAB's ``odezero``) treats a terminal event found while its search is still
    at the initial point as non-terminal; after a restart that is an event recurring within the
    event tolerance of the last one."""
    for j, ie in enumerate(sol.ie):
        if not events.terminal[int(ie)]:
            continue
        if stopped_by is not None and sol.te[j] == sol.te[-1]:
            return None
        return j
    return None


def _missed_crossing(events: EventSet, i: int, sol, t_piece, x_piece, scale: float) -> bool:
    """After a restart at a zero of event ``i``, did the piece pass to the event's far side unseen?

    A "falling" event is caught going from + to -; restarted on its surface, the solution may
    cross back to - only through a located event. Rows before the first event of ``i`` that lie
    on the far side by more than 1e-6 of the event function's scale reveal a crossing that
    fell inside one step (two zeros in a step are invisible to sign tests, MATLAB's as well).

    The scale is the largest |value| seen so far, this piece's rows before the event included:
    a ball restarted exactly on the floor (``reset = { h = "0", ... }``, MATLAB's ballode) has
    zero at every piece's ends, and its flight between them is what a round-off far side
    (the located event's own row, 1e-13 below the floor) is measured against. That row, the
    event itself, is not a missed crossing.
    """
    d = events.direction[i]
    if d == 0:
        return False
    first = sol.te[sol.ie == i]
    limit = first[0] if first.size else None
    forward = 1.0 if t_piece[-1] >= t_piece[0] else -1.0
    far = 0.0
    for t, x in zip(t_piece, x_piece):
        if limit is not None and (t - limit) * forward >= 0:
            break
        value = float(events.values(float(t), x)[i])
        far = max(far, d * value)
        scale = max(scale, abs(value))
    return far > 1e-6 * max(scale, 1e-300)
