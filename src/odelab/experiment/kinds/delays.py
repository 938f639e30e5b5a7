"""Experiment files with delayed states: ``lag(x, tau)`` in [system.equations] and [history].

The equations become a :class:`odelab.systems.delay.DelayEquations`, which the runner solves
with dde23 through :func:`odelab.solve` like any other system; this module checks what a delay
system cannot do yet (inputs, linearisation, control analysis) and says so, with the fix.
"""

from __future__ import annotations

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.cases import Built
from odelab.solvers.registry import DEFAULT_METHOD, DELAY_METHOD, methods_with

__all__ = ["build_delay", "is_delay_system", "check_delay_case"]


_NO_LAG = ("[history] gives x(t) for t <= t0 of delay equations, but no equation uses lag(x, tau): remove "
           "[history], or write the delayed states with lag().")


def is_delay_system(built: Built) -> bool:
    return getattr(built.fun, "lags", None) is not None and hasattr(built.fun, "ddefun")


def build_delay(model: schema.Experiment, params: dict[str, float], states: tuple[str, ...], outputs, output_fn,
                resolved: dict) -> Built:
    """A delay system from [system.equations] with ``lag(...)`` and the optional [history]."""
    from odelab.systems.delay import DelayEquations

    system = model.system
    if system.inputs:
        raise ExperimentError("a system with delayed states (lag(...)) takes no [inputs] yet: write the input as an "
                              "expression of t in its equation (e.g. `+ (t >= 1)` for a unit step at t = 1).",
                              key="system.inputs")
    for section in ("linearize", "analysis"):
        if getattr(model, section) is not None:
            raise ExperimentError(f"[{section}] is not available for delay equations (an infinite-dimensional "
                                  "system); a transport-delay block in a diagram is linearised with a Pade "
                                  "approximation.", key=section)
    if system.jacobian is not None:
        raise ExperimentError("`system.jacobian` is for the stiff solvers; dde23 is explicit and needs none: "
                              "remove it.", key="system.jacobian")
    # expression errors carry their key (system.equations.x, history.x) and a caret; the loader adds the file
    equations = DelayEquations({s: system.equations[s] for s in states}, parameters=params, history=model.history)
    if equations.lags.size == 0:
        raise ExperimentError(_NO_LAG, key="history")
    resolved = dict(resolved)
    resolved["lags"] = [float(v) for v in equations.lags]
    if equations.history_texts:
        resolved["history"] = dict(equations.history_texts)
    return Built(states=states, inputs=(), outputs=outputs, fun=equations, output_fn=output_fn, resolved=resolved)


def check_delay_case(model: schema.Experiment, method, reference_kind: str) -> None:
    """The [solver] and [reference] of a delay system: dde23 only, and no high-accuracy reference."""
    if not method.delays:
        names = methods_with(lambda m: m.delays, delays=True)
        quoted = " or ".join(f'"{n}"' for n in names)
        raise ExperimentError(f"`solver.method` is {method.name!r}, but the equations have delayed states "
                              f"(lag(...)): they are solved by {quoted} "
                              f"(MATLAB's solver for delay equations). Write method = \"{names[0]}\" (or \"auto\").",
                              key="solver.method")
    if reference_kind == "high-accuracy":
        raise ExperimentError("`reference.method` is \"high-accuracy\", which odelab computes for ordinary "
                              "equations only; for delay equations give the [exact] solution, or compare a case "
                              "at a tight rtol.", key="reference.method")


def method_name(model: schema.Experiment, built: Built) -> str:
    """[solver] method as the case runs it: ``"auto"`` (or no method at all, for a delay system) is
    the registry's DELAY_METHOD (dde23) for delay equations and its DEFAULT_METHOD (ode45) otherwise."""
    name = model.solver.method
    delayed = is_delay_system(built)
    if isinstance(name, str) and name.lower() == "auto":
        return DELAY_METHOD if delayed else DEFAULT_METHOD
    if delayed and "method" not in model.solver.model_fields_set:
        return DELAY_METHOD
    return name


def check_delay_method(model: schema.Experiment, built: Built, method) -> None:
    """A delay system runs with dde23 only; [history] belongs to delay equations; its [events] are
    located by dde23, without resets."""
    if not is_delay_system(built):
        if model.history is not None:
            raise ExperimentError(_NO_LAG, key="history")
        if method.delays:
            raise ExperimentError(f"`solver.method` is \"{method.name}\", MATLAB's solver for delay equations, but this "
                                  "system has no delayed states (lag(x, tau) in [system.equations]): use ode23 or "
                                  "ode45.", key="solver.method")
        return
    for name, spec in (model.events or {}).items():
        if isinstance(spec, dict) and "reset" in spec:
            # a restart needs the whole past as its history (MATLAB: dde23(ddefun, lags, sol, [te tf]))
            raise ExperimentError(f"`events.{name}.reset`: restarting delay equations after an event is not supported "
                                  "yet (the restart needs the solution so far as its history); events that stop the "
                                  "run (terminal = true) or are only recorded work. Remove `reset`.",
                                  key=f"events.{name}.reset")
    check_delay_case(model, method, "")


def build_delay_diagram(model: schema.Experiment, compiled, outputs: dict, t0: float) -> Built:
    """A diagram with transport-delay blocks: delay equations solved by dde23
    (:class:`odelab.systems.diagram.delay.DelayDiagram`). Its sources drive it as functions of t
    (their breakpoints are dde23's Jumps); [analysis] and [linearize] are refused (the linear
    model with the delays' Pade approximations is :func:`~odelab.systems.diagram.delay.pade_diagram`)."""
    from odelab.systems.diagram.delay import DelayDiagram

    from odelab.systems.diagram.delay import pade_diagram

    if model.linearize is not None:
        raise ExperimentError("[linearize] compares a diagram with its linear model by simulating both, and the "
                              "linear model of a transport delay is its Pade approximation, not the delay: use "
                              "[analysis] (poles, step response, Bode of the model with the Pade approximations), "
                              "or odelab.systems.diagram.delay.pade_diagram in Python.", key="linearize")
    if model.analysis is not None and model.analysis.loop is not None:
        raise ExperimentError("`analysis.loop` of a diagram with a transport delay is not available yet; remove it "
                              "(the [analysis] of the closed loop works, with the delays' Pade approximations).",
                              key="analysis.loop")
    try:
        delays = DelayDiagram(compiled, t0)
    except InputError as exc:
        raise ExperimentError(exc.message, key=exc.key or "blocks") from None
    resolved = {"kind": "diagram", "outputs": outputs, "lags": [float(v) for v in delays.lags]}
    if model.system.states is not None:
        resolved["states"] = list(model.system.states)
    system, inputs = None, ()
    if model.analysis is not None:
        # [analysis] reads the linear model with each delay's Pade approximation (Simulink's linmod),
        # from the sources to the outputs; the run itself is the delay equations
        linear = pade_diagram(compiled, t0)
        system, inputs = linear.system, compiled.inputs
        compiled.notes.extend(n for n in linear.notes if n not in compiled.notes)
    return Built(states=compiled.states, inputs=inputs, outputs=compiled.outputs, fun=delays,
                 output_fn=delays.output_many if compiled.outputs else None, resolved=resolved, linear=False,
                 model=system, x0=compiled.x0, signals=(), diagram=compiled, compiled=None)
