"""Per-section checks of a case: [units], [linearize], [analysis], [report] and a hand-written Jacobian.

Each raises an :class:`~odelab.exceptions.ExperimentError` naming the key, when the file is
loaded rather than halfway through a run; :func:`odelab.experiment.compile.compile_case` calls them.
"""

from __future__ import annotations

import difflib
import math

import numpy as np

from odelab.exceptions import ExperimentError
from odelab.experiment import schema
from odelab.experiment.fields import constant, mathtext_problem

__all__ = ["check_analysis", "check_jacobian", "check_linearize", "check_report", "check_units"]


MAX_QUOTED = 20


def check_report(spec: schema.Report) -> dict:
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
    return spec.model_dump(exclude_none=True)  # strings, a number, a list of strings: TOML as they are


def check_units(units: dict[str, str], states, inputs, outputs, params) -> dict[str, str]:
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


def check_jacobian(jacobian, system, states, params, t0: float, x0: np.ndarray) -> None:
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


def check_linearize(spec: schema.Linearize, states, inputs, outputs, built) -> None:
    """Catch [linearize] mistakes when the file is loaded, not halfway through a run."""
    if built.model is None:
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


def check_analysis(spec: schema.Analysis, inputs, built, params) -> dict:
    """[analysis] checked at load time; returns what the runner needs."""
    if built.model is None:
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
