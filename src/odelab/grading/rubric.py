"""The rubric file (``rubric.toml``): what to grade, against which reference, for how many points.

The schema (pydantic) checks structure and types; :func:`load_rubric` then checks meaning per
check kind, so that every message names the rubric file, the key path (``check[2].tolerance``),
the value and the fix, as the experiment loader's do. Nothing here runs a solver.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, StrictFloat, StrictInt, StrictStr, ValidationError

from odelab.exceptions import InputError

__all__ = ["CHECK_KINDS", "STEPINFO_METRICS", "Check", "Rubric", "RubricError", "load_rubric", "solver_key"]

Number = Union[StrictInt, StrictFloat]

CHECK_KINDS = ("headline", "trajectory", "final", "stepinfo", "events", "matrix", "solver")

# MATLAB's stepinfo field names, and odelab's (analysis.control.StepInfo) for the same
STEPINFO_METRICS = {"RiseTime": "rise_time", "TransientTime": "transient_time", "SettlingTime": "settling_time",
                    "SettlingMin": "settling_min", "SettlingMax": "settling_max", "Overshoot": "overshoot",
                    "Undershoot": "undershoot", "Peak": "peak", "PeakTime": "peak_time",
                    "SteadyStateValue": "steady_state"}

# Which optional keys each kind takes (besides name, experiment, case, kind, points)
_KIND_KEYS = {
    "headline": {"quantity", "tolerance"},
    "trajectory": {"quantity", "tolerance"},
    "final": {"quantity", "tolerance"},
    "stepinfo": {"quantity", "tolerance", "metric"},
    "events": {"tolerance", "event"},
    "matrix": {"tolerance", "matrix"},
    "solver": set(),
}
_REQUIRED = {
    "headline": ("quantity", "tolerance"),
    "trajectory": ("quantity", "tolerance"),
    "final": ("quantity", "tolerance"),
    "stepinfo": ("quantity", "tolerance", "metric"),
    "events": ("tolerance",),
    "matrix": ("tolerance", "matrix"),
    "solver": (),
}
_EXAMPLE = {"quantity": 'quantity = "y"', "tolerance": "tolerance = { rel = 0.01 }",
            "metric": 'metric = "SettlingTime"', "matrix": 'matrix = "A"'}


class RubricError(InputError):
    """A rubric file is unreadable or invalid."""


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Tolerance(_Section):
    """How far the student's value may be from the reference's: within ``abs`` or within ``rel`` x |reference|."""

    rel: Number | None = None
    abs: Number | None = None


class Check(BaseModel):
    """One ``[[check]]``; a kind = "solver" check takes [solver] keys (odelab's or MATLAB's names) besides these."""

    model_config = ConfigDict(extra="allow", frozen=True)

    name: StrictStr
    experiment: StrictStr
    case: StrictStr | None = None
    kind: Literal["headline", "trajectory", "final", "stepinfo", "events", "matrix", "solver"]
    quantity: StrictStr | None = None
    tolerance: Tolerance | None = None
    points: Number = 1
    metric: StrictStr | None = None
    matrix: StrictStr | None = None
    event: StrictStr | None = None


class RubricModel(_Section):
    title: StrictStr | None = None
    reference: Union[StrictStr, list[StrictStr]]
    submissions: StrictStr | None = None
    check: list[Check] = Field(min_length=1)


@dataclass(frozen=True)
class CheckSpec:
    """A check ready to evaluate (the validated ``[[check]]`` with its solver keys in odelab's names)."""

    index: int
    name: str
    experiment: str
    case: str | None
    kind: str
    points: float
    quantity: str | None = None
    rel: float | None = None
    abs: float | None = None
    metric: str | None = None  # MATLAB's stepinfo name
    matrix: str | None = None
    event: str | None = None
    solver: dict[str, Any] = field(default_factory=dict)  # odelab name -> (as written, value)

    @property
    def key(self) -> str:
        return f"check[{self.index}]"

    def tolerance_text(self) -> str:
        parts = []
        if self.rel is not None:
            parts.append(f"rel {self.rel:g}")
        if self.abs is not None:
            parts.append(f"abs {self.abs:g}")
        return " or ".join(parts)


@dataclass(frozen=True)
class Rubric:
    path: Path
    title: str
    reference: tuple[Path, ...]
    submissions: Path | None
    checks: tuple[CheckSpec, ...]

    @property
    def max_score(self) -> float:
        return sum(c.points for c in self.checks)


def solver_key(name: str) -> str | None:
    """odelab's name of a [solver] key written in odelab's or MATLAB's spelling (RelTol -> rtol), else None."""
    from odelab.experiment.schema import SOLVER_KEYS
    from odelab.solvers.optionset import canonical  # the option registry's map of MATLAB's odeset names

    if name == "method":
        return "method"
    name = canonical(name) or name
    return name if name in SOLVER_KEYS else None


def _fail(message: str, path: Path, key: str | None = None) -> RubricError:
    return RubricError(message, source=str(path), key=key)


def load_rubric(path: str | Path) -> Rubric:
    """Read and validate ``rubric.toml``; paths in it are relative to its folder.

    Raises
    ------
    RubricError
        Naming the file, the key path, the value and the fix.
    """
    from odelab.formats.toml import read_toml

    path = Path(path)
    try:
        data, _ = read_toml(path)
    except InputError as exc:
        raise RubricError(exc.message, source=str(path), key=exc.key) from None
    try:
        model = RubricModel.model_validate(data)
    except ValidationError as exc:
        raise _schema_error(exc, path, data) from None
    folder = path.parent
    refs = [model.reference] if isinstance(model.reference, str) else list(model.reference)
    if not refs:
        raise _fail("`reference` is an empty list; name the instructor's experiment files or their folder, e.g. "
                    'reference = "reference/".', path, "reference")
    checks = []
    names: dict[str, int] = {}
    for i, check in enumerate(model.check):
        spec = _check_spec(i, check, path)
        if spec.name in names:
            raise _fail(f"`check[{i}].name` is {spec.name!r}, the name of check[{names[spec.name]}] too; give each "
                        "check its own name (it is a column of summary.csv).", path, f"check[{i}].name")
        names[spec.name] = i
        checks.append(spec)
    title = model.title if model.title is not None else path.stem
    return Rubric(path=path, title=title, reference=tuple(folder / r for r in refs),
                  submissions=folder / model.submissions if model.submissions is not None else None,
                  checks=tuple(checks))


def _check_spec(i: int, check: Check, path: Path) -> CheckSpec:
    key = f"check[{i}]"
    if not check.name.strip():
        raise _fail(f"`{key}.name` is empty; give the check a name, e.g. \"Exercise 1a\".", path, f"{key}.name")
    if not isinstance(check.points, (int, float)) or not math.isfinite(check.points) or check.points < 0:
        raise _fail(f"`{key}.points` must be a number >= 0; got {check.points!r}.", path, f"{key}.points")
    kind = check.kind
    extras = dict(check.model_extra or {})
    solver: dict[str, Any] = {}
    if kind == "solver":
        for name, value in extras.items():
            canonical = solver_key(name)
            if canonical is None or canonical == "backend":
                from odelab.experiment.schema import SOLVER_KEYS

                known = [k for k in SOLVER_KEYS if k != "backend"]
                close = difflib.get_close_matches(name, [*known, "RelTol", "AbsTol", "MaxStep"], n=1)
                hint = f" Did you mean `{close[0]}`?" if close else ""
                raise _fail(f"`{key}.{name}` is not a [solver] key.{hint} A kind = \"solver\" check lists the "
                            f"[solver] keys the student must have used: {', '.join(known)} (or MATLAB's RelTol, "
                            "AbsTol, MaxStep...).", path, f"{key}.{name}")
            if canonical in solver:
                raise _fail(f"`{key}.{name}` and `{key}.{solver[canonical][0]}` name the same [solver] key; keep one.",
                            path, f"{key}.{name}")
            if isinstance(value, dict):
                raise _fail(f"`{key}.{name}` must be a value (a number, a string, true or false, or a list); got a "
                            "table.", path, f"{key}.{name}")
            solver[canonical] = (name, value)
        if not solver:
            raise _fail(f"`{key}` is a kind = \"solver\" check with no [solver] key to compare: add the keys the "
                        "student must have used, e.g. method = \"ode23\" and rtol = 1e-3.", path, key)
    elif extras:
        name = sorted(extras)[0]
        allowed = sorted({"name", "experiment", "case", "kind", "points", *_KIND_KEYS[kind]})
        close = difflib.get_close_matches(name, allowed, n=1)
        hint = f" Did you mean `{close[0]}`?" if close else ""
        raise _fail(f"unknown key `{key}.{name}`.{hint} A kind = \"{kind}\" check takes: {', '.join(allowed)}.",
                    path, f"{key}.{name}")
    for optional in ("quantity", "tolerance", "metric", "matrix", "event"):
        if getattr(check, optional) is not None and optional not in _KIND_KEYS[kind]:
            takers = [k for k, keys in _KIND_KEYS.items() if optional in keys]
            raise _fail(f"`{key}.{optional}` is for kind = {' or '.join(repr(k) for k in takers)}; this check is "
                        f"kind = {kind!r}: remove it or change the kind.", path, f"{key}.{optional}")
    for required in _REQUIRED[kind]:
        if getattr(check, required) is None:
            raise _fail(f"`{key}.{required}` is required for a kind = {kind!r} check: add {_EXAMPLE[required]}.",
                        path, f"{key}.{required}")
    rel = abs_ = None
    if check.tolerance is not None:
        rel, abs_ = check.tolerance.rel, check.tolerance.abs
        if rel is None and abs_ is None:
            raise _fail(f"`{key}.tolerance` is empty; give rel or abs, e.g. tolerance = {{ rel = 0.01 }}.", path,
                        f"{key}.tolerance")
        for name, value in (("rel", rel), ("abs", abs_)):
            if value is not None and not (math.isfinite(value) and value >= 0):
                raise _fail(f"`{key}.tolerance.{name}` must be a finite number >= 0; got {value!r}.", path,
                            f"{key}.tolerance.{name}")
    metric = check.metric
    if metric is not None:
        by_snake = {v: k for k, v in STEPINFO_METRICS.items()}
        if metric in by_snake:
            metric = by_snake[metric]
        if metric not in STEPINFO_METRICS:
            close = difflib.get_close_matches(metric, list(STEPINFO_METRICS), n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise _fail(f"`{key}.metric` is {check.metric!r}; it must be one of stepinfo's names: "
                        f"{', '.join(STEPINFO_METRICS)}.{hint}", path, f"{key}.metric")
    if check.matrix is not None and check.matrix not in ("A", "B", "C", "D"):
        raise _fail(f"`{key}.matrix` is {check.matrix!r}; it must be one of \"A\", \"B\", \"C\", \"D\" (of the "
                    "state-space model, or of the system's linearisation about its equilibrium).", path,
                    f"{key}.matrix")
    return CheckSpec(index=i, name=check.name, experiment=check.experiment, case=check.case, kind=kind,
                     points=float(check.points), quantity=check.quantity, rel=None if rel is None else float(rel),
                     abs=None if abs_ is None else float(abs_), metric=metric, matrix=check.matrix,
                     event=check.event, solver=solver)


def _schema_error(exc: ValidationError, path: Path, data: Any) -> RubricError:
    """pydantic's first error as one line naming the key path, the value and the fix."""
    errors = exc.errors()
    err = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])  # a typo explains the rest
    loc = [seg for seg in err["loc"] if not (isinstance(seg, str) and ("[" in seg or seg in
                                                                         ("str", "int", "float", "list")))]
    key = ""
    for seg in loc:
        key = f"{key}[{seg}]" if isinstance(seg, int) else (f"{key}.{seg}" if key else str(seg))
    kind = err["type"]
    if kind == "extra_forbidden":
        known = {"": list(RubricModel.model_fields), "tolerance": list(Tolerance.model_fields)}
        parent = "tolerance" if len(loc) >= 2 and loc[-2] == "tolerance" else ""
        leaf = str(loc[-1])
        close = difflib.get_close_matches(leaf, known[parent], n=1)
        hint = f" Did you mean `{close[0]}`?" if close else ""
        text = f"unknown key `{key}`.{hint} Known keys: {', '.join(known[parent])}."
    elif kind == "missing":
        hints = {"reference": ' add reference = "reference/" (the instructor\'s experiment files)',
                 "check": " add at least one [[check]] table"}
        leaf = str(loc[-1]) if loc else ""
        text = f"`{key}` is required" + (f":{hints[leaf]}." if leaf in hints else ".")
        if leaf == "check" or key == "check":
            text = "`check` is required: add at least one [[check]] table (name, experiment, case, kind, points)."
    elif kind == "literal_error":
        given = err.get("input")
        close = difflib.get_close_matches(str(given), CHECK_KINDS, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        text = f"`{key}` is {given!r}; it must be one of {', '.join(CHECK_KINDS)}.{hint}"
    elif kind == "too_short":
        text = "`check` is empty: add at least one [[check]] table."
    else:
        expected = {"string_type": "a string", "int_type": "a number", "float_type": "a number",
                    "model_type": "a table", "list_type": "an array", "dict_type": "a table"}.get(kind, err["msg"])
        given = err.get("input")
        shown = repr(given) if len(repr(given)) <= 60 else repr(given)[:57] + "..."
        text = f"`{key}` must be {expected}; got {shown}."
    return RubricError(text, source=str(path), key=key or None)
