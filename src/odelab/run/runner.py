"""Running a case: solve, compute its reference, and measure the errors."""

from __future__ import annotations

import copy
import os
import time
import warnings
from pathlib import Path

import numpy as np

from odelab.analysis.errors import summarize
from odelab.exceptions import InputError, SolverWarning
from odelab.experiment.cases import Case, LoadedExperiment
from odelab.experiment.limits import capped_max_steps
from odelab.experiment.loader import load_experiment
from odelab.run.backend import (
    run_hybrid,
    run_stateless,
    simulate_problem,
    solve_events_problem,
    solve_problem,
)
from odelab.store.result import CaseResult, Integration
from odelab.solution import Stats
from odelab.solvers.options import given_options
from odelab.solvers.registry import REFERENCE_METHOD

__all__ = ["CaseResult", "run_case", "run_experiment"]


def _integrate(problem, tspan, method, options, backend="python", rows_to=None) -> Integration:
    """Solve (no inputs) or simulate (inputs, restarting at their discontinuities), a hybrid diagram or a run
    with [events]: one :class:`~odelab.store.result.Integration` whichever ran (its ``backend``: the engine,
    "python" or "compiled", see :mod:`odelab.run.backend`). ``options``: the case's resolved SolverOptions
    (``Problem.solver_options``), or a dict (a reference's). A failed integration is reported in
    the case's result, so the solvers' SolverWarning is not repeated here. ``rows_to``: the run's spool
    (:mod:`odelab.store.spool`), used by a plain problem's compiled solve (no inputs, events or diagram).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SolverWarning)
        if problem.system.fmu is not None:  # kind = "fmu": odelab's solvers step the FMU
            from odelab.fmi.simulate import run_fmu

            return Integration(*run_fmu(problem.system.fmu, problem.x0, tspan, method, given_options(options)))
        if problem.system.diagram is not None and not problem.system.diagram.states:
            return run_stateless(problem, tspan, options)
        if problem.system.diagram is not None and problem.system.diagram.hybrid:
            return run_hybrid(problem, tspan, method, options, backend)
        if problem.system.events is not None:
            (t, x, stats, status, message, warns, events, marks), ran = solve_events_problem(
                problem, tspan, method, options, backend)
            return Integration(t, x, None, stats, status, message, warns, events, marks, ran)
        return _integrate_quietly(problem, tspan, method, options, backend, rows_to)


def _integrate_quietly(problem, tspan, method, options, backend="python", rows_to=None):
    if problem.system.signals:
        r, ran = simulate_problem(problem, tspan, method, options, backend)
        return Integration(r.t, r.x, r.u, r.stats, r.status, r.message, (), backend=ran)

    try:
        sol, ran = solve_problem(problem, tspan, method, options, backend, rows_to)
    except InputError as exc:
        if exc.key != "fun":
            raise
        # The user's function returned something unusable (wrong shape, complex): a failed
        # case with the reason, like any other fault of the right-hand side.
        message = f"{method} could not start: {exc.message.replace('`fun`', 'the system function')}"
        return Integration(tspan[:1].copy(), problem.x0.reshape(1, -1), None, Stats(0, 0, 1), "failed", message)
    return Integration(sol.t, sol.y, None, sol.stats, sol.status, sol.message, sol.warnings, backend=ran)


def run_case(case: Case, *, max_steps: int | None = None, backend: str | None = None,
             estimate: bool | None = None, spool_in: Path | None = None) -> CaseResult:
    """Run one case and compute its error table (never raises for a failed integration).

    ``backend`` ("auto", "python", "compiled") overrides the case's ``[solver] backend``;
    ``estimate`` (True/False) the file's ``[solver] estimate_error`` (odelab.run.estimate).
    ``spool_in``: the results folder the case is going to be stored in (``odelab run --runs``): a long
    compiled run writes its rows beside the case's folder as its blocks fill (:mod:`odelab.store.spool`),
    its ``t`` and ``x`` are maps of them, and the store writes the case from them (``result.spool``).
    A run that raises (or is interrupted) removes its spool.
    """
    spool = _spool_for(case, spool_in)
    if spool is None:
        return _run_case(case, max_steps, backend, estimate, None)
    try:
        result = _run_case(case, max_steps, backend, estimate, spool)
    except BaseException:
        spool.discard()
        raise
    if spool.folder is not None:  # the run's rows are the spool's
        result.spool = spool
    return result


def _spool_for(case: Case, runs: Path | None):
    """The spool of a case that is going to be stored in its own folder under ``runs`` (None: in memory). A
    [sweep]'s cases stay in memory (a sweep may store only its table), as everywhere but POSIX (a file that
    is mapped cannot be removed on Windows)."""
    if runs is None or case.swept or os.name != "posix" or case.problem.linearize is not None:
        return None
    from odelab.store.results import case_dir
    from odelab.store.spool import Spool

    return Spool(case_dir(runs, case.experiment, case.name))


def _run_case(case: Case, max_steps: int | None, backend: str | None, estimate: bool | None,
              spool) -> CaseResult:
    p = case.problem
    if p.linearize is not None:
        from odelab.run.linearization import run_linearization_case

        return _drawings(run_linearization_case(case, max_steps=max_steps), p)
    options = p.solver_options  # resolved once, at load
    capped = False
    if max_steps and "h" not in p.options:
        budget, capped = capped_max_steps(p.options.get("max_steps"), max_steps)
        options = options.updated(max_steps=budget)
    start = time.perf_counter()
    run = _integrate(p, p.tspan, p.method, options, backend or p.backend, spool)
    t, x, u, stats, status, message, warnings = run.t, run.x, run.u, run.stats, run.status, run.message, run.warnings
    elapsed = time.perf_counter() - start
    if (status != "success" and max_steps and ("max_steps" not in p.options or capped) and "h" not in p.options
            and stats.nsteps >= max_steps):
        asked = p.options.get("max_steps")
        why = (f" ([solver] asks max_steps = {asked:,}{' (no limit)' if asked == 0 else ''}, but a file cannot lift "
               "the budget of whoever runs it)" if capped else "")
        message += (f" It was odelab run's step budget that stopped it (--max-steps, {max_steps} steps){why}: lift "
                    f"it with --max-steps {10 * max_steps if not capped or not asked else asked} (or --max-steps 0 "
                    "for no limit).")
    if u is None and p.system.input_fn is not None:
        u = p.system.input_fn(t)
    y = p.system.output_fn(t, x, u) if p.system.output_fn is not None else None
    from odelab.cachedir import take_notes

    # a cache that could not be used or an entry compiled again (odelab.cachedir): said once, with this case
    warnings = [*warnings, *take_notes()]
    from odelab.expressions.functions import shadowing_note

    warnings += shadowing_note(p.parameters)  # "parameter e shadows the constant e (2.718...)"
    warnings += [n for n in p.notes if n not in warnings]  # loading's: values converted from their units
    result = CaseResult(case=case, status=status, message=message, stats=stats, elapsed=elapsed, t=t, x=x, u=u,
                        y=y, warnings=list(warnings), events=run.events, event_marks=run.marks, backend=run.backend)
    result.record_input_jumps()
    if p.fit is not None:  # the experiment's [fit], estimated before its cases ran (experiment/fit.py)
        result.extra["fit"] = p.fit
    _reference(result, max_steps)
    from odelab.run.estimate import estimate_case, estimate_warning, wants_estimate

    if wants_estimate(result, estimate):  # a second solve at tighter tolerances (analysis/estimate.py)
        result.estimate = estimate_case(result, _integrate, max_steps, backend)
        if result.estimate.get("reasons"):
            result.warnings.append(estimate_warning(result.estimate))
        result.warnings.extend(result.estimate.get("notes", ()))  # differences that are a phase error
    if status == "success" and case.config.get("expect") in ("max-steps", "failure"):
        result.warnings.append(f"the file expects this case to stop (expect = {case.config['expect']!r}), but it "
                               "reached the end of its span: remove `expect` if that is now right.")
    _drawings(result, p)
    if p.analysis is not None:
        try:
            result.extra["analysis"] = analyze_problem(p)
        except InputError as exc:  # e.g. no equilibrium to linearise about
            result.warnings.append(f"[analysis] could not be computed: {exc.message}")
    return result


def _drawings(result: CaseResult, p) -> CaseResult:
    """A diagram's or a network's drawing (and a network's derivation) on its result, whatever ran the case
    (a [linearize] case too: the report draws the system it linearised)."""
    if p.system.diagram is not None:
        result.extra["diagram"] = diagram_record(p)
        result.warnings.extend(n for n in p.system.diagram.notes if n not in result.warnings)
    if p.system.network is not None:  # kind = "network": its drawing and derivation
        from odelab.experiment.kinds.network import network_record

        result.extra["network"] = network_record(p)
    return result


def diagram_record(p) -> dict:
    """What the report needs of a diagram: its drawing (DOT) and, if linear, its A, B, C, D."""
    from odelab.systems.diagram.draw import to_dot

    d = p.system.diagram
    record = {"linear": d.linear, "dot": to_dot(d.wiring), "states": list(d.states), "inputs": list(d.inputs),
              "outputs": list(d.outputs)}
    if d.linear and d.outputs:
        record.update(zip("ABCD", (M.tolist() for M in d.matrices())))
    return record


def analyze_problem(p) -> dict:
    """The [analysis] of a case's system: its own matrices if linear, else its linear model about
    the equilibrium for the operating input (exact Jacobians)."""
    from odelab.analysis.control import analyze
    from odelab.systems.statespace import StateSpace

    key = None if not isinstance(p.system.model, StateSpace) else (
        p.system.model.A.tobytes(), p.system.model.B.tobytes(), p.system.model.C.tobytes(), p.system.model.D.tobytes(), p.system.model.A.shape,
        p.system.model.B.shape, p.system.model.C.shape, p.system.model.states, p.system.model.inputs, p.system.model.outputs, repr(p.analysis))
    if key is not None and key in _ANALYSES:  # the cases of an experiment usually share their system
        return copy.deepcopy(_ANALYSES[key])
    system, point = p.system.model, None
    if not isinstance(system, StateSpace):
        from odelab.analysis.linearize import linearize

        system = linearize(system, u0=p.analysis["input"])
        op = system.operating_point
        point = {"x": dict(zip(op.states, op.x.tolist())), "u": dict(zip(op.inputs, op.u.tolist())),
                 "residual": op.residual}
    spec = p.analysis
    info = analyze(system, step_info=spec["step_info"], bode_range=spec["bode"], show_poles=spec["poles"],
                   linearized_at=point, with_margins=p.system.diagram is None)
    if spec.get("loop"):
        from odelab.analysis.control import loop_analysis

        op = getattr(system, "operating_point", None)
        x0 = op.x if op is not None else np.zeros(len(p.states))
        u0 = op.u if op is not None else np.zeros(len(p.inputs))
        info["loop"] = loop_analysis(p.system.diagram.open_loop(spec["loop"]), x0, u0, spec["loop"], spec["bode"])
    if key is not None:
        if len(_ANALYSES) > 64:
            _ANALYSES.clear()
        _ANALYSES[key] = copy.deepcopy(info)
    return info


_ANALYSES: dict = {}


def _reference(result: CaseResult, max_steps: int | None = None) -> None:
    p = result.case.problem
    t = result.t
    kind = p.reference
    ref: dict[str, np.ndarray] = {}
    if kind == "data":
        from odelab.experiment.data import data_reference

        data_reference(result, _integrate)
        return
    if kind == "none" or t.size < 2:
        return
    if kind == "exact":
        ref = p.system.exact_fn(t)
    elif kind == "lti" and np.all(np.diff(t) > 0):
        from odelab.analysis.lti import lti_response

        xr, yr = lti_response(p.system.model, t, p.x0, u=list(p.system.signals) if p.system.signals else None)
        ref = {name: xr[:, i] for i, name in enumerate(p.states)}
        ref.update({name: yr[:, i] for i, name in enumerate(p.outputs)})
    else:
        if kind == "lti":
            result.warnings.append("exact LTI reference needs increasing time; used a high-accuracy one instead")
            kind = "high-accuracy"
        solver, rtol, atol = p.reference_solver
        from odelab.run.reference import can_share, shared_reference

        if can_share(p):  # one stiff-aware, bounded solve shared by the problem's cases
            shared = shared_reference(result.case, max_steps)
            if shared.status != "success":
                result.warnings.append(f"the high-accuracy reference ({shared.solver}, rtol {rtol:g}) failed: "
                                       f"{shared.message}")
                return
            if shared.note:
                result.warnings.append(f"reference: {shared.note}")
            rt, rx, ru = t, shared.values(t), None
        else:
            options = {"rtol": rtol, "atol": atol, **({"max_steps": max_steps} if max_steps else {})}
            solver = REFERENCE_METHOD if solver == "auto" else solver
            ran = _integrate(p, t, solver, options)
            rt, rx, ru = ran.t, ran.x, ran.u
            if ran.status != "success" or rt.size != t.size:
                result.warnings.append(f"the high-accuracy reference ({solver}, rtol {rtol:g}) failed: {ran.message}")
                return
        ref = {name: rx[:, i] for i, name in enumerate(p.states)}
        if p.system.output_fn is not None:
            if ru is None and p.system.input_fn is not None:
                ru = p.system.input_fn(rt)
            ry = p.system.output_fn(rt, rx, ru)
            ref.update({name: ry[:, i] for i, name in enumerate(p.outputs)})
    result.reference_kind = kind
    series = result.series()
    for name, values in ref.items():
        result.reference[name] = np.asarray(values, dtype=float)
        result.errors[name] = summarize(name, t, series[name], result.reference[name])
    undefined = [f"{n} ({e.undefined})" for n, e in result.errors.items() if e.undefined]
    if undefined:
        result.warnings.append(
            "relative error undefined where the reference is zero or tiny, at the number of points shown: "
            + ", ".join(undefined) + "; left out of the maximum")


def run_experiment(path_or_experiment, *, max_steps: int | None = None, backend: str | None = None,
                   estimate: bool | None = None) -> list[CaseResult]:
    """Load (if given a path) and run every case of an experiment."""
    exp = path_or_experiment if isinstance(path_or_experiment, LoadedExperiment) else load_experiment(path_or_experiment)
    return [run_case(case, max_steps=max_steps, backend=backend, estimate=estimate) for case in exp.cases]
