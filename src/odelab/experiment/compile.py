"""Compiling one validated case into the :class:`~odelab.experiment.cases.Problem` a runner solves.

The case's system is built (equations, state space, diagram, network or a Python function),
then its initial state, time span, inputs, solver options, [events], [data], the compiled
backend, the exact solution and reference, [units], [linearize], [analysis] and [report],
each checked with a message naming its key. Beside the Problem, ``resolved`` is the case's
configuration with every default filled in: stored as ``resolved.toml``, it reproduces the run.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.cases import Problem
from odelab.experiment.fields import check_keys, constant, expr
from odelab.experiment.limits import DEFAULT_LIMITS, Limits, check_count, check_solve
from odelab.experiment.section_checks import (check_analysis, check_jacobian, check_linearize, check_report,
                                              check_units)
from odelab.solvers.optionset import DEFAULT_ATOL, DEFAULT_RTOL
from odelab.solvers.registry import get_method, join_names, methods_with
from odelab.systems.system import System

__all__ = ["compile_case"]


def compile_case(model: schema.Experiment, path: Path, *, limits: Limits = DEFAULT_LIMITS,
                 shared: dict | None = None) -> tuple[Problem, dict]:
    """Compile a validated case into a :class:`Problem` and its resolved configuration.

    ``shared`` (a dict kept across the cases of one file) lets cases that share the base's
    validated [system] and [time] (see ``loader._validated_sections``) share their builds.
    """
    model, notes = with_units_converted(model)
    params = expr().evaluate_parameters(model.parameters) if model.parameters else {}
    system = model.system
    resolved: dict[str, Any] = {}
    if model.title:
        resolved["title"] = model.title
    if model.description:
        resolved["description"] = model.description
    if model.expect is not None:
        resolved["expect"] = model.expect
    if model.plot is not None:
        resolved["plot"] = _plain(model.plot.model_dump(exclude_none=True))
    if model.report is not None:
        resolved["report"] = check_report(model.report)
    if params:
        resolved["parameters"] = dict(params)
    params_key = tuple(sorted(params.items()))
    built = _build_system(model, path, params, params_key, limits, shared)
    states, inputs, outputs = built.states, built.inputs, built.outputs
    resolved["system"] = dict(built.resolved)

    # initial state (a diagram's blocks carry theirs; [initial] may override some; an implicit
    # system's also guesses der() values and says what decic may not change: experiment/kinds/implicit.py)
    from odelab.experiment.kinds.implicit import consistent_start, is_implicit_system, split_initial

    implicit = is_implicit_system(built)
    initial, slopes, fixed = split_initial(model.initial, states, implicit)
    check_keys(initial, states, "initial", "states", require_all=built.x0 is None)
    x0 = np.array([constant(initial[s], f"initial.{s}", params) if s in initial else built.x0[i]
                   for i, s in enumerate(states)], dtype=float)
    resolved["initial"] = {s: float(v) for s, v in zip(states, x0)}
    tspan, resolved["time"] = _case_tspan(model, params, params_key, limits, shared)
    signals, input_fn = _case_inputs(model, built, path, tspan, limits, resolved)
    method, options, backend, solver_options = _case_solver(model, built, params, tspan, limits, resolved)
    if implicit:  # decic: consistent x0 and x'0 at load time, or the file's keys to change

        x0, fun, _ = consistent_start(model, built, x0, slopes, fixed, params, float(tspan[0]), options, resolved)
        built = replace(built, fun=fun)
    events = _case_events(model, method, inputs, states, params, limits, resolved)
    data = _case_data(model, events, path, states, outputs, tspan, resolved)
    fast = built.compiled  # the compiled backend's system, its inputs driven by the signals
    if fast is not None and fast.inputs:
        fast = fast.with_signals(signals)
    if fast is not None and events is not None:
        fast = fast.with_events([w for w, _ in events.whens], events.terminal, events.direction, params,
                                [k for _, k in events.whens])
    if backend != "auto":
        resolved["solver"]["backend"] = backend
        from odelab.solvers.compiled.capability import check_backend

        check_backend(backend, method, fast, "solver.backend", options, events)
    if method.matlab_defaults:
        resolved["solver"].setdefault("rtol", DEFAULT_RTOL)
        resolved["solver"].setdefault("atol", DEFAULT_ATOL)
    if system.kind == "ode" and system.jacobian is not None and built.jacobian is not None:
        check_jacobian(built.jacobian, system, states, params, float(tspan[0]), x0)
    if "jacobian" in method.options and built.jacobian is not None:
        # The stiff solvers get the exact Jacobian of a known system, never finite differences (it is in the
        # resolved options since _case_solver)
        resolved["solver"]["jacobian"] = getattr(built.jacobian, "source", "the A matrix")
    exact_fn, kind = _case_reference(model, built, method, signals, events, data, params, resolved)
    if model.units:
        resolved["units"] = check_units(model.units, states, inputs, outputs, params)
    given = tuple(s for s in states if s in (model.initial or {}))
    linearize = model.linearize
    if linearize is not None:
        check_linearize(linearize, states, inputs, outputs, built)
        if linearize.amplitudes is not None:
            check_count("amplitudes", len(linearize.amplitudes), "linearize.amplitudes", "amplitudes", limits)
        if "start" not in linearize.model_fields_set:  # from the file's [initial] if it gives one (issue 37)
            linearize = linearize.model_copy(update={"start": "initial" if given else "operating-point"})
        resolved["linearize"] = _plain(linearize.model_dump(exclude_none=True))
    analysis = None
    if model.analysis is not None:
        analysis = check_analysis(model.analysis, inputs, built, params)
        resolved["analysis"] = _plain({k: v for k, v in model.analysis.model_dump(by_alias=True).items()
                                       if v is not None})
    ref = model.reference
    case_system = System(
        states=states, inputs=inputs, outputs=outputs, fun=built.fun, output_fn=built.output_fn, input_fn=input_fn,
        jacobian=built.jacobian, signals=signals, events=events, exact_fn=exact_fn, linear=built.linear,
        model=built.model, compiled=fast, diagram=built.diagram, network=built.network,
        fmu=_bound_fmu(built.fmu, signals))
    problem = Problem(
        system=case_system, tspan=tspan, x0=x0, method=method.name, solver_options=solver_options,
        reference=kind, reference_solver=(ref.solver, float(ref.rtol), float(ref.atol)), linearize=linearize,
        parameters=params, backend=backend, analysis=analysis, data=data, initial_given=given, notes=tuple(notes),
    )
    return problem, resolved


def with_units_converted(model: schema.Experiment) -> tuple[schema.Experiment, list[str]]:
    """[parameters], [initial] and [time] values written with a unit (``L = "100 cm"``) as plain numbers:
    in the unit [units] declares for the name (``t`` for [time]), else in SI (odelab.expressions.units).
    Returns the model with the numbers and one note per conversion."""
    sections = {"parameters": model.parameters or {}, "initial": model.initial or {}}
    time = {k: getattr(model.time, k) for k in ("start", "stop")} if model.time is not None else {}
    texts = [v for table in (*sections.values(), time) for v in table.values() if isinstance(v, str)]
    if not texts:  # numbers only: the units module is not even imported
        return model, []
    from odelab.expressions.units import split_unit_value

    if not any(split_unit_value(v) for v in texts):
        return model, []  # pint is imported only when a unit appears
    from odelab.expressions.units import convert

    units = model.units or {}
    notes: list[str] = []
    update: dict[str, Any] = {}

    def converted(table: dict, section: str, declared) -> dict:
        out = dict(table)
        for name, value in table.items():
            if split_unit_value(value) is None:
                continue
            try:
                unit = convert(name, value, declared(name), f"`{section}.{name}`")
            except InputError as exc:
                raise ExperimentError(exc.message, key=f"{section}.{name}") from None
            out[name] = unit.value
            notes.append(f"{section}.{unit.note(name)}")
        return out

    for section, table in sections.items():
        new = converted(table, section, units.get)
        if new != table:
            update[section] = new
    if time:
        new = converted(time, "time", lambda name: units.get("t", "s"))
        if new != time:
            update["time"] = model.time.model_copy(update=new)
    return model.model_copy(update=update), notes


def _bound_fmu(run, signals):
    """An FMU case's run with its inputs' signals bound (kind = "fmu")."""
    if run is not None:
        run.signals = tuple(signals)  # built for this case alone: its output_fn reads this run
    return run


def _build_system(model: schema.Experiment, path: Path, params: dict, params_key: tuple, limits: Limits,
                  shared: dict | None):
    """The case's :class:`~odelab.experiment.cases.Built` system, by its kind.

    A system table that the case does not change is shared with the base (see merge): it is
    built once per file and parameter values, not once per case. (Keys hold the model's id;
    the value keeps the model alive, so the id cannot be reused.)
    """
    system = model.system
    share = None
    if shared is not None and system.kind in ("state-space", "ode") and system.function is None \
            and model.blocks is None:
        share = ("system", id(system), params_key, model.linearize is not None)
    if system.kind in ("ode", "state-space") and system.states and not limits.allows("states", len(system.states)):
        # name the missing initial values first (that is the file's mistake), then the budget
        check_keys(model.initial, tuple(system.states), "initial", "states", require_all=True)
        check_count("states", len(system.states), "system.states", "states", limits)
    if system.residuals is not None and system.kind != "implicit":
        raise ExperimentError("[system.residuals] (F = 0 with der(x) for x') is given but the system is not implicit: "
                              "add kind = \"implicit\" under [system] (solved by ode15i), or write "
                              "[system.equations] for x' = f(t, x).", key="system.residuals")
    if share is not None and share in shared:
        built = shared[share][1]
    elif system.kind == "state-space":
        from odelab.experiment.build import build_state_space

        built = build_state_space(model, params)
    elif system.kind == "implicit":
        from odelab.experiment.kinds.implicit import build_implicit

        built = build_implicit(model, params)
    elif system.kind == "diagram":
        from odelab.experiment.kinds.diagram import build_diagram

        built = build_diagram(model, params, path, constant(model.time.start, "time.start", params),
                              max_rows=limits.table_rows or None, limits=limits)
    elif system.kind == "network":
        from odelab.experiment.kinds.network import build_network

        built = build_network(model, params)
    elif system.kind == "fmu":
        from odelab.experiment.kinds.fmu import build_fmu

        built = build_fmu(model, params, path, limits)
    elif system.file is not None or system.interface is not None:
        key = "system.file" if system.file is not None else "system.interface"
        raise ExperimentError(f"`{key}` is for an FMU: add kind = \"fmu\" under [system], or remove it.", key=key)
    elif model.elements is not None:
        raise ExperimentError("[elements] is given but the system is not a network: add kind = \"network\" under "
                              "[system].", key="elements")
    elif model.blocks is not None:
        raise ExperimentError("[blocks] is given but the system is not a diagram: add kind = \"diagram\" under "
                              "[system].", key="blocks")
    elif system.function is not None:
        from odelab.experiment.build import build_function_system

        built = build_function_system(model, path)
    else:
        from odelab.experiment.build import build_ode

        built = build_ode(model, params)
    if share is not None:
        shared[share] = (system, built)
    return built


def _case_tspan(model: schema.Experiment, params: dict, params_key: tuple, limits: Limits,
                shared: dict | None) -> tuple[np.ndarray, dict]:
    """The output times (read-only: shared by the cases that leave [time] alone) and the resolved [time]."""
    time_share = ("time", id(model.time), params_key, limits) if shared is not None else None
    if time_share is not None and time_share in shared:
        tspan, time_resolved = shared[time_share][1]
    else:
        tspan, time_resolved = _tspan(model.time, params, limits)
        tspan.flags.writeable = False  # shared by the cases that leave [time] alone
        if time_share is not None:
            shared[time_share] = (model.time, (tspan, time_resolved))
    return tspan, dict(time_resolved)


def _case_inputs(model: schema.Experiment, built, path: Path, tspan: np.ndarray, limits: Limits,
                 resolved: dict) -> tuple[tuple, Any]:
    """The input signals and u(t): a diagram's source blocks, or one [inputs] signal per declared input."""
    inputs = built.inputs
    signals: tuple = ()
    input_fn = None
    if built.signals:
        signals = built.signals
        resolved["blocks"] = _plain(model.blocks)
        from odelab.systems.fields import SignalColumns

        input_fn = SignalColumns(signals)
    elif built.diagram is not None:
        resolved["blocks"] = _plain(model.blocks)
    elif inputs:
        from odelab.experiment.build import build_inputs

        signals, input_fn, resolved["inputs"] = build_inputs(model, inputs, path, tspan,
                                                             max_rows=limits.table_rows or None)
    elif model.inputs:
        raise ExperimentError(
            "[inputs] is given but the system declares no inputs: add `inputs = [...]` under [system].",
            key="inputs")
    return signals, input_fn


def _case_solver(model: schema.Experiment, built, params: dict, tspan: np.ndarray, limits: Limits,
                 resolved: dict):
    """The method, the options it runs with (state names made indices, a mass matrix evaluated), the backend and
    the options resolved once (with the exact Jacobian the stiff solvers are given below), for the run."""
    from odelab.experiment.kinds.delays import check_delay_method, method_name
    from odelab.solvers.options import as_tspan, normalize_options, resolve_options

    from odelab.experiment.kinds.implicit import implicit_method_name

    states = built.states
    method = get_method(implicit_method_name(model, built, method_name(model, built)), key="solver.method")
    check_delay_method(model, built, method)  # lag(...) runs with dde23 only (experiment/delays.py)
    options = {k: v for k, v in model.solver.model_dump().items()
               if k not in ("method", "backend", "zero_crossing", "estimate_error") and v is not None}
    backend = model.solver.backend
    runtime_options = _state_options(options, states, params, dae=method.dae,
                                     takes_dependence="mstate_dependence" in method.options)
    given = dict(runtime_options)
    if "jacobian" in method.options and built.jacobian is not None:
        given["jacobian"] = built.jacobian  # as the options the case runs with get it (build_case)
    try:
        as_tspan(tspan)
        solver_options = resolve_options(method, normalize_options(given, method), tspan, len(states))
    except InputError as exc:
        raise ExperimentError(exc.message.replace(f"`{exc.key}`", f"`solver.{exc.key}`"),
                              key=f"solver.{exc.key}" if exc.key else "solver") from None
    check_solve(fixed_step=not method.adaptive, tspan=tspan, options=solver_options.given,
                refine_default=getattr(method, "refine", 1) or 1, limits=limits)
    resolved["solver"] = {"method": method.name, **_plain(options)}
    if model.solver.estimate_error is not None:  # read by odelab.run.estimate
        resolved["solver"]["estimate_error"] = model.solver.estimate_error
    return method, runtime_options, backend, solver_options


def _case_events(model: schema.Experiment, method, inputs, states, params: dict, limits: Limits, resolved: dict):
    """[events] compiled, after checking that the method locates events and the case allows them."""
    if model.events is None:
        return None
    from odelab.experiment.events import compile_events

    if not method.events:
        raise ExperimentError(f"[events] are located by {join_names(methods_with(lambda m: m.events))} (MATLAB's "
                              f"Events); `solver.method` is {method.name!r}.", key="solver.method")
    if inputs or model.linearize is not None:
        raise ExperimentError("[events] work with systems without [inputs] and without [linearize]; remove one "
                              "of them.", key="events")
    if model.reference.method not in ("auto", "exact", "none"):
        raise ExperimentError(f"`reference.method` is {model.reference.method!r}, but with [events] the reference "
                              "is \"exact\" (from [exact]) or \"none\"; event times can have exact values with "
                              "`exact` in the event's table.", key="reference.method")
    events, resolved["events"] = compile_events(model.events, states, params, limits)
    return events


def _case_data(model: schema.Experiment, events, path: Path, states, outputs, tspan: np.ndarray, resolved: dict):
    """[data]: the measurements that are the reference of every case."""
    if model.data is None:
        return None
    from odelab.experiment.data import check_span, read_data

    if events is not None or model.linearize is not None:
        raise ExperimentError("[data] is the reference of a plain simulation; a case with [events] or "
                              "[linearize] cannot be compared with measurements yet: remove one of them.",
                              key="data")
    data = read_data(model.data, path, tuple(states) + tuple(outputs))
    check_span(data, tspan)
    resolved["data"] = data.as_dict()
    return data


def _case_reference(model: schema.Experiment, built, method, signals, events, data, params: dict,
                    resolved: dict):
    """The exact solution (a function of t, from [exact]) and the kind of reference errors are measured against."""
    states, outputs = built.states, built.outputs
    exact_fn = None
    if model.exact is not None:
        check_keys(model.exact, states + outputs, "exact", "states and outputs", require_all=False)
        from odelab.systems.fields import ExactSolution

        exact_fn = ExactSolution({name: expr().compile_expression(text, names=["t", *params], key=f"exact.{name}")
                                  for name, text in model.exact.items()}, params)

        resolved["exact"] = {k: v for k, v in model.exact.items()}
    ref = model.reference
    kind = ref.method
    if kind == "auto" and data is not None:
        kind = "data"  # measurements are the reference of every case
    if kind == "auto":
        kind = "exact" if exact_fn else ("lti" if built.linear and _all_exact(signals) and events is None else "none")
    from odelab.experiment.kinds.implicit import check_implicit_case

    check_implicit_case(model, built, method, kind)  # ode15i and implicit systems only together
    if kind == "exact" and exact_fn is None:
        raise ExperimentError("`reference.method` is \"exact\" but the file has no [exact] section: add one, "
                              "or use \"high-accuracy\".", key="reference.method")
    if kind == "lti" and not built.linear:
        raise ExperimentError("`reference.method` is \"lti\" but the system is not a linear state-space "
                              "model: use \"high-accuracy\".", key="reference.method")
    if kind == "lti" and not _all_exact(signals):
        kind = "high-accuracy"
    if ref.solver != "auto":
        get_method(ref.solver, key="reference.solver")
    if method.delays:
        from odelab.experiment.kinds.delays import check_delay_case

        check_delay_case(model, method, kind)
    resolved["reference"] = {"method": kind, "solver": ref.solver, "rtol": ref.rtol, "atol": ref.atol}
    return exact_fn, kind


def _state_options(options: dict, states: tuple[str, ...], params: dict[str, float], dae: bool = False,
                   takes_dependence: bool = True) -> dict:
    """[solver] options written with state names or expressions, made what the solver takes.

    ``nonnegative = ["h"]`` becomes 0-based indices; ``mass`` (a matrix of expressions of t, the
    states and the parameters) becomes a constant matrix, or ``M(t, y)`` if it uses t or a state.
    """
    out = dict(options)
    if "nonnegative" in out:
        names = out["nonnegative"]
        for i, name in enumerate(names):
            if name not in states:
                close = difflib.get_close_matches(name, states, n=1)
                hint = f" Did you mean {close[0]!r}?" if close else ""
                raise ExperimentError(f"`solver.nonnegative[{i}]` is {name!r}, not a state ({', '.join(states)}).{hint}",
                                      key=f"solver.nonnegative[{i}]")
        out["nonnegative"] = [states.index(name) for name in names]
    if "mass" in out:
        rows = out["mass"]
        n = len(states)
        if not (isinstance(rows, list) and len(rows) == n and all(isinstance(r, list) and len(r) == n for r in rows)):
            raise ExperimentError(f"`solver.mass` must be a {n}-by-{n} matrix (one row per state), e.g. "
                                  f"{[[1 if i == j else 0 for j in range(n)] for i in range(n)]}.", key="solver.mass")
        ex = expr()
        texts = [v for row in rows for v in row]
        keys = [f"solver.mass[{i}][{j}]" for i in range(n) for j in range(n)]
        try:
            out["mass"] = np.array([constant(v, k, params) for v, k in zip(texts, keys)]).reshape(n, n)
            if not dae and np.linalg.matrix_rank(out["mass"]) < n:
                raise ExperimentError("`solver.mass` is singular: M y' = f with a singular M is a differential-"
                                      "algebraic equation (DAE), which ode45/ode23 cannot solve (MATLAB uses ode15s "
                                      "or ode23t).", key="solver.mass")
        except ExperimentError:
            raise
        except InputError:  # uses t or a state: a function M(t, y)
            F = ex.compile_vector(texts, args=["t", *states], constants=params, keys=keys)

            def mass(t, y, _F=F, _n=n):
                return np.asarray(_F(t, *y), dtype=float).reshape(_n, _n)

            out["mass"] = mass
            if takes_dependence:  # the stiff solvers refuse a mass function themselves, naming the mass
                out.setdefault("mstate_dependence", "weak")
    return out


def _all_exact(signals) -> bool:
    return all(s.exact_terms() is not None for s in signals)


def _plain(value):
    """Make a value TOML-writable (tuples to lists, numpy scalars to floats)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _matlab_range(text: str, params: dict[str, float], limits: Limits) -> np.ndarray:
    """``time.output = "0:0.1:15"``: MATLAB's colon range (start:step:stop or start:stop) as output times."""
    from odelab.expressions.matlab import colon_range, range_parts

    parts = range_parts(text)
    if parts is None:
        raise ExperimentError(f"`time.output` is {text!r}; give a list of times ([0, 0.5, 1]) or a MATLAB range "
                              "such as \"0:0.1:15\" (start:step:stop).", key="time.output")
    a, d, b = (constant(p, "time.output", params) for p in parts)
    if d == 0 or (b - a) * d < 0:
        raise ExperimentError(f"`time.output` is {text!r}: the step {d:g} never reaches {b:g} from {a:g}; "
                              "give a step with the sign of stop - start.", key="time.output")
    count = abs((b - a) / d) + 1 if math.isfinite(b - a) else math.inf
    if not math.isfinite(count):  # a subnormal step, or a span past the largest float
        raise ExperimentError(f"`time.output` is {text!r}: from {a:g} to {b:g} in steps of {d:g} is more output "
                              "times than can be counted; take a larger step, or give time.points.",
                              key="time.output")
    check_count("points", int(count), "time.output", "output times", limits)
    return colon_range(a, d, b)


def _tspan(time: schema.Time, params: dict[str, float], limits: Limits = DEFAULT_LIMITS) -> tuple[np.ndarray, dict]:
    if time.output is not None and time.points is not None:
        raise ExperimentError("give either `time.output` (the output times) or `time.points` (how many evenly "
                              "spaced ones), not both.", key="time.points")
    start = constant(time.start, "time.start", params)
    stop = constant(time.stop, "time.stop", params)
    if start == stop:
        raise ExperimentError(f"`time.stop` equals `time.start` ({start:g}): the time span has zero length.",
                              key="time.stop")
    resolved: dict[str, Any] = {"start": start, "stop": stop}
    if isinstance(time.output, str):
        out = _matlab_range(time.output, params, limits)
    elif time.output is not None:
        check_count("points", len(time.output), "time.output", "output times", limits)
        out = np.array([constant(v, f"time.output[{i}]", params) for i, v in enumerate(time.output)])
    if time.output is not None:
        if out.size < 2:
            raise ExperimentError("`time.output` needs at least two times (MATLAB's vector tspan).",
                                  key="time.output")
        if out[0] != start or out[-1] != stop:
            raise ExperimentError(
                f"`time.output` must run from time.start ({start:g}) to time.stop ({stop:g}), as MATLAB's tspan "
                f"does; it runs from {out[0]:g} to {out[-1]:g}.", key="time.output")
        steps = np.sign(stop - start) * np.diff(out)
        if np.any(steps <= 0):
            i = int(np.argmax(steps <= 0)) + 1
            raise ExperimentError(f"`time.output` must be strictly monotonic from start to stop; entry {i} "
                                  f"({out[i]:g}) follows {out[i - 1]:g}.", key="time.output")
        resolved["output"] = out.tolist()
        return out, resolved
    if time.points is not None:
        if time.points < 2:
            raise ExperimentError(f"`time.points` must be at least 2; got {time.points}.", key="time.points")
        check_count("points", time.points, "time.points", "", limits, asked=f"is {time.points:,}")
        resolved["points"] = time.points
        return np.linspace(start, stop, time.points), resolved
    return np.array([start, stop]), resolved


