"""Running an FMU system: Model Exchange stepped by odelab's solvers, Co-Simulation at its
communication step.

Model Exchange: between events the FMU's derivatives are the right-hand side of
:func:`odelab.solvers.api.solve` (MATLAB's methods and options), its event indicators the
solver's terminal events (located as MATLAB's odezero locates them), and its next time event
the end of the piece. At each event the FMU's own event iteration runs (it resets its states,
as a bouncing ball's velocity), and the solver restarts from the states it gives back. Each
event is recorded as [events] records are (name, time, state, reset).

Co-Simulation: the FMU integrates itself; odelab sets its inputs and calls ``doStep`` at each
communication point: the output times of ``[time] points`` or ``output`` if given, else every
``[solver] h`` (a fixed-step method's), else every DefaultExperiment ``stepSize``, else every
500th of the span.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from odelab.solution import Stats

__all__ = ["FmuRun", "run_fmu"]

#: at most this many events in one run (each restarts the solver): a chattering model stops here
MAX_EVENTS = 100_000


@dataclass(eq=False)
class FmuRun:
    """What a case runs: the FMU, the interface, the values to set (parameters, [initial]), the inputs'
    signals; and, after a run, its outputs (read from the FMU as it ran)."""

    model: object  # odelab.fmi.fmu.FmuModel
    interface: str
    values: dict  # Var -> value, set before initialisation
    signals: tuple = ()
    last: tuple | None = field(default=None, repr=False)  # (t, y) of the last run

    def output_fn(self, t, x, u=None):
        if self.last is not None and (self.last[0] is t or np.array_equal(self.last[0], t)):
            return self.last[1]
        raise RuntimeError("the outputs of an FMU are read while it runs; run the case first")

    def inputs_at(self, t: float) -> dict:
        return {v: float(np.asarray(s(t))) for v, s in zip(self.model.inputs, self.signals)}


class _Record:
    def __init__(self, n: int, ny: int):
        self.t: list[np.ndarray] = []
        self.x: list[np.ndarray] = []
        self.y: list[np.ndarray] = []
        self.n, self.ny = n, ny

    def add(self, adapter, run: FmuRun, t, x) -> None:
        """Rows at times ``t`` with states ``x``: the outputs read from the FMU at each."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        x = np.asarray(x, dtype=float).reshape(t.size, self.n)
        y = np.empty((t.size, self.ny))
        outputs = run.model.outputs
        for i in range(t.size):
            if run.signals:
                adapter.set(run.inputs_at(t[i]))
            adapter.set_time_state(t[i], x[i])
            y[i] = adapter.get(outputs) if outputs else ()
        self.t.append(t)
        self.x.append(x)
        self.y.append(y)

    def arrays(self):
        if not self.t:
            return np.zeros(0), np.zeros((0, self.n)), np.zeros((0, self.ny))
        return np.concatenate(self.t), np.concatenate(self.x), np.concatenate(self.y)


def _grid(tspan: np.ndarray, t: float, t_end: float, step: float | None = None) -> np.ndarray:
    """The output times of a piece: the vector tspan's inside it, else (``step``, for a model without
    states, which no solver steps) every ``step`` from the span's start."""
    if tspan.size > 2:
        inside = tspan[(tspan > t) & (tspan < t_end)]
    elif step:
        k = np.arange(np.floor((t - tspan[0]) / step) + 1, np.ceil((t_end - tspan[0]) / step))
        inside = tspan[0] + step * k
        inside = inside[(inside > t) & (inside < t_end)]
    else:
        inside = np.zeros(0)
    return np.concatenate([[t], inside, [t_end]])


def _me_piece(adapter, run: FmuRun, grid, x, method: str, options: dict):
    """One piece between events: the solver's solution (events located), with the FMU's derivatives."""
    from odelab.solvers.api import solve

    def fun(t, y):
        if run.signals:
            adapter.set(run.inputs_at(t))
        adapter.set_time_state(t, y)
        return adapter.derivatives()

    opts = dict(options)
    if adapter.nz:
        terminal, direction = np.ones(adapter.nz), np.zeros(adapter.nz)

        def events(t, y):
            if run.signals:
                adapter.set(run.inputs_at(t))
            adapter.set_time_state(t, y)
            return adapter.indicators(), terminal, direction

        opts["events"] = events
    return solve(fun, grid, x, method=method, **opts)


def run_model_exchange(run: FmuRun, tspan, x0, method: str, options: dict):
    """A Model Exchange FMU's run from ``tspan[0]`` to ``tspan[-1]`` (see :func:`run_fmu`)."""
    model = run.model
    adapter = model.adapter("model-exchange")
    t0, tf = float(tspan[0]), float(tspan[-1])
    rec = _Record(len(model.states), len(model.outputs))
    records: list[dict] = []
    marks: list[int] = []
    stats = [0, 0, 0]
    status, message, warnings = "success", f"{method} reached t = {tf:g}.", []
    names = [s.name for s in model.states]
    adapter.start(t0, options.get("rtol"), tf, {**run.values, **(run.inputs_at(t0) if run.signals else {})})
    try:
        terminate, _, next_time = adapter.event_iteration()
        adapter.enter_continuous_mode()
        x, t = adapter.states(), t0
        rec.add(adapter, run, t, x)
        while t < tf and not terminate:
            t_end = min(tf, next_time) if next_time is not None and next_time > t else tf
            if adapter.nx:
                sol = _me_piece(adapter, run, _grid(tspan, t, t_end), x, method, options)
                stats = [stats[0] + sol.stats.nsteps, stats[1] + (sol.stats.nfailed or 0),
                         stats[2] + sol.stats.nfevals]
                warnings.extend(w for w in sol.warnings if w not in warnings)
                rec.add(adapter, run, sol.t[1:], sol.y[1:])
                if sol.status != "success":
                    status, message = sol.status, sol.message
                    break
                t, x = float(sol.t[-1]), np.asarray(sol.y[-1], dtype=float)
                state_event = bool(sol.te.size) and sol.t[-1] == sol.te[-1]
            else:
                grid = _grid(tspan, t, t_end, model.default.get("stepSize") or (tf - t0) / 100.0)
                rec.add(adapter, run, grid[1:], np.zeros((grid.size - 1, 0)))
                t, state_event = t_end, False
                if adapter.nz:
                    message += " (its event indicators are read only at the output times: it has no states)"
            time_event = next_time is not None and t >= next_time
            step_event, terminate = adapter.completed_step()
            if not (state_event or time_event or step_event) or terminate:
                continue
            adapter.set_time_state(t, x)
            adapter.enter_event_mode()
            terminate, changed, next_time = adapter.event_iteration()
            before = dict(zip(names, map(float, x)))
            x = adapter.states() if changed else x
            kind = "state event" if state_event else "time event" if time_event else "step event"
            records.append({"name": kind, "index": 0 if state_event else 1, "occurrence": sum(
                r["name"] == kind for r in records), "t": t, "state": before,
                "reset": dict(zip(names, map(float, x)))})
            if terminate:  # as FMPy records it: the run ends at the event, its last row the one before
                break
            adapter.enter_continuous_mode()
            rec.add(adapter, run, t, x)
            marks.append(len(rec.t) - 1)
            if len(records) > MAX_EVENTS:
                status, message = "failed", f"the FMU had {MAX_EVENTS:,} events by t = {t:.10g}; stopped (chattering?)."
                break
        if terminate and t < tf:
            message = f"the FMU asked to stop at t = {t:.10g}."
    finally:
        adapter.close()
    return _integration(rec, run, Stats(*stats), status, message, warnings, records)


def _integration(rec: _Record, run: FmuRun, stats, status, message, warnings, records) -> tuple:
    t, x, y = rec.arrays()
    u = np.column_stack([np.asarray(s(t), dtype=float) * np.ones(t.size) for s in run.signals]) if run.signals \
        else None
    run.last = (t, y)
    mark = np.zeros(t.size, dtype=int)
    number = 0
    for i in range(1, t.size):  # a row repeating the time before it is the state after an event
        if t[i] == t[i - 1] and number < len(records) and records[number]["t"] == t[i]:
            number += 1
            mark[i] = number
    return t, x, u, stats, status, message, warnings, records, (mark if records else None)


def run_co_simulation(run: FmuRun, tspan, x0, method: str, options: dict):
    """A Co-Simulation FMU's run, one ``doStep`` per communication interval (see :func:`run_fmu`)."""
    model = run.model
    adapter = model.adapter("co-simulation")
    t0, tf = float(tspan[0]), float(tspan[-1])
    if tspan.size > 2:  # [time] points or output: the communication points
        grid = np.asarray(tspan, dtype=float)
        n = grid.size - 1
    else:
        h = float(options.get("h") or model.default.get("stepSize") or (tf - t0) / 500.0)
        n = int(np.ceil((tf - t0) / h - 1e-9))
        grid = t0 + h * np.arange(n + 1)
        grid[-1] = tf
    rec_t, rec_x, rec_y = [], [], []
    status, message = "success", f"the FMU's co-simulation reached t = {tf:g} in {n} communication steps."
    adapter.start(t0, options.get("rtol"), tf, {**run.values, **(run.inputs_at(t0) if run.signals else {})})
    try:
        def record(t):
            rec_t.append(float(t))
            rec_x.append(adapter.get(model.states) if model.states else np.zeros(0))
            rec_y.append(adapter.get(model.outputs) if model.outputs else np.zeros(0))

        record(grid[0])
        for k in range(n):
            t = float(grid[k])
            if run.signals:
                adapter.set(run.inputs_at(t))
            stopped = adapter.do_step(t, float(grid[k + 1]) - t)
            if stopped is not None:
                record(stopped)
                message = f"the FMU asked to stop at t = {stopped:.10g}."
                break
            record(grid[k + 1])
    except Exception as exc:  # an FMI call that failed: a failed case with the reason
        status, message = "failed", f"the FMU's doStep failed at t = {rec_t[-1]:.10g}: {exc}."
    finally:
        adapter.close()
    rec = _Record(len(model.states), len(model.outputs))
    rec.t, rec.x, rec.y = [np.array(rec_t)], [np.array(rec_x).reshape(len(rec_t), -1)], \
        [np.array(rec_y).reshape(len(rec_t), -1)]
    return _integration(rec, run, Stats(len(rec_t) - 1, 0, 0), status, message, [], [])


def run_fmu(run, x0, tspan, method: str, options: dict):
    """The runner's entry: an FMU case's run (``problem.system.fmu``) from ``x0`` on the interface the case
    chose, as the fields of :class:`odelab.store.result.Integration`: (t, x, u, stats, status, message,
    warnings, events, marks)."""
    if run.interface == "co-simulation":
        return run_co_simulation(run, tspan, x0, method, options)
    values = dict(run.values)
    for var, value in zip(run.model.states, x0):
        if var.initial != "calculated" and var.causality != "independent" and var.start is not None:
            values[var] = float(value)
    return _me_with(run, values, tspan, x0, method, options)


def _me_with(run: FmuRun, values: dict, tspan, x0, method, options):
    saved = run.values
    run.values = values
    try:
        return run_model_exchange(run, tspan, x0, method, options)
    finally:
        run.values = saved
