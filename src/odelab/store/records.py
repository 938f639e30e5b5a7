"""result.json read back: each stored case checked field by field and typed (:class:`StoredRun`).

:mod:`odelab.store.results` writes result.json; this module is its reader, so the one format
lives in one package. A field a reader depends on that is missing or of the wrong shape is a
``ValueError`` naming the field (the report skips that case with a warning), never a KeyError
further on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["QuantityErrors", "StoredRun", "parse_record", "parse_events", "check_extra"]


@dataclass(frozen=True)
class QuantityErrors:
    """The stored maximum errors of one quantity (``max_rel`` is None where undefined)."""

    name: str
    max_abs: float | None
    t_max_abs: float | None
    max_rel: float | None  # the lab's pointwise max |f - y| / |f|
    t_max_rel: float | None
    undefined: int
    scale: float | None = None  # max |f|
    ref_at_max_rel: float | None = None  # |f| where the pointwise maximum is
    basis: str = "pointwise"  # which relative error headlines: see odelab.analysis.errors.HEADLINE_RULE

    @property
    def peak_rel(self) -> float | None:
        if self.max_abs is None or not self.scale:
            return None
        return self.max_abs / self.scale

    @property
    def headline(self) -> float | None:
        return self.max_rel if self.basis == "pointwise" else self.peak_rel


@dataclass(frozen=True)
class EstimatedError:
    """One quantity's stored global error estimate (result.json ``estimate.quantities``, odelab.run.estimate)."""

    name: str
    max_abs: float | None
    digits: float | None
    flagged: bool = False


def _estimate(raw: Any) -> tuple[dict[str, EstimatedError], str | None]:
    """``(quantities, verdict)`` of a stored estimate; an estimate that was skipped has no quantities."""
    if raw is None:
        return {}, None
    if not isinstance(raw, dict):
        raise ValueError("`estimate` must be a table")
    verdict = raw.get("verdict")
    if verdict is not None and verdict not in ("ok", "unreliable"):
        raise ValueError(f"`estimate.verdict` must be \"ok\" or \"unreliable\"; got {verdict!r}")
    quantities = raw.get("quantities") or {}
    if not isinstance(quantities, dict):
        raise ValueError("`estimate.quantities` must be a table")
    out = {}
    for name, q in quantities.items():
        if not isinstance(q, dict):
            raise ValueError(f"`estimate.quantities.{name}` must be a table")
        out[name] = EstimatedError(name, _number(q.get("max_abs"), f"estimate.quantities.{name}.max_abs"),
                                   _number(q.get("digits"), f"estimate.quantities.{name}.digits"),
                                   bool(q.get("flagged", False)))
    return out, verdict


@dataclass(frozen=True, eq=False)
class StoredRun:
    """One stored case, validated: the fields the report uses, typed, plus the raw record."""

    experiment: str
    case: str
    title: str
    method: str
    status: str
    message: str
    points: int
    nsteps: int | None
    nfailed: int | None
    nfevals: int | None
    reference: str
    errors: dict[str, QuantityErrors]
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    warnings: tuple[str, ...]
    elapsed_s: float | None
    source: str
    file_sha256: str
    created: str
    versions: dict[str, str]
    config: dict[str, Any]
    extra: dict[str, Any]
    trajectory: dict[str, np.ndarray]
    folder: Path
    events: tuple[dict, ...] = ()  # located events (result.json "events"), see report/events.py
    stats: dict[str, Any] = field(default_factory=dict)  # as stored, with the stiff solvers' npds, ndecomps...
    expected: bool = False  # failed the way its file said it would (expect = "max-steps"): not a real failure
    case_index: int | None = None  # the case's place in its experiment (None: stored by an older odelab)
    estimate: dict[str, EstimatedError] = field(default_factory=dict)  # the global error estimate, per quantity
    verdict: str | None = None  # the estimate's: "ok", "unreliable" (shown ok?) or None (no estimate)

    @property
    def ok(self) -> bool:
        return self.status == "success"

    @property
    def unreliable(self) -> bool:
        """It succeeded, but its error estimate says not to trust it (ok?)."""
        return self.ok and self.verdict == "unreliable"

    @property
    def t(self) -> np.ndarray:
        return self.trajectory["t"]

    def column(self, name: str) -> np.ndarray | None:
        return self.trajectory.get(name)

    def has_reference(self, name: str) -> bool:
        return f"{name}_ref" in self.trajectory


def _str(record: dict, key: str, *, required: bool = False) -> str:
    value = record.get(key)
    if value is None and not required:
        return ""
    if not isinstance(value, str):
        raise ValueError(f"`{key}` must be a string; got {type(value).__name__}")
    return value


def _count(value: Any, key: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value or value < 0:
        raise ValueError(f"`{key}` must be a non-negative count; got {value!r}")
    return int(value)


def _number(value: Any, key: str) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"`{key}` must be a number; got {value!r}")
    value = float(value)
    return value if math.isfinite(value) else None


def _names(record: dict, key: str) -> tuple[str, ...]:
    value = record.get(key) or []
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ValueError(f"`{key}` must be a list of names")
    return tuple(value)


def parse_record(record: dict[str, Any]) -> StoredRun:
    """Check and type a record returned by :func:`odelab.store.results.read_run`.

    Raises
    ------
    ValueError
        Naming the field that is missing or of the wrong type.
    """
    stats = record.get("stats")
    if not isinstance(stats, dict):
        raise ValueError("`stats` must be a table of nsteps, nfailed, nfevals")
    errors_raw = record.get("errors") or {}
    if not isinstance(errors_raw, dict):
        raise ValueError("`errors` must be a table")
    trajectory = record.get("trajectory")
    if not isinstance(trajectory, dict) or "t" not in trajectory:
        raise ValueError("trajectory.csv has no `t` column")
    trajectory = {str(k): np.asarray(v, dtype=float) for k, v in trajectory.items()}
    errors = {}
    for name, e in errors_raw.items():
        if not isinstance(e, dict):
            raise ValueError(f"`errors.{name}` must be a table")
        basis, scale = e.get("rel_basis"), _number(e.get("scale"), f"errors.{name}.scale")
        ref = trajectory.get(f"{name}_ref")
        if basis not in ("pointwise", "peak"):  # a run stored before the headline rule: apply it now
            from odelab.analysis.errors import headline_basis

            basis = headline_basis(ref) if ref is not None and ref.size else "pointwise"
        if scale is None and ref is not None and np.any(np.isfinite(ref)):
            scale = float(np.nanmax(np.abs(ref)))
        errors[name] = QuantityErrors(
            name=name, max_abs=_number(e.get("max_abs"), f"errors.{name}.max_abs"),
            t_max_abs=_number(e.get("t_max_abs"), f"errors.{name}.t_max_abs"),
            max_rel=_number(e.get("max_rel"), f"errors.{name}.max_rel"),
            t_max_rel=_number(e.get("t_max_rel"), f"errors.{name}.t_max_rel"),
            undefined=_count(e.get("undefined_rel_points"), f"errors.{name}.undefined_rel_points") or 0,
            scale=scale, ref_at_max_rel=_number(e.get("ref_at_max_rel"), f"errors.{name}.ref_at_max_rel"),
            basis=basis)
    warnings = record.get("warnings") or []
    if not isinstance(warnings, list):
        raise ValueError("`warnings` must be a list")
    versions = record.get("versions") or {}
    config = record.get("config") or {}
    extra = record.get("extra") or {}
    for key, value in (("versions", versions), ("config", config), ("extra", extra)):
        if not isinstance(value, dict):
            raise ValueError(f"`{key}` must be a table")
    check_extra(extra)
    status = _str(record, "status", required=True)
    estimate, verdict = _estimate(record.get("estimate"))
    return StoredRun(
        estimate=estimate, verdict=verdict,
        experiment=_str(record, "experiment", required=True),
        case=_str(record, "case", required=True),
        title=_str(record, "title"),
        method=_str(record, "method", required=True),
        status=status,
        message=_str(record, "message"),
        points=_count(record.get("points"), "points") or int(trajectory["t"].size),
        nsteps=_count(stats.get("nsteps"), "stats.nsteps"),
        nfailed=_count(stats.get("nfailed"), "stats.nfailed"),
        nfevals=_count(stats.get("nfevals"), "stats.nfevals"),
        reference=_str(record, "reference") or "none",
        errors=errors,
        states=_names(record, "states"),
        inputs=_names(record, "inputs"),
        outputs=_names(record, "outputs"),
        warnings=tuple(str(w) for w in warnings),
        elapsed_s=_number(record.get("elapsed_s"), "elapsed_s"),
        source=_str(record, "source"),
        file_sha256=_str(record, "file_sha256"),
        created=_str(record, "created"),
        case_index=_count(record.get("case_index"), "case_index"),
        versions={str(k): str(v) for k, v in versions.items() if v is not None},
        config=config,
        extra=extra,
        trajectory=trajectory,
        folder=Path(str(record.get("folder", ""))),
        events=parse_events(record.get("events"), (float(trajectory["t"][0]), float(trajectory["t"][-1]))
                            if trajectory["t"].size else None),
        stats=dict(stats),
        expected=record.get("expected") is True and status != "success",
    )


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def parse_events(raw, span: tuple[float, float] | None = None) -> tuple[dict, ...]:
    """Check result.json's ``events``: a list of tables with a name, a time and a state.

    Every state and reset value is a number, and the event and exact times are finite and (with
    ``span``, the trajectory's first and last time) inside the run: a hand-edited
    ``"h": "abc"`` or ``"t": 1e308`` is a record odelab did not write, skipped with the reason."""
    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise ValueError("`events` must be a list")
    lo, hi = (min(span), max(span)) if span else (-math.inf, math.inf)
    slack = 1e-9 * max(1.0, abs(lo), abs(hi)) if span else 0.0
    out = []
    for i, e in enumerate(raw):
        if not (isinstance(e, dict) and isinstance(e.get("name"), str) and _is_number(e.get("t"))
                and isinstance(e.get("state"), dict)):
            raise ValueError(f"`events[{i}]` must be a table with a name, a time t and a state")
        if not (math.isfinite(e["t"]) and lo - slack <= e["t"] <= hi + slack):
            raise ValueError(f"`events[{i}].t` is {e['t']!r}, outside the run's time span [{lo:g}, {hi:g}]")
        if "exact_t" in e and not _is_number(e["exact_t"]):
            raise ValueError(f"`events[{i}].exact_t` must be a number; got {e['exact_t']!r:.40}")
        if "exact_t" in e and not (math.isfinite(e["exact_t"])
                                   and abs(e["exact_t"]) <= 1e6 * max(1.0, abs(lo) if span else 1e300, abs(hi))):
            raise ValueError(f"`events[{i}].exact_t` must be a finite time near the run's span; got {e['exact_t']!r}")
        for key in ("index", "occurrence"):
            if key in e and not (isinstance(e[key], int) and not isinstance(e[key], bool) and 0 <= e[key] < 2**31):
                raise ValueError(f"`events[{i}].{key}` must be a whole number; got {e[key]!r}")
        for key in ("state", "reset"):
            if key not in e:
                continue
            if not isinstance(e[key], dict):
                raise ValueError(f"`events[{i}].{key}` must be a table")
            bad = next((k for k, v in e[key].items() if not _is_number(v)), None)
            if bad is not None:
                raise ValueError(f"`events[{i}].{key}.{bad}` must be a number; got {e[key][bad]!r}")
        out.append(e)
    return tuple(out)


# The shapes of what odelab stores under ``extra`` and the report reads: a type, a list of one
# shape ([shape]), a table of known keys ({key: shape}; other keys are let through), or a table
# of any keys with one shape ({str: shape}). A record of another shape was not written by odelab.
_NUM = "number"
_MAYBE = "number or null"
_NAMES = [str]
_MATRIX = [[_NUM]]
_COMPLEX = {"re": _NUM, "im": _NUM}


class Optional:
    """A key of a table shape that odelab does not always write (every other listed key must be there:
    the report reads it without asking)."""

    def __init__(self, shape) -> None:
        self.shape = shape


_EXTRA_SHAPES = {
    "input_jumps": {"t": [_NUM], "before": [[_NUM]], "after": [[_NUM]]},
    "diagram": {"linear": bool, "dot": str, "states": _NAMES, "inputs": _NAMES, "outputs": _NAMES,
                "A": Optional(_MATRIX), "B": Optional(_MATRIX), "C": Optional(_MATRIX), "D": Optional(_MATRIX)},
    "analysis": {
        "states": _NAMES, "inputs": _NAMES, "outputs": _NAMES, "A": _MATRIX, "B": _MATRIX, "C": _MATRIX,
        "D": _MATRIX,
        "operating_point": Optional({"x": {str: _NUM}, "u": {str: _NUM}, "residual": _MAYBE}),
        "transfer_functions": [{"output": str, "input": str, "num": [_NUM], "den": [_NUM], "text": _NAMES,
                                "dc_gain": _MAYBE}],
        "poles": Optional([{"re": _NUM, "im": _NUM, "wn": _MAYBE, "zeta": _MAYBE}]),
        "zeros": Optional({str: [_COMPLEX]}),
        "step_info": Optional([{"output": str, "input": str, str: _MAYBE}]),
        "margins": Optional([{"output": str, "input": str, str: _MAYBE}]),
        "bode": Optional({"w": [_NUM], "channels": [{"output": str, "input": str, "magnitude_db": [_MAYBE],
                                                     "phase_deg": [_MAYBE]}]}),
        "loop": Optional({"at": str, "num": [_NUM], "den": [_NUM], "text": _NAMES,
                          "bode": {"w": [_NUM], "magnitude_db": [_MAYBE], "phase_deg": [_MAYBE]}, str: _MAYBE}),
    },
}


def _check_shape(value, shape, where: str) -> None:
    if isinstance(shape, Optional):
        shape = shape.shape
    if shape == _NUM or shape == _MAYBE:
        if not (_is_number(value) or (shape == _MAYBE and value is None)):
            raise ValueError(f"`{where}` must be a number; got {value!r:.40}")
    elif isinstance(shape, type):
        if not isinstance(value, shape) or (shape is not bool and isinstance(value, bool)):
            raise ValueError(f"`{where}` must be {shape.__name__}; got {type(value).__name__}")
    elif isinstance(shape, list):
        if not isinstance(value, list):
            raise ValueError(f"`{where}` must be a list; got {type(value).__name__}")
        for i, item in enumerate(value):
            _check_shape(item, shape[0], f"{where}[{i}]")
    elif isinstance(shape, dict):
        if not isinstance(value, dict):
            raise ValueError(f"`{where}` must be a table; got {type(value).__name__}")
        missing = [k for k, s in shape.items() if k is not str and not isinstance(s, Optional) and k not in value]
        if missing:
            raise ValueError(f"`{where}` has no `{missing[0]}`, which odelab always writes")
        rest = shape.get(str)
        for key, item in value.items():
            if key in shape:
                _check_shape(item, shape[key], f"{where}.{key}")
            elif rest is not None:
                _check_shape(item, rest, f"{where}.{key}")


def _check_matrices(d: dict, where: str) -> None:
    """A, B, C, D of a stored linear model: states x states, states x inputs, outputs x ..."""
    dims = {"A": ("states", "states"), "B": ("states", "inputs"), "C": ("outputs", "states"),
            "D": ("outputs", "inputs")}
    for name, (rows, cols) in dims.items():
        if name in d and isinstance(d.get(rows), list) and isinstance(d.get(cols), list):
            M = d[name]
            if len(M) != len(d[rows]) or any(len(r) != len(d[cols]) for r in M):
                raise ValueError(f"`{where}.{name}` is not {len(d[rows])} x {len(d[cols])} ({rows} x {cols})")


def check_extra(extra: dict) -> None:
    """``extra["diagram"]`` and ``extra["analysis"]`` of the shape odelab writes (ValueError if not)."""
    for key, shape in _EXTRA_SHAPES.items():
        if key in extra:
            _check_shape(extra[key], shape, f"extra.{key}")
            _check_matrices(extra[key], f"extra.{key}")
