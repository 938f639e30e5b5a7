"""A case's global error estimate: the second solve at tighter tolerances, aligned with the first.

:func:`estimate_case` solves the case again with the same method at ``RelTol`` and ``AbsTol``
divided by :data:`odelab.analysis.estimate.ESTIMATE_FACTOR` (a fixed-step method at ``h/2``),
with output at the run's own output times, and hands both to
:func:`odelab.analysis.estimate.compare_solves`. Rows where the two cannot be compared are left
out: with [events], the times between an event of the run and the same event of the tighter
solve (the jump happened in one and not yet in the other), and everything after the first event
the two do not share. What is on by default, and its cost: docs/guide/trust.md.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from odelab.exceptions import InputError, SolverWarning
from odelab.solvers.registry import get_method
from odelab.store.spool import release, take

__all__ = ["estimate_case", "estimate_warning", "wants_estimate", "UNRELIABLE"]

#: How a warning about an unreliable result begins (the terminal and the report find it by it).
UNRELIABLE = "unreliable (the error estimate): "

ADVICE = ("Try a tighter AbsTol for the quantities that are small against their tolerance, NonNegative for "
          "quantities that cannot go below zero, or another stiff method (ode15s, ode23tb, Radau), and compare.")


def estimate_warning(estimate: dict) -> str:
    """The one warning of an unreliable result: each quantity's reason, then what to try."""
    *reasons, advice = estimate["reasons"]
    return UNRELIABLE + "; ".join(reasons) + ". " + advice


def wants_estimate(result, asked: bool | None) -> bool:
    """Whether this case gets an estimate: ``asked`` (``--estimate`` / ``--no-estimate``), else the file's
    ``[solver] estimate_error``, else on for a case whose errors are not known (no reference) and that is
    not one of a [sweep]'s cases (a sweep of a thousand cases would take twice as long unasked)."""
    case = result.case
    if case.problem.linearize is not None or result.status != "success":
        return False
    if asked is not None:
        return asked
    given = (case.config.get("solver") or {}).get("estimate_error")
    if given is not None:
        return bool(given)
    return not result.errors and not case.swept


def estimate_case(result, integrate, max_steps: int | None = None, backend: str | None = None) -> dict:
    """The estimate of ``result``'s errors (JSON-ready: :meth:`ErrorEstimate.as_dict` plus the second
    solve's cost), or ``{"skipped": why}``. ``integrate(problem, tspan, method, options, backend)`` is
    the runner's solve."""
    from odelab.analysis.estimate import ESTIMATE_FACTOR  # only for a case that gets an estimate: not at start-up

    p = result.case.problem
    if p.system.diagram is not None and p.system.diagram.hybrid:
        return {"skipped": "a hybrid diagram's switching instants move with the tolerances; compare a case at a "
                           "tighter rtol"}
    method = get_method(p.method)
    case = p.solver_options  # the options the run had, resolved once at load
    changes: dict = {}
    if max_steps and method.adaptive:  # the tighter solve takes more steps (10^(1/2)x at order 1): its own budget
        changes["max_steps"] = 10 * max_steps
    if not method.adaptive:
        changes["h"] = case.h / 2
        factor, proportion, rtol = 2.0, 2.0 ** method.order, None
        from odelab.experiment.limits import fixed_step_count

        steps = fixed_step_count(np.asarray(p.tspan, dtype=float), changes["h"])
        if max_steps and steps > max_steps:
            return {"skipped": f"h/2 takes {steps:,} steps, over the run's budget of {max_steps:,} steps per solve "
                               "(--max-steps)"}
    else:
        rtol = float(case.given.get("rtol", case.rtol))  # as asked (the solve raises one below 100 eps)
        atol = np.asarray(case.atol, dtype=float)
        changes["rtol"] = rtol / ESTIMATE_FACTOR
        changes["atol"] = (atol / ESTIMATE_FACTOR).tolist() if atol.ndim else float(atol) / ESTIMATE_FACTOR
        factor = proportion = ESTIMATE_FACTOR
    t = np.asarray(result.t, dtype=float)
    refine = case.refine
    candidates = None  # the run's rows that can be compared (None: all)
    if p.tspan.size == 2 and refine > 1 and not result.events and _strictly_monotonic(t):
        # Refine output: compared at the steps' ends, where the method's own solution is (the points between
        # are its interpolant's; a vector tspan of them all would cost the second solve one interpolation each)
        candidates = np.arange(0, t.size, refine)
        if (t.size - 1) % refine:
            candidates = np.append(candidates, t.size - 1)
        times = take(t, candidates)
    else:
        times = np.unique(t)
        if t.size > 1 and t[-1] < t[0]:
            times = times[::-1]
    if times.size < 2:
        return {"skipped": "the run has a single output time"}
    if times.size == 2:  # a two-element tspan would mean Refine output: ask for a midpoint too
        times = np.array([times[0], 0.5 * (times[0] + times[1]), times[1]])

    start = time.perf_counter()
    try:
        options = case.updated(**changes)  # resolved again: the tighter solve's options
        if result.backend == "compiled" and _plain(p, method):
            # the run's own engine, with output at the compared times: no step's stages kept for an interpolant
            ran = integrate(p, times, p.method, options, "compiled")
        else:
            ran = (_dense_solve(p, times, method, options)
                   or integrate(p, times, p.method, options, backend or p.backend))
    except InputError as exc:  # e.g. h/2 over the run's step budget: no estimate, and why
        return {"skipped": f"the solve at {'h/2' if not method.adaptive else 'tighter tolerances'} could not run: "
                           f"{exc.message}"}
    elapsed = time.perf_counter() - start
    stats = {"nsteps": ran.stats.nsteps, "elapsed_s": elapsed}
    if ran.status != "success":
        return {"skipped": f"the solve at tolerances {factor:g} times tighter did not finish: {ran.message}",
                "tight": stats}
    rows, tight_rows = _aligned(result, ran, candidates)
    del times, candidates
    if rows.size == 0:
        return {"skipped": "no output time of the run could be compared with the tighter solve", "tight": stats}
    tight_series = _series(p, ran)
    # contiguous (a column of the solve's rows is strided): compare_solves' phase check takes windows of them
    # point by point (np.interp, searchsorted), which would copy a strided array at each point
    tight_values = {n: np.ascontiguousarray(np.asarray(v)[tight_rows]) for n, v in tight_series.items()}
    del ran, tight_series  # what is left of the tighter solve is what is compared (a long run's arrays)
    # gathered a block at a time: a spooled run's maps hand their pages back (odelab.store.spool)
    run_values = {n: take(v, rows) for n, v in result.series().items() if n in tight_values}
    atol_map = None
    if rtol is not None:
        atol = np.broadcast_to(np.asarray(case.atol, dtype=float), (len(p.states),))
        atol_map = {name: float(a) for name, a in zip(p.states, atol)}
    from odelab.analysis.estimate import compare_solves

    est = compare_solves(take(t, rows), run_values, tight_values, factor=factor, proportion=proportion, rtol=rtol,
                         atol=atol_map, advice=ADVICE)
    out = est.as_dict()
    out["tight"] = stats
    out["method"] = p.method
    if not method.adaptive:
        out["rule"] = f"h/2 (order {method.order}: the error e ~ |y_h - y_h/2| 2^p/(2^p - 1))"
    else:
        out["rule"] = (f"RelTol and AbsTol / {ESTIMATE_FACTOR:g}, same method (the error e ~ |y - y_tight| F/(F - 1), "
                       "F = 10)")
    return out


def _dense_solve(p, times: np.ndarray, method, options):
    """The tighter solve of a plain problem (no inputs, events or diagram) by a method with dense output:
    solved over the span and evaluated at ``times`` by its interpolant (``deval``, one vectorised call),
    cheaper than output at every time step by step. None where that does not apply."""
    if not method.dense_output or not _plain(p, method):
        return None

    from odelab.solvers.api import solve
    from odelab.store.result import Integration

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SolverWarning)
            sol = solve(p.system.fun, [float(times[0]), float(times[-1])], p.x0, method=p.method,
                        resolved=options.updated(refine=1))
    except InputError:
        return None
    if sol.status != "success" or sol.interpolant is None:
        return Integration(sol.t, sol.y, None, sol.stats, sol.status if sol.status != "success" else "failed",
                           sol.message)
    return Integration(times, np.asarray(sol.deval(times)).reshape(times.size, -1), None, sol.stats, sol.status,
                       sol.message)


def _plain(p, method) -> bool:
    """A plain problem (no inputs, events, diagram, FMU or residual form) solved by an adaptive method."""
    system = p.system
    return not (system.signals or system.events is not None or system.diagram is not None or system.fmu is not None
                or not method.adaptive or getattr(system.fun, "residual", None) is not None or not callable(system.fun))


def _strictly_monotonic(t: np.ndarray) -> bool:
    """Whether ``t`` has no repeated time (increasing or decreasing), checked a block at a time: no
    temporary the size of a long run's output."""
    if t.size < 2:
        return True
    sign = 1.0 if t[-1] >= t[0] else -1.0
    block = 1 << 16
    for lo in range(0, t.size - 1, block):
        piece = t[lo:lo + block + 1]
        if not np.all(sign * np.diff(piece) > 0):
            return False
        release(t)  # a spooled run's map: its pages handed back
    return True


def _series(p, ran) -> dict[str, np.ndarray]:
    out = {name: ran.x[:, i] for i, name in enumerate(p.states)}
    if p.system.output_fn is not None:
        u = ran.u if ran.u is not None else (p.system.input_fn(ran.t) if p.system.input_fn is not None else None)
        y = p.system.output_fn(ran.t, ran.x, u)
        out.update({name: y[:, i] for i, name in enumerate(p.outputs)})
    return out


def _aligned(result, ran, candidates: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | slice]:
    """Row indices of the run and of the tighter solve at the same times, leaving out what cannot be
    compared around events (the rows between an event of one and the same event of the other).
    ``candidates``: the only rows of the run that can match (the steps' ends of Refine output), or None.
    Where the tighter solve's times are the run's (compared) times, in order, its rows are all of them
    (``slice(None)``)."""
    t, tt = np.asarray(result.t, dtype=float), np.asarray(ran.t, dtype=float)
    if candidates is not None:
        t = take(t, candidates)
    run_events = [e["t"] for e in (result.events or [])]
    tight_events = [e["t"] for e in (ran.events or [])]
    if not run_events and not tight_events and np.array_equal(t, tt):  # output at the run's compared times
        return (np.arange(t.size) if candidates is None else candidates), slice(None)
    tdir = 1.0 if t[-1] >= t[0] else -1.0
    order = np.argsort(tdir * tt, kind="stable")
    sorted_t = tdir * tt[order]
    pos = np.searchsorted(sorted_t, tdir * t, side="left")
    pos = np.clip(pos, 0, max(tt.size - 1, 0))
    match = tt[order[pos]] == t if tt.size else np.zeros(t.size, dtype=bool)
    keep = match.copy()
    # a duplicated time (an event's jump) in the run: the first row is before the jump, as is the tighter
    # solve's value there only if its event is not earlier; the windows below leave those rows out
    shared = min(len(run_events), len(tight_events))
    for a, b in zip(run_events[:shared], tight_events[:shared]):
        lo, hi = min(a, b), max(a, b)
        keep &= ~((t >= lo) & (t <= hi))
    if len(run_events) != len(tight_events):
        cut = run_events[shared] if len(run_events) > shared else tight_events[shared]
        keep &= tdir * (t - cut) < 0
    rows = np.flatnonzero(keep)
    return (rows if candidates is None else candidates[rows]), order[pos[rows]]
