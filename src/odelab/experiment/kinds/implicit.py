"""Experiment files with fully implicit systems: ``kind = "implicit"``, [system.residuals] with ``der(x)``.

```toml
[system]
kind = "implicit"
states = ["y"]
[system.residuals]              # each residual = 0; der(y) is y'
r = "t*y^2*der(y)^3 - y^3*der(y)^2 + t*(t^2 + 1)*der(y) - t^2*y"
[initial]
y = "sqrt(3/2)"
"der(y)" = 0                    # a guess; decic makes it consistent
[initial.fixed]                 # what decic may not change (default: the states)
y = true
[solver]
method = "ode15i"               # the default for kind = "implicit"
```

The residuals become an :class:`odelab.systems.implicit.ImplicitSystem`; the initial values and
the ``der()`` guesses (default 0) are made consistent by MATLAB's decic at load time, so a file
whose initial conditions cannot be made consistent is refused with decic's reason and the keys
to change; the case then runs with ode15i through :func:`odelab.solve` like any other system.
What an implicit system cannot do yet (inputs, linearisation, control analysis, fitting, the
compiled backend, a high-accuracy reference) is said with the fix.
"""

from __future__ import annotations

import re

import numpy as np

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.cases import Built
from odelab.experiment.fields import constant, expr
from odelab.solvers.optionset import DEFAULT_ATOL, DEFAULT_RTOL
from odelab.solvers.registry import join_names, methods_with
from odelab.systems.outputs import ExpressionOutputs

__all__ = ["build_implicit", "is_implicit_system", "implicit_method_name", "check_implicit_case",
           "split_initial", "consistent_start"]

_DER_KEY = re.compile(r"^\s*der\s*\(\s*([A-Za-z_][A-Za-z0-9_]*)\s*\)\s*$")


def is_implicit_system(built: Built) -> bool:
    return hasattr(built.fun, "residual") and hasattr(built.fun, "partials") and hasattr(built.fun, "start")


def build_implicit(model: schema.Experiment, params: dict[str, float]) -> Built:
    """The system of [system.residuals] (and [system.outputs], expressions of t and the states)."""
    from odelab.experiment.build import check_names
    from odelab.systems.implicit import ImplicitSystem

    system = model.system
    if not system.states:
        raise ExperimentError("`system.states` is required: list the state names, e.g. states = [\"y\"].",
                              key="system.states")
    states = check_names(system.states, "system.states", "state")
    clash = sorted(set(states) & set(params))
    if clash:
        raise ExperimentError(f"{clash[0]!r} is both a parameter and a state; rename one.",
                              key=f"parameters.{clash[0]}")
    for key in ("equations", "function", "A", "B", "C", "D", "jacobian"):
        if getattr(system, key) is not None:
            raise ExperimentError(f"`system.{key}` is not part of an implicit system: kind = \"implicit\" is given by "
                                  "[system.residuals] (one F = 0 per state, der(x) for x'); remove `system.{key}` or "
                                  "the kind.".replace("{key}", key), key=f"system.{key}")
    if system.inputs:
        raise ExperimentError("an implicit system takes no [inputs] yet: write the input as an expression of t in its "
                              "residual (e.g. `+ (t >= 1)` for a unit step at t = 1).", key="system.inputs")
    for section in ("linearize", "analysis"):
        if getattr(model, section) is not None:
            raise ExperimentError(f"[{section}] is not available for an implicit system yet (it linearises "
                                  "x' = f(t, x)); write the system as [system.equations] to use it.", key=section)
    if system.residuals is None:
        raise ExperimentError("[system.residuals] is required for kind = \"implicit\": one residual per state, each "
                              f"= 0 on the solution, with der(x) for x', e.g. r = \"der({states[0]}) + "
                              f"{states[0]}\".", key="system.residuals")
    implicit = ImplicitSystem(system.residuals, states, parameters=params)
    outputs: tuple[str, ...] = ()
    output_fn = None
    resolved = {"kind": "implicit", "states": list(states), "residuals": dict(system.residuals)}
    if system.outputs:
        if isinstance(system.outputs, list):
            raise ExperimentError("`system.outputs` of an implicit system is a table of expressions of t and the "
                                  "states, e.g. [system.outputs] total = \"y1 + y2\".", key="system.outputs")
        ex = expr()
        outputs = tuple(ex.check_identifier(n, key=f"system.outputs.{n}", what="output") for n in system.outputs)
        dup = sorted(set(outputs) & (set(states) | set(params)))
        if dup:
            raise ExperimentError(f"output {dup[0]!r} has the name of a state or parameter; rename it.",
                                  key=f"system.outputs.{dup[0]}")
        G = ex.compile_vector(list(system.outputs.values()), args=["t", *states], constants=params,
                              keys=[f"system.outputs.{n}" for n in outputs])
        output_fn = ExpressionOutputs(G, len(outputs))  # no inputs: g(t, x)

        resolved["outputs"] = dict(system.outputs)
    return Built(states=states, inputs=(), outputs=outputs, fun=implicit, output_fn=output_fn, resolved=resolved)


def implicit_method_name(model: schema.Experiment, built: Built, name: str) -> str:
    """[solver] method for an implicit system (ode15i when none is given, or "auto"), and the message when a
    method for y' = f meets one, or ode15i meets a system of another kind."""
    if is_implicit_system(built) and ((isinstance(name, str) and name.lower() == "auto")
                                      or "method" not in model.solver.model_fields_set):
        return methods_with(lambda m: True, residual=True)[0]
    return name


def check_implicit_case(model: schema.Experiment, built: Built, method, reference_kind: str) -> None:
    """ode15i for implicit systems only, and only them by ode15i; the references an implicit system has."""
    implicit = is_implicit_system(built)
    if implicit and not method.residual:
        names = join_names([f'"{n}"' for n in methods_with(lambda m: True, residual=True)], "or")
        raise ExperimentError(f"`solver.method` is {method.name!r}, which solves x' = f(t, x); an implicit system "
                              f"(kind = \"implicit\", der() in its residuals) is solved by {names} (MATLAB's solver "
                              "for F(t, x, x') = 0).", key="solver.method")
    if method.residual and not implicit:
        raise ExperimentError(f"`solver.method` is {method.name!r}, which solves fully implicit systems "
                              "F(t, x, x') = 0: write [system] kind = \"implicit\" with [system.residuals] (der(x) for "
                              "x'), or use \"ode15s\" for x' = f(t, x) and M x' = f(t, x).", key="solver.method")
    if implicit and reference_kind in ("high-accuracy", "lti"):
        raise ExperimentError(f"`reference.method` is {reference_kind!r}, which odelab computes for x' = f(t, x); for "
                              "an implicit system give the [exact] solution (or compare a case at a tighter rtol).",
                              key="reference.method")


def split_initial(initial: dict, states: tuple[str, ...], implicit: bool):
    """[initial] as ``(values, slopes, fixed)``: the states' values, the ``"der(x)"`` guesses and the
    [initial.fixed] flags (implicit systems only; elsewhere both are refused with the reason)."""
    values, slopes, fixed = {}, {}, None
    for key, value in initial.items():
        match = _DER_KEY.match(key)
        if key == "fixed" and isinstance(value, dict):
            if not implicit:
                raise ExperimentError("[initial.fixed] says what decic may not change in an implicit system's initial "
                                      "values (kind = \"implicit\"); this system's initial values are used as given: "
                                      "remove it.", key="initial.fixed")
            fixed = value
        elif match:
            if not implicit:
                raise ExperimentError(f"`initial.\"{key}\"` guesses an initial slope, which an implicit system (kind = "
                                      "\"implicit\") needs; here the equations give x' from x: remove it.",
                                      key=f"initial.{key}")
            state = match.group(1)
            if state not in states:
                raise ExperimentError(f"`initial.\"{key}\"`: {state!r} is not a state ({', '.join(states)}).",
                                      key=f"initial.{key}")
            slopes[state] = value
        elif isinstance(value, dict):
            raise ExperimentError(f"`initial.{key}` is a table; [initial] holds the states' values (and, for an "
                                  "implicit system, \"der(x)\" guesses and [initial.fixed]).", key=f"initial.{key}")
        else:
            values[key] = value
    return values, slopes, fixed


def consistent_start(model: schema.Experiment, built: Built, x0: np.ndarray, slopes: dict, fixed, params: dict,
                     t0: float, options: dict, resolved: dict):
    """decic at load time: ``(x0, system)``, the consistent initial state and the system carrying its slope.

    ``fixed``: the [initial.fixed] table (state or "der(state)" -> true/false; default: the states
    fixed, the slopes free, as MATLAB's example). Errors name the keys to change."""
    from odelab.solvers.implicit.decic import DecicError, decic

    system = built.fun
    states = built.states
    n = len(states)
    yp0 = np.array([constant(slopes[s], f"initial.der({s})", params) if s in slopes else 0.0 for s in states])
    fixed_y = np.ones(n, dtype=int)
    fixed_yp = np.zeros(n, dtype=int)
    if fixed is not None:
        for key, flag in fixed.items():
            if not isinstance(flag, bool):
                raise ExperimentError(f"`initial.fixed.{key}` must be true or false; got {flag!r}.",
                                      key=f"initial.fixed.{key}")
            match = _DER_KEY.match(key)
            name = match.group(1) if match else key
            if name not in states:
                raise ExperimentError(f"`initial.fixed.{key}`: {name!r} is not a state ({', '.join(states)}); write a "
                                      "state (its value) or \"der(state)\" (its slope).", key=f"initial.fixed.{key}")
            (fixed_yp if match else fixed_y)[states.index(name)] = int(flag)
    rtol = float(options.get("rtol", DEFAULT_RTOL))
    atol = options.get("atol", DEFAULT_ATOL)
    try:
        y, yp, resnrm = decic(system.residual, t0, x0, fixed_y, yp0, fixed_yp,
                              {"RelTol": rtol, "AbsTol": atol, "Jacobian": system.partials})
    except DecicError as exc:
        from odelab.solvers.implicit.residual import index_problem

        why = index_problem(*system.partials(t0, x0, yp0))  # the deeper reason, when it is one
        if why is not None:
            raise _index_error(t0, why) from None
        key = "initial.fixed" if exc.key == "fixed" else "initial"
        raise ExperimentError(f"the initial conditions of [initial] cannot be made consistent (F(t0, x0, x'0) = 0): "
                              f"{exc.message}", key=key) from None
    except InputError as exc:
        raise ExperimentError(f"decic: {exc.message}", key="initial") from None
    from odelab.solvers.implicit.residual import index_problem

    why = index_problem(*system.partials(t0, y, yp))
    if why is not None:
        raise _index_error(t0, why)
    # the guesses, not decic's values: decic from the same guesses is the same start, bit for bit
    entry = {s: float(v) for s, v in zip(states, x0)}
    entry.update({f"der({s})": float(v) for s, v in zip(states, yp0)})
    entry["fixed"] = {**{s: bool(f) for s, f in zip(states, fixed_y)},
                      **{f"der({s})": bool(f) for s, f in zip(states, fixed_yp)}}
    resolved["initial"] = entry
    return y, system.with_start(t0, y, yp, fixed_y, fixed_yp), resnrm


def _index_error(t0: float, why: str) -> ExperimentError:
    return ExperimentError(f"ode15i solves ODEs and DAEs of index 1, as MATLAB's; at t = {t0:g} {why}. Write the hidden "
                           "constraints out (differentiate the algebraic residuals until the system is of index 1, "
                           "e.g. x = sin(t) gives der(x) = cos(t)).", key="system.residuals")
