"""Loading experiment files: TOML -> validated, merged, compiled cases.

Every problem with a file is raised as one :class:`~odelab.exceptions.ExperimentError`
naming the file, the TOML key, the value, and the fix. Nothing here runs a solver.
"""

from __future__ import annotations

import copy
import difflib
import hashlib
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ValidationError

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.cases import Case, LoadedExperiment, Problem
from odelab.experiment.fields import check_keys, constant, expr, mathtext_problem
from odelab.experiment.limits import DEFAULT_LIMITS, Limits, check_count, check_solve
from odelab.experiment.naming import NAME_RULE, check_experiment_names, folder_key, slug  # noqa: F401 (re-exported)
from odelab.experiment.reading import read_toml
from odelab.experiment.schema_errors import describe_value, schema_error  # noqa: F401 (schema_error re-exported)

__all__ = ["Case", "LoadedExperiment", "Problem", "load_experiment", "load_experiments", "merge", "slug"]


# --- reading ------------------------------------------------------------------------------


def merge(base: dict, override: dict) -> dict:
    """Deep-merge ``override`` over ``base``: tables merge key by key, other values replace.

    A table that changes its ``type`` (``inputs.f`` or ``blocks.force`` from a step to a sine)
    replaces the base's table instead, since the base's keys would not apply to the new type.

    Neither argument is modified, and only the tables on the override's paths are copied: the
    rest of the base is shared, so merging many small cases over a large base costs the size
    of the cases, not cases x base (the parsed TOML is never modified afterwards).
    """
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict) and not _retyped(out[key], value):
            out[key] = merge(out[key], value)
        else:
            out[key] = value
    return out


def _retyped(base: dict, override: dict) -> bool:
    """A case's table with another `type` (a step input becoming a sine) replaces the base's."""
    return "type" in override and "type" in base and override["type"] != base["type"]


# --- loading ------------------------------------------------------------------------------


def load_experiment(path: str | Path, *, limits: Limits = DEFAULT_LIMITS) -> LoadedExperiment:
    """Read, validate and compile an experiment file into its cases, within the work and memory ``limits``.

    Raises
    ------
    ExperimentError
        Naming the file, the key, the value and the fix.
    """
    path = Path(path)
    data, raw = read_toml(path)
    if "problem" in data:
        raise ExperimentError("holds several problems ([[problem]]); load it with `load_experiments`, which "
                              "returns one experiment per problem.", source=str(path), key="problem")
    return _load(path, data, hashlib.sha256(raw).hexdigest(), data.get("name", path.stem), limits)


def load_experiments(path: str | Path, *, limits: Limits = DEFAULT_LIMITS) -> list[LoadedExperiment]:
    """Load an experiment file as a list of experiments: one, or one per ``[[problem]]``.

    A ``[[problem]]`` table (with a ``name``) replaces the base's tables of the same names
    (``system``, ``initial``, ``time``, ``exact``, ``parameters``, ``inputs``, ``reference``,
    ``title``...) while the rest (``[solver]``, ``[sweep]``, ``[study]``, ``[[case]]``) is shared:
    one study run on several problems. Each becomes the experiment ``<name>_<problem name>``.
    """
    path = Path(path)
    src = str(path)
    data, raw = read_toml(path)
    file_hash = hashlib.sha256(raw).hexdigest()
    name = data.get("name", path.stem)
    problems = data.pop("problem", None)
    if problems is None:
        return [_load(path, data, file_hash, name, limits)]
    if not isinstance(problems, list) or not problems or not all(isinstance(p, dict) for p in problems):
        raise ExperimentError("`problem` must be an array of tables: write each problem as [[problem]] with a "
                              "`name`.", source=src, key="problem")
    out, seen = [], set()
    for i, problem in enumerate(problems):
        pname = problem.get("name")
        if not isinstance(pname, str) or not pname.strip():
            raise ExperimentError(f"[[problem]] number {i + 1} needs a `name` (a non-empty string), e.g. "
                                  "name = \"exercise1\".", source=src, key=f"problem[{i}].name")
        if pname in seen:
            raise ExperimentError(f"two problems are named {pname!r}; give each its own name.", source=src,
                                  key=f"problem[{i}].name")
        seen.add(pname)
        if "case" in problem or "sweep" in problem or "study" in problem or "problem" in problem:
            raise ExperimentError(f"[[problem]] {pname!r} sets `case`, `sweep`, `study` or `problem`; those belong "
                                  "to the whole file (outside [[problem]]).", source=src, key=f"problem[{i}]")
        merged = {**copy.deepcopy(data), **{k: v for k, v in problem.items() if k != "name"}}
        out.append(_load(path, merged, file_hash, f"{name}_{pname}", limits, copies=len(problems)))
    return out


def _dotted_states(table):
    """A network's ``mass.x = 0.1`` (TOML's nested table {mass: {x: 0.1}}) as the key "mass.x"."""
    if not isinstance(table, dict):
        return table
    out = {}
    for key, value in table.items():
        if isinstance(value, dict) and value and all(not isinstance(v, dict) for v in value.values()):
            out.update({f"{key}.{k}": v for k, v in value.items()})
        else:
            out[key] = value
    return out


def _load(path: Path, data: dict, file_hash: str, name, limits: Limits, copies: int = 1) -> LoadedExperiment:
    """One experiment; ``copies`` is the file's number of [[problem]] tables (the case budget is the file's)."""
    src = str(path)
    if isinstance(data.get("system"), dict) and data["system"].get("kind") == "network":
        for section in ("initial", "units"):
            if section in data:
                data[section] = _dotted_states(data[section])
    fit_raw = data.pop("fit", None)
    original = copy.deepcopy(data) if fit_raw is not None else None  # [fit] rebuilds the file with its estimates
    cases_raw = data.pop("case", None)
    if cases_raw is None:
        cases_raw = [None]
    elif not isinstance(cases_raw, list) or not all(isinstance(c, dict) for c in cases_raw):
        raise ExperimentError("`case` must be an array of tables: write each case as [[case]].", source=src,
                              key="case")
    elif not cases_raw:
        cases_raw = [None]
    if not isinstance(name, str) or not name.strip():
        raise ExperimentError(f"`name` must be a non-empty string; got {describe_value(name)}.", source=src, key="name")
    sweep, swept, study_raw = None, [{} for _ in cases_raw], data.pop("study", None)
    if "sweep" in data:
        from odelab.experiment.sweep import expand_sweep

        try:
            sweep = expand_sweep(data.pop("sweep"), data, [c for c in cases_raw if c is not None], limits=limits,
                                 copies=copies)
        except InputError as exc:
            raise exc.located(source=src) from None
        cases_raw, swept = _sweep_cases(cases_raw, sweep.points())
    elif study_raw is not None:
        raise ExperimentError("[study] compares the cases of a [sweep]: add a [sweep] table, e.g. "
                              "\"solver.h\" = [0.1, 0.05, 0.025].", source=src, key="study")
    elif copies > 1:
        try:
            check_count("cases", len(cases_raw) * copies, "problem", "", limits,
                        asked=f"has {copies:,} [[problem]] tables times {len(cases_raw):,} case"
                              f"{'s' if len(cases_raw) != 1 else ''}: {len(cases_raw) * copies:,} cases")
        except InputError as exc:
            raise exc.located(source=src) from None

    try:
        if sweep is not None:
            check_count("cases", len(cases_raw), "sweep", "cases (the sweep's values times the [[case]] tables)",
                        limits)
        else:
            check_count("cases", len(cases_raw), "case", "[[case]] tables", limits)
    except InputError as exc:
        raise exc.located(source=src) from None
    _check_case_names(cases_raw, src)  # before any case is compiled
    for index, override in enumerate(cases_raw):
        if override is not None and "fit" in override:
            raise ExperimentError("[fit] belongs to the whole file (outside [[case]]): one [fit] estimates one set "
                                  "of parameters from the [data] of every case, jointly.", source=src,
                                  key=f"case[{index}].fit")
    cases = []
    models = []  # each case's validated model, for [fit]
    shared: dict = {}
    base_sections = _validated_sections(data) if len(cases_raw) > 1 else {}
    for index, override in enumerate(cases_raw):
        if override is None:
            merged = data
            case_name = None
        else:
            case_name = override["name"]
            merged = merge(data, {k: v for k, v in override.items() if k != "name"})
        try:
            normalized = _normalize_solver(merged, src, case_name)
            model = schema.Experiment.model_validate(_reuse_sections(normalized, data, base_sections))
        except ValidationError as exc:
            error = schema_error(exc, source=src, case=None, data=normalized)
            raise _in_case(error, override, case_name) from None
        try:
            problem, resolved = compile_case(model, path, limits=limits, shared=shared)
        except InputError as exc:
            raise _in_case(exc.located(source=src), override, case_name) from None
        if case_name is None:
            case_name = problem.method
        if fit_raw is not None:
            models.append(model)
        config = {"name": name, **resolved, "case": [{"name": case_name}]}
        cases.append(Case(experiment=name, name=case_name, title=model.title or name, source=path,
                          file_hash=file_hash, config=config, problem=problem, index=index, swept=swept[index]))
    title = data.get("title") if isinstance(data.get("title"), str) else name
    study = None
    if study_raw is not None:
        from odelab.experiment.study import parse_study

        try:
            study = parse_study(study_raw, sweep, cases)
        except InputError as exc:
            raise exc.located(source=src) from None
    fit = None
    if fit_raw is not None:
        from odelab.experiment.fit import parse_fit

        try:
            fit = parse_fit(fit_raw, cases, models, original, path=path, file_hash=file_hash, name=name,
                            limits=limits, sweep=sweep, load=_load)
        except InputError as exc:
            raise exc.located(source=src) from None
    return LoadedExperiment(name=name, title=title, source=path, file_hash=file_hash, cases=tuple(cases),
                            sweep=sweep, study=study, fit=fit)


def _sweep_cases(cases_raw: list, points: list) -> tuple[list, list]:
    """Every [[case]] (or the base) once per sweep point, named "case, h=0.1" (or "h=0.1")."""
    out, swept = [], []
    for override in cases_raw:
        base_name = override.get("name") if override is not None else None
        for point in points:
            if override is None:
                out.append({"name": point.name, **point.override})
            elif isinstance(base_name, str) and base_name.strip():
                out.append({**merge(override, point.override), "name": f"{base_name}, {point.name}"})
            else:  # let the [[case]] checks below name the problem
                out.append(override)
            swept.append(dict(point.values))
    return out, swept


_SHAREABLE = ("system", "time", "reference")  # tables validated once when the cases leave them alone


def _validated_sections(data: dict) -> dict[str, BaseModel]:
    """The base's [system], [time] and [reference], each validated on its own (None where invalid).

    A case that does not change such a table gets this validated (frozen) model in place of
    the raw table, so a large matrix or output list is validated once per file, not per case.
    """
    out = {}
    for key in _SHAREABLE:
        raw = data.get(key)
        if isinstance(raw, dict):
            try:
                out[key] = schema.Experiment.model_fields[key].annotation.model_validate(raw)
            except ValidationError:  # reported, with its key, when a case is validated
                pass
    return out


def _reuse_sections(normalized: dict, data: dict, sections: dict[str, BaseModel]) -> dict:
    reused = {key: model for key, model in sections.items() if normalized.get(key) is data.get(key)}
    return {**normalized, **reused} if reused else normalized


def _check_case_names(cases_raw: list, src: str) -> None:
    """Every [[case]] has a name, and no two are stored in the same results folder."""
    seen: dict[str, int] = {}
    by_folder: dict[str, int] = {}
    for index, override in enumerate(cases_raw):
        if override is None:
            continue
        case_name = override.get("name")
        if not isinstance(case_name, str) or not case_name.strip():
            raise ExperimentError(
                f"[[case]] number {index + 1} needs a `name` (a non-empty string), e.g. name = \"ode45\".",
                source=src, key=f"case[{index}].name")
        if case_name in seen:
            raise ExperimentError(f"two cases are named {case_name!r} (cases {seen[case_name] + 1} and "
                                  f"{index + 1}); give each case its own name.", source=src,
                                  key=f"case[{index}].name")
        seen[case_name] = index
        folder = folder_key(case_name)
        if folder in by_folder:
            other = cases_raw[by_folder[folder]]["name"]
            raise ExperimentError(
                f"cases {other!r} (case {by_folder[folder] + 1}) and {case_name!r} (case {index + 1}) would be stored "
                f"in the same results folder {slug(case_name)!r}, the second overwriting the first: give each case a "
                f"name of its own {NAME_RULE}.",
                source=src, key=f"case[{index}].name")
        by_folder[folder] = index


def _in_case(exc: InputError, override: dict | None, case_name: str | None) -> InputError:
    """Say which case an error comes from when the offending key is set by that case."""
    if not override or not case_name or not exc.key:
        return exc
    node: Any = override
    for part in re.split(r"\.|\[", exc.key):
        part = part.rstrip("]")
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return exc
    exc.message += f" (set in case {case_name!r})"
    return exc


def _normalize_solver(config: dict, src: str, case: str | None) -> dict:
    """Map MATLAB's option names in [solver] (RelTol, AbsTol, ...) to odelab's, before the schema."""
    solver = config.get("solver")
    if not isinstance(solver, dict):
        return config
    from odelab.solvers.options import _ALIASES

    out: dict[str, Any] = {}
    origin: dict[str, str] = {}
    for key, value in solver.items():
        canonical = key if key == "method" else _ALIASES.get(key.lower().replace("_", ""), key)
        if canonical in out:
            where = f" (in case {case!r})" if case else ""
            raise ExperimentError(f"`solver.{key}` and `solver.{origin[canonical]}` set the same option{where}; "
                                  "keep one.", source=src, key=f"solver.{key}")
        out[canonical] = value
        origin[canonical] = key
    return {**config, "solver": out}


# --- compiling a case -----------------------------------------------------------------------


def compile_case(model: schema.Experiment, path: Path, *, limits: Limits = DEFAULT_LIMITS,
                 shared: dict | None = None) -> tuple[Problem, dict]:
    """Compile a validated case into a :class:`Problem` and its resolved configuration.

    ``shared`` (a dict kept across the cases of one file) lets cases that share the base's
    validated [system] and [time] (see :func:`_validated_sections`) share their builds.
    """
    ex = expr()
    params = ex.evaluate_parameters(model.parameters) if model.parameters else {}
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
        resolved["report"] = _report(model.report)
    if params:
        resolved["parameters"] = dict(params)

    # A system table that the case does not change is shared with the base (see merge): build
    # it once per file and parameter values, not once per case.
    # (keys hold the model's id; the value keeps the model alive, so the id cannot be reused)
    params_key = tuple(sorted(params.items()))
    share = None
    if shared is not None and system.kind in ("state-space", "ode") and system.function is None \
            and model.blocks is None:
        share = ("system", id(system), params_key, model.linearize is not None)
    if system.kind in ("ode", "state-space") and system.states and not limits.allows("states", len(system.states)):
        # name the missing initial values first (that is the file's mistake), then the budget
        check_keys(model.initial, tuple(system.states), "initial", "states", require_all=True)
        check_count("states", len(system.states), "system.states", "states", limits)
    if share is not None and share in shared:
        built = shared[share][1]
    elif system.kind == "state-space":
        from odelab.experiment.build import build_state_space

        built = build_state_space(model, params)
    elif system.kind == "diagram":
        from odelab.experiment.diagram import build_diagram

        built = build_diagram(model, params, path, constant(model.time.start, "time.start", params),
                              max_rows=limits.table_rows or None, limits=limits)
    elif system.kind == "network":
        from odelab.experiment.network import build_network

        built = build_network(model, params)
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
    states, inputs, outputs = built.states, built.inputs, built.outputs
    resolved["system"] = dict(built.resolved)

    # initial state (a diagram's blocks carry theirs; [initial] may override some)
    check_keys(model.initial, states, "initial", "states", require_all=built.x0 is None)
    x0 = np.array([constant(model.initial[s], f"initial.{s}", params) if s in model.initial else built.x0[i]
                   for i, s in enumerate(states)], dtype=float)
    resolved["initial"] = {s: float(v) for s, v in zip(states, x0)}

    time_share = ("time", id(model.time), params_key, limits) if shared is not None else None
    if time_share is not None and time_share in shared:
        tspan, time_resolved = shared[time_share][1]
    else:
        tspan, time_resolved = _tspan(model.time, params, limits)
        tspan.flags.writeable = False  # shared by the cases that leave [time] alone
        if time_share is not None:
            shared[time_share] = (model.time, (tspan, time_resolved))
    time_resolved = dict(time_resolved)
    resolved["time"] = time_resolved

    # inputs
    signals: tuple = ()
    input_fn = None
    if built.signals:
        signals = built.signals
        resolved["blocks"] = _plain(model.blocks)

        def input_fn(t, _signals=signals):
            t = np.asarray(t, dtype=float)
            return np.column_stack([np.broadcast_to(np.asarray(s(t), dtype=float), t.shape) for s in _signals])
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

    # solver
    from odelab.solvers.options import as_tspan, normalize_options, resolve_options
    from odelab.solvers.registry import get_method

    from odelab.experiment.delays import check_delay_method, method_name

    method = get_method(method_name(model, built), key="solver.method")
    check_delay_method(model, built, method)  # lag(...) runs with dde23 only (experiment/delays.py)
    options = {k: v for k, v in model.solver.model_dump().items()
               if k not in ("method", "backend", "zero_crossing") and v is not None}
    backend = model.solver.backend
    runtime_options = _state_options(options, states, params, dae=method.name in ("ode15s", "ode23t"),
                                     takes_dependence="mstate_dependence" in method.options)
    try:
        as_tspan(tspan)
        resolve_options(method, normalize_options(runtime_options, method), tspan, len(states))
    except InputError as exc:
        raise ExperimentError(exc.message.replace(f"`{exc.key}`", f"`solver.{exc.key}`"),
                              key=f"solver.{exc.key}" if exc.key else "solver") from None
    check_solve(method_kind=method.kind, tspan=tspan, options=normalize_options(options, method),
                refine_default=getattr(method, "refine", 1) or 1, limits=limits)
    resolved["solver"] = {"method": method.name, **_plain(options)}
    options = runtime_options

    events = None
    if model.events is not None:
        from odelab.experiment.events import compile_events

        if method.kind not in ("adaptive", "multistep", "implicit"):
            raise ExperimentError(f"[events] are located by ode23, ode45, ode78, ode89, ode113, ode15s, ode23s, ode23t "
                                  f"and ode23tb (MATLAB's Events); `solver.method` is "
                                  f"{method.name!r}.", key="solver.method")
        if inputs or model.linearize is not None:
            raise ExperimentError("[events] work with systems without [inputs] and without [linearize]; remove one "
                                  "of them.", key="events")
        if model.reference.method not in ("auto", "exact", "none"):
            raise ExperimentError(f"`reference.method` is {model.reference.method!r}, but with [events] the reference "
                                  "is \"exact\" (from [exact]) or \"none\"; event times can have exact values with "
                                  "`exact` in the event's table.", key="reference.method")
        events, resolved["events"] = compile_events(model.events, states, params, limits)
    data = None
    if model.data is not None:
        from odelab.experiment.data import check_span, read_data

        if events is not None or model.linearize is not None:
            raise ExperimentError("[data] is the reference of a plain simulation; a case with [events] or "
                                  "[linearize] cannot be compared with measurements yet: remove one of them.",
                                  key="data")
        data = read_data(model.data, path, tuple(states) + tuple(outputs))
        check_span(data, tspan)
        resolved["data"] = data.as_dict()
    fast = built.compiled  # the compiled backend's system, its inputs driven by the signals
    if fast is not None and fast.inputs:
        fast = fast.with_signals(signals)
    if fast is not None and events is not None:
        fast = fast.with_events([w for w, _ in events.whens], events.terminal, events.direction, params,
                                [k for _, k in events.whens])
    if backend != "auto":
        resolved["solver"]["backend"] = backend
        from odelab.experiment.backend import check_backend

        check_backend(backend, method, fast, "solver.backend", options, events)
    if method.kind in ("adaptive", "implicit", "multistep"):
        resolved["solver"].setdefault("rtol", 1e-3)
        resolved["solver"].setdefault("atol", 1e-6)
    if system.kind == "ode" and system.jacobian is not None and built.jacobian is not None:
        _check_jacobian(built.jacobian, system, states, params, float(tspan[0]), x0)
    if method.kind == "implicit" and built.jacobian is not None:
        # The stiff solvers get the exact Jacobian of a known system, never finite differences.
        options["jacobian"] = built.jacobian
        resolved["solver"]["jacobian"] = getattr(built.jacobian, "source", "the A matrix")

    # exact solution and reference
    exact_fn = None
    if model.exact is not None:
        check_keys(model.exact, states + outputs, "exact", "states and outputs", require_all=False)
        compiled = {
            name: ex.compile_expression(text, names=["t", *params], key=f"exact.{name}")
            for name, text in model.exact.items()
        }

        def exact_fn(t, _compiled=compiled, _params=params):
            return {name: np.broadcast_to(np.asarray(fn(t=t, **_params), dtype=float), np.shape(t)).astype(float)
                    for name, fn in _compiled.items()}

        resolved["exact"] = {k: v for k, v in model.exact.items()}
    ref = model.reference
    kind = ref.method
    if kind == "auto" and data is not None:
        kind = "data"  # measurements are the reference of every case
    if kind == "auto":
        kind = "exact" if exact_fn else ("lti" if built.linear and _all_exact(signals) and events is None else "none")
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
    if method.kind == "delay":
        from odelab.experiment.delays import check_delay_case

        check_delay_case(model, method, kind)
    resolved["reference"] = {"method": kind, "solver": ref.solver, "rtol": ref.rtol, "atol": ref.atol}
    if model.units:
        resolved["units"] = _units(model.units, states, inputs, outputs, params)
    if model.linearize is not None:
        _check_linearize(model.linearize, states, inputs, outputs, built)
        if model.linearize.amplitudes is not None:
            check_count("amplitudes", len(model.linearize.amplitudes), "linearize.amplitudes", "amplitudes", limits)
        resolved["linearize"] = _plain(model.linearize.model_dump(exclude_none=True))

    analysis = None
    if model.analysis is not None:
        analysis = _check_analysis(model.analysis, inputs, built, params)
        resolved["analysis"] = _plain({k: v for k, v in model.analysis.model_dump(by_alias=True).items()
                                       if v is not None})

    problem = Problem(
        states=states, inputs=inputs, outputs=outputs, fun=built.fun, tspan=tspan, x0=x0, method=method.name,
        options=options, output_fn=built.output_fn, input_fn=input_fn, exact_fn=exact_fn, reference=kind,
        reference_solver=(ref.solver, float(ref.rtol), float(ref.atol)), system=built.system, signals=signals,
        linearize=model.linearize, parameters=params, diagram=built.diagram, events=events, backend=backend,
        compiled=fast, analysis=analysis, data=data, network=built.network,
    )
    return problem, resolved


MAX_QUOTED = 20


def _report(spec: schema.Report) -> dict:
    """[report] checked: ``quote`` names stored cases as "experiment/case"."""
    quote = spec.quote or []
    if len(quote) > MAX_QUOTED:
        raise ExperimentError(f"`report.quote` lists {len(quote)} cases; a note quotes at most {MAX_QUOTED}.",
                              key="report.quote")
    for i, entry in enumerate(quote):
        experiment, slash, case = entry.partition("/")
        if not (slash and experiment.strip() and case.strip()) or "/" in case:
            raise ExperimentError(f"`report.quote[{i}]` is {entry!r}; name a stored case as \"experiment/case\", "
                                  "e.g. \"exercise1/ode23\".", key=f"report.quote[{i}]")
    if quote and spec.note is None:
        raise ExperimentError("`report.quote` quotes errors in the section's note: add `note` under [report].",
                              key="report.quote")
    return _plain(spec.model_dump(exclude_none=True))


def _units(units: dict[str, str], states, inputs, outputs, params) -> dict[str, str]:
    """[units]: a short unit per time, state, input, output or parameter, shown on the report's axes."""
    names = ["t", *states, *inputs, *outputs, *params]
    for name, unit in units.items():
        if name not in names:
            close = difflib.get_close_matches(name, names, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ExperimentError(f"`units.{name}`: {name!r} is not t, a state, an input, an output or a parameter "
                                  f"({', '.join(names)}).{hint}", key=f"units.{name}")
        if not unit.strip() or len(unit) > 20 or not unit.isprintable():
            raise ExperimentError(f"`units.{name}` is {unit!r}; write a short unit on one line, e.g. "
                                  f"{name} = \"m\" or \"N\" or \"rad/s\".", key=f"units.{name}")
        problem = mathtext_problem(unit)
        if problem:
            raise ExperimentError(f"`units.{name}` is {unit!r}, which matplotlib cannot draw as mathtext "
                                  f"({problem}); write the unit as plain text (\"m/s^2\"), or as mathtext it "
                                  f"parses (\"$m/s^2$\"), or escape a literal dollar as \\$.",
                                  key=f"units.{name}")
    return dict(units)


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


def _check_jacobian(jacobian, system, states, params, t0: float, x0: np.ndarray) -> None:
    """A hand-written Jacobian must match the equations (checked at the initial state by complex step)."""
    from odelab.systems.jacobian import complex_step_jacobian

    exact = complex_step_jacobian([system.equations[s] for s in states], states, params)(t0, x0)
    given = jacobian(t0, x0)
    bad = np.abs(given - exact) > 1e-6 * np.maximum(1.0, np.abs(exact))
    if bad.any():
        i, j = (int(k) for k in np.argwhere(bad)[0])
        raise ExperimentError(
            f"`system.jacobian[{i}][{j}]` = {system.jacobian[i][j]!r} is {given[i, j] + 0.0:.6g} at the initial state, "
            f"but the derivative of the equation of {states[i]!r} with respect to {states[j]!r} is "
            f"{exact[i, j]:.6g} there: fix the entry, or remove `jacobian` (odelab derives it exactly).",
            key=f"system.jacobian[{i}][{j}]")


def _check_linearize(spec: schema.Linearize, states, inputs, outputs, built) -> None:
    """Catch [linearize] mistakes when the file is loaded, not halfway through a run."""
    if built.system is None:
        raise ExperimentError("[linearize] needs a system of equations or a state-space model; a `function` "
                              "system cannot be linearised from the file.", key="linearize")
    for field_name, names, what in (("input", inputs, "inputs"), ("state", states, "states"),
                                    ("guess", states, "states"), ("fixed", states, "states")):
        for name in getattr(spec, field_name) or {}:
            if name not in names:
                close = difflib.get_close_matches(name, names, n=1)
                hint = f" Did you mean `{close[0]}`?" if close else ""
                raise ExperimentError(f"`linearize.{field_name}.{name}`: {name!r} is not one of the {what} "
                                      f"({', '.join(names) or 'none'}).{hint}", key=f"linearize.{field_name}.{name}")
    if spec.amplitudes is not None:
        if not inputs:
            raise ExperimentError("`linearize.amplitudes` steps an input, but the system has no inputs.",
                                  key="linearize.amplitudes")
        bad = [a for a in spec.amplitudes if not (math.isfinite(a) and a > 0)]
        if bad or not spec.amplitudes:
            raise ExperimentError(f"`linearize.amplitudes` must be positive, finite step sizes; got {bad or '[]'}.",
                                  key="linearize.amplitudes")
    if spec.drive is not None and spec.drive not in inputs:
        raise ExperimentError(f"`linearize.drive` is {spec.drive!r}, not one of the inputs ({', '.join(inputs)}).",
                              key="linearize.drive")
    if spec.quantity is not None and spec.quantity not in states + outputs:
        raise ExperimentError(f"`linearize.quantity` is {spec.quantity!r}, not a state or output "
                              f"({', '.join(states + outputs)}).", key="linearize.quantity")
    if not (math.isfinite(spec.threshold) and spec.threshold > 0):
        raise ExperimentError(f"`linearize.threshold` must be a positive fraction such as 0.05; got {spec.threshold!r}.",
                              key="linearize.threshold")


def _check_analysis(spec: schema.Analysis, inputs, built, params) -> dict:
    """[analysis] checked at load time; returns what the runner needs."""
    if built.system is None:
        raise ExperimentError("[analysis] needs a state-space model, a diagram or a system of equations; a "
                              "`function` system cannot be analysed from the file.", key="analysis")
    if not inputs:
        raise ExperimentError("[analysis] computes the transfer functions from the system's inputs to its outputs "
                              "(poles, stepinfo, Bode, margins), and this system has no inputs: declare one "
                              "(inputs = [\"f\"] with [inputs.f], or a source block in a diagram), or remove "
                              "[analysis].", key="analysis")
    u0 = {}
    for name, value in (spec.input or {}).items():
        if name not in inputs:
            close = difflib.get_close_matches(name, inputs, n=1)
            hint = f" Did you mean `{close[0]}`?" if close else ""
            raise ExperimentError(f"`analysis.input.{name}`: {name!r} is not one of the inputs "
                                  f"({', '.join(inputs) or 'none'}).{hint}", key=f"analysis.input.{name}")
        u0[name] = constant(value, f"analysis.input.{name}", params)
    if u0 and built.linear:
        raise ExperimentError("`analysis.input` sets the operating input of a nonlinear system; this system is "
                              "linear, so its model does not depend on it: remove it.", key="analysis.input")
    bode = None
    if spec.bode is not False:
        rng = spec.bode if spec.bode is not True else schema.BodeRange()
        lo, hi = float(rng.from_), float(rng.to)
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
            raise ExperimentError(f"`analysis.bode` must have 0 < from < to (rad/s); got from = {rng.from_!r}, "
                                  f"to = {rng.to!r}.", key="analysis.bode")
        if not 2 <= rng.points <= 100_000:
            raise ExperimentError(f"`analysis.bode.points` must be between 2 and 100000; got {rng.points}.",
                                  key="analysis.bode.points")
        bode = {"from": lo, "to": hi, "points": rng.points}
    if spec.loop is not None:
        if built.diagram is None:
            raise ExperimentError("`analysis.loop` opens a loop of a diagram at a block's input; this system is not "
                                  "a diagram: remove it (the margins of a state-space system are computed as if "
                                  "it were the loop gain).", key="analysis.loop")
        built.diagram.open_loop(spec.loop)  # checks the block now, with its message
    return {"step_info": spec.step_info, "bode": bode, "poles": spec.poles,
            "input": [u0.get(n, 0.0) for n in inputs], "loop": spec.loop}


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


