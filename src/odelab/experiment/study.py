"""Studies over a sweep's cases: the ``[study]`` table, the sweep's summary table, the study result.

```toml
[study]
kind = "convergence"      # or "work-precision"
over = "solver.h"         # the swept key on the x axis (default: solver.h, else solver.rtol)
error = "max"             # "max": largest error over the span; "end": at the final time
quantity = "y"            # the state or output measured (default: the first output, else state)
```

The curves are the values of the other swept keys (usually ``solver.method``). What each kind
computes and shows is its class in :mod:`odelab.experiment.studykinds` (the registry
``STUDY_KINDS``); this module checks the table and gathers the numbers from the results.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.exceptions import ExperimentError
from odelab.experiment.studykinds import STUDY_KINDS
from odelab.experiment.sweep import format_value

__all__ = ["STUDY_KINDS", "StudySpec", "parse_study", "run_study", "sweep_rows", "study_keys"]

_COMMON_KEYS = ("kind", "over", "error", "quantity")


def study_keys() -> tuple[str, ...]:
    """Every key [study] knows: the common ones, then each registered kind's own."""
    own = [k for kind in STUDY_KINDS.values() for k in kind.KEYS]
    return _COMMON_KEYS + tuple(dict.fromkeys(own))


@dataclass(frozen=True)
class StudySpec:
    kind: str
    over: str
    error: str
    quantity: str
    options: dict[str, Any] = field(default_factory=dict, compare=False)  # the kind's own keys

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "over": self.over, "error": self.error, "quantity": self.quantity, **self.options}


def parse_study(spec: Any, sweep, cases) -> StudySpec:
    """Check ``[study]`` against the sweep and the loaded cases."""
    names = " or ".join(f'"{name}"' for name in STUDY_KINDS)
    if not isinstance(spec, dict):
        raise ExperimentError(f"`study` must be a table: [study] with kind = {names}.", key="study")
    known = study_keys()
    for key in spec:
        if key not in known:
            close = difflib.get_close_matches(key, known, n=1)
            hint = f" Did you mean `{close[0]}`?" if close else ""
            raise ExperimentError(f"unknown key `study.{key}`.{hint} Known keys in [study]: {', '.join(known)}.",
                                  key=f"study.{key}")
    kind = spec.get("kind")
    if kind not in STUDY_KINDS:
        choices = " or ".join(f'"{name}" ({k.DOC})' for name, k in STUDY_KINDS.items())
        raise ExperimentError(f"`study.kind` is {kind!r}; it must be {choices}.", key="study.kind")
    study_kind = STUDY_KINDS[kind]
    foreign = [k for k in spec if k not in _COMMON_KEYS and k not in study_kind.KEYS]
    if foreign:
        raise ExperimentError(f"`study.{foreign[0]}` is not a key of a {kind} study; its keys: "
                              f"{', '.join((*_COMMON_KEYS, *study_kind.KEYS))}.", key=f"study.{foreign[0]}")
    keys = sweep.keys
    over = spec.get("over", study_kind.default_over(tuple(keys)))
    if over not in keys:
        swept = ", ".join(f'"{k}"' for k in keys)
        raise ExperimentError(f"`study.over` is {over!r}, but the sweep does not sweep it (it sweeps {swept}): "
                              f"add \"{over}\" to [sweep] or set `study.over`.", key="study.over")
    values = sweep.values[keys.index(over)]
    if any(isinstance(v, bool) or not isinstance(v, (int, float)) or v <= 0 for v in values):
        raise ExperimentError(f"`study.over` is {over!r}, whose swept values must be positive numbers for a log-log "
                              f"study; got {', '.join(format_value(v) for v in values)}.", key="study.over")
    error = spec.get("error", study_kind.ERROR)
    if error not in ("max", "end"):
        raise ExperimentError(f"`study.error` is {error!r}; it must be \"max\" (the largest error over the span) "
                              "or \"end\" (the error at the final time).", key="study.error")
    problem = cases[0].problem
    names = (*problem.states, *problem.outputs)
    quantity = spec.get("quantity", problem.outputs[0] if problem.outputs else problem.states[0])
    if quantity not in names:
        raise ExperimentError(f"`study.quantity` is {quantity!r}, not a state or output of the system "
                              f"({', '.join(names)}).", key="study.quantity")
    if problem.reference == "none" and any(c.problem.reference == "none" for c in cases):
        raise ExperimentError("a study measures errors, but the experiment has no reference: add [exact], or "
                              "[reference] method = \"high-accuracy\".", key="study")
    study_kind.check_cases(over, cases)
    options = {k: spec.get(k, default) for k, default in study_kind.KEYS.items()}
    return StudySpec(kind=kind, over=over, error=error, quantity=quantity, options=options)


def _end_errors(result) -> dict[str, float]:
    series = result.series()
    out = {}
    for name, ref in result.reference.items():
        if ref.size and name in series:
            out[name] = float(abs(series[name][-1] - ref[-1]))
    return out


def _metrics(result) -> dict[str, dict[str, float]]:
    """Quantities of interest of each shown series: final value, peak, trough, overshoot, peak time."""
    p = result.case.problem
    series = result.series()
    names = list(p.outputs) or list(p.states)
    out = {}
    for name in names:
        v = series.get(name)
        if v is None or v.size == 0 or not np.all(np.isfinite(v)):
            continue
        final = float(v[-1])
        peak = float(np.max(v))
        start = float(v[0])
        rise = final - start  # overshoot as MATLAB's stepinfo: beyond the final value, relative to the change
        if abs(rise) <= 1e-12 * max(1.0, abs(final)):
            overshoot = math.nan
        elif rise > 0:
            overshoot = 100.0 * (peak - final) / rise
        else:
            overshoot = 100.0 * (final - float(np.min(v))) / -rise
        out[name] = {"final": final, "max": peak, "min": float(np.min(v)), "t_max": float(result.t[int(np.argmax(v))]),
                     "overshoot_percent": overshoot, "settled": _settled(result.t, v, rise)}
    return out


# A response counts as settled when it stays within 2 % of the change (stepinfo's band) of its
# last value over the last tenth of the span: then "overshoot beyond the final value" means what
# stepinfo means; otherwise the last value is not yet the steady state and the report says so.
SETTLED_BAND = 0.02


def _settled(t: np.ndarray, v: np.ndarray, rise: float) -> bool:
    if t.size < 2 or not rise:
        return True
    tail = v[t >= t[-1] - 0.1 * (t[-1] - t[0])]
    return bool(np.max(np.abs(tail - v[-1])) <= SETTLED_BAND * abs(rise))


def is_quadrature(problem) -> bool:
    """Whether dy/dt = f(t) only (a pure quadrature, as Exercise 1): f is unchanged when the state is moved."""
    x0 = np.asarray(problem.x0, dtype=float)
    t0, t1 = float(problem.tspan[0]), float(problem.tspan[-1])
    try:
        for t in (t0, t0 + 0.37 * (t1 - t0), t1):
            for shift in (1.0, -2.5):
                moved = x0 + shift * (1.0 + np.abs(x0))
                if not np.array_equal(np.asarray(problem.system.fun(t, x0.copy()), dtype=float),
                                      np.asarray(problem.system.fun(t, moved), dtype=float)):
                    return False
    except Exception:  # a right-hand side that cannot take the moved state: not a plain quadrature
        return False
    return True


def sweep_rows(results) -> list[dict[str, Any]]:
    """One row per case: its swept values, method, status, statistics and errors (JSON-ready)."""
    rows = []
    quadrature: dict[int, bool] = {}  # by problem: a sweep's cases usually share one right-hand side
    for r in results:
        fun = r.case.problem.system.fun
        if id(fun) not in quadrature:
            quadrature[id(fun)] = is_quadrature(r.case.problem)
        ends = _end_errors(r)
        row: dict[str, Any] = {
            "case": r.case.name,
            "swept": dict(r.case.swept),
            "method": r.case.problem.method,
            "status": r.status,
            "message": r.message,
            "nsteps": r.stats.nsteps,
            "nfailed": r.stats.nfailed,
            "nfevals": r.stats.nfevals,
            "elapsed_s": r.elapsed,
            "span": float(abs(r.case.problem.tspan[-1] - r.case.problem.tspan[0])),
            "max_abs": {n: e.max_abs for n, e in r.errors.items()},
            "max_rel": {n: e.max_rel for n, e in r.errors.items()},
            "end_abs": ends,
            "scale": {n: float(np.max(np.abs(v))) if v.size else 0.0 for n, v in r.reference.items()},
            "metrics": _metrics(r),
            # [analysis] step_info: MATLAB's stepinfo of each channel of the case's linear model
            "step_info": list((r.extra.get("analysis") or {}).get("step_info") or []),
            # the global error estimate, when the case has one (odelab.run.estimate): max error and digits
            **_estimate_columns(r),
            "quadrature": quadrature[id(fun)],  # dy/dt = f(t): a method shows its quadrature rule's order
        }
        rows.append(row)
    return rows


def _estimate_columns(r) -> dict[str, Any]:
    est = getattr(r, "estimate", None) or {}
    quantities = est.get("quantities")
    if not isinstance(quantities, dict):
        return {}
    return {"est_abs": {n: q.get("max_abs") for n, q in quantities.items()},
            "est_digits": {n: q.get("digits") for n, q in quantities.items()},
            "estimate": est.get("verdict")}


def _curve_label(row: dict, over: str) -> str:
    others = {k: v for k, v in row["swept"].items() if k != over}
    if not others:
        return row["method"]
    return ", ".join(format_value(v) if k == "solver.method" else f"{k.rsplit('.', 1)[-1]}={format_value(v)}"
                     for k, v in others.items())


def run_study(spec: StudySpec, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The study's result (JSON-ready): one fit or curve per value of the other swept keys (its kind's)."""
    kind = STUDY_KINDS[spec.kind]
    groups: dict[str, list[dict]] = {}
    for row in rows:
        groups.setdefault(_curve_label(row, spec.over), []).append(row)
    measure = "max_abs" if spec.error == "max" else "end_abs"
    curves = []
    warnings: list[str] = []
    for label, members in groups.items():
        x = [float(m["swept"][spec.over]) for m in members]
        err = [float(m[measure].get(spec.quantity, math.nan)) if m["status"] == "success" else math.nan
               for m in members]
        curve, notes = kind.curve(spec, label, x, err, members)
        curves.append(curve)
        warnings.extend(notes)
    return {**spec.as_dict(), "curves": curves, "warnings": warnings}
