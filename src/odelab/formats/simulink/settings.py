"""A model's solver settings -> ``[time]`` and ``[solver]`` (Simulink's defaults where the model leaves them).

Simulink's defaults: StartTime 0, StopTime 10, RelTol 1e-3, AbsTol auto, MaxStep auto (the span
over 50), Refine 1, the solver VariableStepAuto. The ode-named variable-step solvers are odelab's
methods of the same names (MATLAB's); ``VariableStepAuto`` is ode45 (what Simulink chooses for a
model with continuous states); the fixed-step ode1, ode2, ode3, ode4 are euler, heun, rk3 and rk4
(Simulink's ode3 is Bogacki-Shampine's third-order formula, odelab's rk3 Kutta's: the same order,
different round-off and truncation), ode5 and ode8 have no fixed-step peer in odelab and run as rk4
with a note.
"""

from __future__ import annotations

import math

from odelab.formats.base import TRANSLATED, Note
from odelab.formats.simulink.mexpr import MExprError, evaluate

__all__ = ["SOLVERS", "settings"]

#: Simulink's solver -> (odelab's method, what the note says; empty when it is the same method)
SOLVERS = {
    **{m: (m, "") for m in ("ode45", "ode23", "ode113", "ode15s", "ode23s", "ode23t", "ode23tb")},
    "VariableStepAuto": ("ode45", "VariableStepAuto is ode45 for a model with continuous states (Simulink's choice)"),
    "VariableStepDiscrete": ("ode45", "the discrete solver: odelab steps the discrete blocks at their hits with ode45 "
                             "between them (there is nothing continuous to integrate)"),
    "daessc": ("ode15s", "daessc (a DAE solver for Simscape) as ode15s"),
    "ode1": ("euler", ""), "ode2": ("heun", ""), "ode4": ("rk4", ""),
    "ode3": ("rk3", "Simulink's ode3 is the Bogacki-Shampine third-order formula; odelab's rk3 is Kutta's third-order "
             "formula (same order, different digits)"),
    "ode5": ("rk4", "ode5 (fixed-step Dormand-Prince) has no fixed-step peer in odelab: rk4, one order lower"),
    "ode8": ("rk4", "ode8 (fixed-step Dormand-Prince 8) has no fixed-step peer in odelab: rk4"),
    "ode14x": ("rk4", "ode14x (implicit extrapolation) has no peer in odelab: the explicit rk4"),
    "ode1be": ("rk4", "ode1be (backward Euler) has no fixed-step peer in odelab: the explicit rk4"),
    "FixedStepAuto": ("rk3", "FixedStepAuto is ode3 for a model with continuous states (Simulink's choice), here "
                      "odelab's rk3 (Kutta's third-order formula)"),
    "FixedStepDiscrete": ("rk4", "the discrete fixed-step solver: odelab steps the discrete blocks at their hits"),
}


def _number(text: str, lookup, what: str, notes: list, default: float | None):
    if text is None or text.strip().lower() in ("auto", "", "-1"):
        return default
    missing: set[str] = set()
    try:
        value = evaluate(text, lookup, missing)
    except MExprError as exc:
        notes.append(Note("model", what, TRANSLATED, f"{text!r} is not a number this importer reads ({exc}); "
                          f"Simulink's default {default!r} is used"))
        return default
    if value.num.size < 1 or missing:
        return default
    return float(value.num.reshape(-1)[0])


def _time(text: str, lookup, default: float):
    """A start or stop time: a number, or an expression of the parameters (``tf``) with its number."""
    try:
        value = evaluate(text, lookup)
    except MExprError:
        return default, default
    number = float(value.num.reshape(-1)[0])
    if value.sym is not None:
        return str(value.texts().reshape(-1)[0]), number
    return number, number


def settings(solver: dict, lookup, sample_times: list[float]):
    """([time] entries, [solver] entries, fixed step or None, notes); each entry (key, value, comment)."""
    notes: list[Note] = []
    start, t0 = _time(solver.get("StartTime", "0.0"), lookup, 0.0)
    stop, tf = _time(solver.get("StopTime", "10.0"), lookup, 10.0)
    time = [("start", start, f"StartTime {solver.get('StartTime', '0.0 (the default)')}"),
            ("stop", stop, f"StopTime {solver.get('StopTime', '10.0 (the default)')}")]
    if not math.isfinite(tf):
        time[1] = ("stop", None, "StopTime inf: the model runs until a Stop block ends it")
    name = solver.get("Solver", "VariableStepAuto").strip() or "VariableStepAuto"
    method, why = SOLVERS.get(name, ("ode45", f"the solver {name!r} is not one odelab knows: ode45"))
    span = (tf - t0) if math.isfinite(tf) else 10.0
    entries = [("method", method, f"Solver {name}" + (f": {why}" if why else ""))]
    fixed = method in ("euler", "heun", "rk3", "rk4")
    step = None
    if fixed:
        h = _number(solver.get("FixedStep", "auto"), lookup, "FixedStep", notes, None)
        if h is None:
            h = min([span / 50, *[t for t in sample_times if t > 0]])
            entries.append(("h", h, "FixedStep auto: the span over 50, or the fastest sample time"))
        else:
            entries.append(("h", h, f"FixedStep {solver.get('FixedStep')}"))
        step = h
    else:
        rtol = _number(solver.get("RelTol", "1e-3"), lookup, "RelTol", notes, 1e-3)
        atol_text = solver.get("AbsTol", "auto")
        atol = _number(atol_text, lookup, "AbsTol", notes, 1e-6)
        max_step = _number(solver.get("MaxStep", "auto"), lookup, "MaxStep", notes, span / 50)
        entries += [("rtol", rtol, f"RelTol {solver.get('RelTol', '1e-3 (the default)')}"),
                    ("atol", atol, f"AbsTol {atol_text}" + (": Simulink starts from 1e-6 and raises it with the "
                                                            "states' size; odelab keeps 1e-6" if atol_text.strip().lower() == "auto" else "")),
                    ("max_step", max_step, f"MaxStep {solver.get('MaxStep', 'auto')}" + (" (the span over 50)"
                                                                                        if solver.get("MaxStep", "auto").strip().lower() == "auto" else ""))]
        initial = _number(solver.get("InitialStep", "auto"), lookup, "InitialStep", notes, None)
        if initial is not None and initial > 0:
            entries.append(("initial_step", initial, f"InitialStep {solver.get('InitialStep')}"))
        refine = _number(solver.get("Refine", "1"), lookup, "Refine", notes, 1.0)
        entries.append(("refine", int(refine) if refine and refine >= 1 else 1, "Refine (Simulink's default 1: "
                                                                                  "one output point per step)"))
        if method == "ode15s" and solver.get("MaxOrder", "5").strip() not in ("5", ""):
            entries.append(("max_order", int(_number(solver["MaxOrder"], lookup, "MaxOrder", notes, 5.0)),
                            f"MaxOrder {solver['MaxOrder']}"))
    if solver.get("ZeroCrossControl", "UseLocalSettings") == "DisableAll":
        entries.append(("zero_crossing", False, "ZeroCrossControl DisableAll"))
    return time, entries, step, notes
