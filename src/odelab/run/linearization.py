"""Cases with a [linearize] section: the lab's linear-versus-nonlinear comparison.

The case's system is linearised about its operating point (found from the input ū, or
checked when x̄ is given); the nonlinear model and the linear one (in incremental variables,
x̄ added back) are driven by the case's input from the same initial state, and their
difference is the case's error table. With ``amplitudes``, the comparison is repeated for
steps of those sizes on top of ū, giving the linearisation error against amplitude and the
largest amplitude whose error stays under ``threshold``.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from odelab.analysis.errors import summarize
from odelab.exceptions import ExperimentError
from odelab.experiment.cases import Case
from odelab.store.result import CaseResult

__all__ = ["run_linearization_case"]


def _vector(values, names, key, params, default=0.0) -> np.ndarray:
    from odelab.expressions import evaluate_constant

    values = values or {}
    for name in values:
        if name not in names:
            raise ExperimentError(f"`{key}.{name}`: {name!r} is not one of {', '.join(names) or 'nothing'}.",
                                  key=f"{key}.{name}")
    return np.array([evaluate_constant(values.get(n, default), values=params, key=f"{key}.{n}") for n in names])


def _mapping(values, names, key, params):
    from odelab.expressions import evaluate_constant

    if not values:
        return None
    for name in values:
        if name not in names:
            raise ExperimentError(f"`{key}.{name}`: {name!r} is not one of the states ({', '.join(names)}).",
                                  key=f"{key}.{name}")
    return {n: evaluate_constant(v, values=params, key=f"{key}.{n}") for n, v in values.items()}


def run_linearization_case(case: Case, *, max_steps: int | None = None) -> CaseResult:
    """Linearise, compare with the nonlinear model and (optionally) sweep input amplitudes."""
    from odelab.analysis.linearize import amplitude_study, compare_linearization, linearize
    from odelab.signals import Constant, Step

    p = case.problem
    spec = p.linearize
    system = p.system.model
    params = p.parameters
    u_bar = _vector(spec.input, p.inputs, "linearize.input", params)
    x_bar = _vector(spec.state, p.states, "linearize.state", params) if spec.state else None
    guess = _mapping(spec.guess, p.states, "linearize.guess", params)
    fixed = _mapping(spec.fixed, p.states, "linearize.fixed", params)
    options = dict(p.options)
    if max_steps and "h" not in options:
        from odelab.experiment.limits import capped_max_steps

        options["max_steps"] = capped_max_steps(options.get("max_steps"), max_steps)[0]

    start = time.perf_counter()
    notes: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            lin = linearize(system, x0=x_bar, u0=u_bar, x_guess=guess, fixed=fixed)
        except ExperimentError:
            raise
        except ValueError as exc:  # no equilibrium for that input, and similar: the file's problem
            raise ExperimentError(f"`linearize`: {exc}", key="linearize") from None
    notes.extend(str(w.message) for w in caught)
    op = lin.operating_point
    start_from = _start(case, spec, op.x, notes)
    x_init = op.x if start_from == "operating-point" else p.x0
    # the inputs held at the operating point (or the file's signals); None for a system without inputs
    u = list(p.system.signals) if p.system.signals else [Constant(float(v)) for v in u_bar] if p.inputs else None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cmp = compare_linearization(system, lin, u, x_init, p.tspan, method=p.method, **options)
    notes.extend(str(w.message) for w in caught)
    nl = cmp.nonlinear
    result = CaseResult(case=case, status=cmp.status, message=cmp.message or nl.message, stats=nl.stats,
                        elapsed=time.perf_counter() - start, t=cmp.t, x=cmp.x_nonlinear, u=cmp.u,
                        y=cmp.y_nonlinear if p.outputs else None, warnings=notes)
    result.record_input_jumps()
    result.reference_kind = "linearization"
    reference = {n: cmp.x_linear[:, i] for i, n in enumerate(p.states)}
    if p.outputs:
        reference.update({n: cmp.y_linear[:, i] for i, n in enumerate(p.outputs)})
    series = result.series()
    for name, values in reference.items():
        result.reference[name] = values
        result.errors[name] = summarize(name, result.t, series[name], values)

    info = {
        "operating_point": {
            "x": dict(zip(p.states, op.x.tolist())),
            "u": dict(zip(p.inputs, op.u.tolist())),
            "y": dict(zip(lin.outputs, op.y.tolist())),
            "residual": float(op.residual),
        },
        "A": lin.A.tolist(), "B": lin.B.tolist(), "C": lin.C.tolist(), "D": lin.D.tolist(),
        "states": list(lin.states), "inputs": list(lin.inputs), "outputs": list(lin.outputs),
        "start": start_from,
    }
    if spec.amplitudes:
        drive = spec.drive or (p.inputs[0] if p.inputs else None)
        if drive not in p.inputs:
            raise ExperimentError(f"`linearize.drive` is {drive!r}, not one of the inputs ({', '.join(p.inputs)}).",
                                  key="linearize.drive")
        quantity = spec.quantity or (p.outputs[0] if p.outputs else p.states[0])
        if quantity not in p.states + p.outputs:
            raise ExperimentError(f"`linearize.quantity` is {quantity!r}, not a state or output "
                                  f"({', '.join(p.states + p.outputs)}).", key="linearize.quantity")
        k = p.inputs.index(drive)

        def make_input(amplitude):
            return [Step(time=float(spec.step_time), initial=float(u_bar[j]), final=float(u_bar[j] + amplitude))
                    if j == k else Constant(float(u_bar[j])) for j in range(len(p.inputs))]

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            study = amplitude_study(system, lin, make_input, spec.amplitudes, x_init, p.tspan,
                                    threshold=float(spec.threshold), quantity=quantity, method=p.method, **options)
        notes.extend(str(w.message) for w in caught)
        info.update({
            "drive": drive,
            "step_time": float(spec.step_time),
            "threshold": float(study.threshold),
            "quantity": study.quantity,
            "amplitudes": study.amplitudes.tolist(),
            "errors": {n: np.asarray(v).tolist() for n, v in study.max_rel_error.items()},
            "abs_errors": {n: np.asarray(v).tolist() for n, v in study.max_abs_error.items()},
            "max_amplitude_within": study.max_amplitude_within,
            "threshold_amplitude": study.threshold_amplitude,
            "slope": _slope(study),
            "comparisons": [
                {"amplitude": float(a), "t": c.t.tolist(),
                 "nonlinear": {n: c.y_nonlinear[:, i].tolist() for i, n in enumerate(p.outputs)}
                 | {n: c.x_nonlinear[:, i].tolist() for i, n in enumerate(p.states)},
                 "linear": {n: c.y_linear[:, i].tolist() for i, n in enumerate(p.outputs)}
                 | {n: c.x_linear[:, i].tolist() for i, n in enumerate(p.states)},
                 "status": c.status}
                for a, c in zip(study.amplitudes, study.comparisons)],
        })
    result.extra["linearization"] = info
    if p.analysis is not None:  # [analysis] of the linear model [linearize] made, about its operating point
        result.extra["analysis"] = _analysis(lin, p, info["operating_point"])
    return result


def _start(case: Case, spec, x_bar: np.ndarray, notes: list[str]) -> str:
    """Where both models start (``linearize.start``, which loading resolved: the file's [initial] when it gives
    one and the file does not say); [initial] values that are not used are said."""
    p = case.problem
    if spec.start == "operating-point" and p.initial_given:
        x0 = np.asarray(p.x0, dtype=float)
        differ = [f"{n} = {x0[i]:.6g}" for i, n in enumerate(p.states) if n in p.initial_given and x0[i] != x_bar[i]]
        if differ:
            notes.append(f"[initial] ({', '.join(differ)}) is not used: linearize.start = \"operating-point\" starts "
                         "both models at the operating point; write start = \"initial\" to start them from [initial]")
    return spec.start


def _analysis(lin, p, point: dict) -> dict:
    """[analysis] with [linearize]: transfer functions, poles, stepinfo, Bode and margins of its linear model."""
    from odelab.analysis.control import analyze

    spec = p.analysis
    linearized_at = {"x": point["x"], "u": point["u"], "residual": point["residual"]}
    return analyze(lin, step_info=spec["step_info"], bode_range=spec["bode"], show_poles=spec["poles"],
                   linearized_at=linearized_at, with_margins=True)


def _slope(study) -> float | None:
    try:
        value = float(study.slope())
    except (ValueError, ZeroDivisionError, FloatingPointError):
        return None
    return value if np.isfinite(value) else None
