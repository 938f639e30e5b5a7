"""Loading experiment files: a file's dict (:mod:`odelab.formats`) -> validated, merged, compiled cases.

Every problem with a file is raised as one :class:`~odelab.exceptions.ExperimentError`
naming the file, the TOML key, the value, and the fix. Nothing here runs a solver.
"""

from __future__ import annotations

import copy
import hashlib
import re
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.cases import Case, LoadedExperiment, Problem
from odelab.experiment.compile import compile_case
from odelab.experiment.limits import DEFAULT_LIMITS, Limits, check_count
from odelab.experiment.naming import NAME_RULE, check_experiment_names, folder_key, slug  # noqa: F401 (re-exported)
from odelab.formats import ImportOptions, read
from odelab.experiment.schema_errors import describe_value, schema_error  # noqa: F401 (schema_error re-exported)
from odelab.solvers.optionset import canonical as option_name

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


def load_experiment(path: str | Path, *, limits: Limits = DEFAULT_LIMITS,
                    options: ImportOptions | None = None) -> LoadedExperiment:
    """Read, validate and compile an experiment file into its cases, within the work and memory ``limits``.

    Raises
    ------
    ExperimentError
        Naming the file, the key, the value and the fix.
    """
    path = Path(path)
    data, raw = _read(path, options)
    if "problem" in data:
        raise ExperimentError("holds several problems ([[problem]]); load it with `load_experiments`, which "
                              "returns one experiment per problem.", source=str(path), key="problem")
    return _load(path, data, hashlib.sha256(raw).hexdigest(), data.get("name", path.stem), limits)


def load_experiments(path: str | Path, *, limits: Limits = DEFAULT_LIMITS,
                     options: ImportOptions | None = None) -> list[LoadedExperiment]:
    """Load an experiment file as a list of experiments: one, or one per ``[[problem]]``.

    A ``[[problem]]`` table (with a ``name``) replaces the base's tables of the same names
    (``system``, ``initial``, ``time``, ``exact``, ``parameters``, ``inputs``, ``reference``,
    ``title``...) while the rest (``[solver]``, ``[sweep]``, ``[study]``, ``[[case]]``) is shared:
    one study run on several problems. Each becomes the experiment ``<name>_<problem name>``.
    """
    path = Path(path)
    src = str(path)
    data, raw = _read(path, options)
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


def _read(path: Path, options: ImportOptions | None) -> tuple[dict, bytes]:
    """The file's dict and bytes, by its format (:mod:`odelab.formats`); an imported file with gaps is refused."""
    doc = read(path, options)
    if doc.gaps:
        raise ExperimentError(doc.gaps_message(), source=str(path))
    return doc.data, doc.raw


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

    out: dict[str, Any] = {}
    origin: dict[str, str] = {}
    for key, value in solver.items():
        canonical = key if key == "method" else option_name(key) or key
        if canonical in out:
            where = f" (in case {case!r})" if case else ""
            raise ExperimentError(f"`solver.{key}` and `solver.{origin[canonical]}` set the same option{where}; "
                                  "keep one.", source=src, key=f"solver.{key}")
        out[canonical] = value
        origin[canonical] = key
    return {**config, "solver": out}
