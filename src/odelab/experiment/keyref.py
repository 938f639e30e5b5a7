"""The key reference of experiment files, generated from the schema so that it cannot drift.

Every key the pydantic schema (:mod:`odelab.experiment.schema`) accepts is listed with its
type, default and choices read from the model itself; the free-form tables that other modules
check (``[sweep]``, ``[study]``, ``[events]``, ``[[case]]``, ``[[problem]]``) and each input
signal type's keys (from the signal registry, :data:`odelab.signals.SIGNALS`) are added from the
modules that check them. A sentence per key comes from :data:`NOTES`; a key without one is
still listed, with its type and default. ``odelab explain KEY`` and the documentation's key
reference page both read :func:`entries`.
"""

from __future__ import annotations

import difflib
import textwrap
import types
import typing
from dataclasses import dataclass, field

__all__ = ["KeyEntry", "NOTES", "entries", "explain", "find", "markdown"]


@dataclass(frozen=True)
class KeyEntry:
    """One key of an experiment file: ``solver.rtol``, ``inputs.<name>.type``, ``inputs.pulse.width``."""

    path: str
    type: str
    default: str | None = None
    choices: tuple[str, ...] = ()
    text: str = ""
    matlab: tuple[str, ...] = ()  # MATLAB's spellings that the file also accepts
    children: tuple[str, ...] = field(default=(), compare=False)

    @property
    def table(self) -> str:
        return self.path.rsplit(".", 1)[0] if "." in self.path else ""


# One sentence (or two) per key: what it means, its unit, what MATLAB calls it.
NOTES: dict[str, str] = {
    "name": "The experiment's name (default: the file's name without .toml); runs are stored under runs/<name>/.",
    "title": "A one-line title, shown in the terminal and as the report's section heading.",
    "description": "A paragraph for the report, under the title.",
    "expect": "How the case is expected to end: `max-steps` for a case that shows a solver stopped by its step "
              "limit on purpose (reported as \"stopped, as expected\", not counted as a failed run), `failure` "
              "for any failed integration; default `success`.",
    "parameters": "Named numbers or expressions of other parameters (`k = \"m*w^2\"`), usable in every expression "
                  "of the file, as MATLAB workspace variables. A parameter may shadow a constant such as `e`.",
    "parameters.<name>": "A number, or an expression of other parameters, or a number with a unit (`L = \"100 "
                         "cm\"`, `k = \"3 N/m\"`): converted with pint to the unit [units] gives the name, else to "
                         "SI, and said in the run's notes and resolved.toml ([initial] and [time] start/stop too).",
    "system": "What is integrated: equations, a state-space model, a block diagram or a Python function.",
    "system.kind": "The kind of system: `ode` (states and [system.equations]), `state-space` (A, B, C, D), "
                   "`diagram` ([blocks]), `network` ([elements]: odelab derives the equations), `implicit` "
                   "([system.residuals]: F(t, x, x') = 0, solved by ode15i), `fmu` (an FMU through FMPy: `file`).",
    "system.states": "The state names, in order (the order of y in MATLAB).",
    "system.equations": "d(state)/dt for each state, in the expression language.",
    "system.equations.<name>": "The right-hand side of d(<name>)/dt: an expression of t, the states, the inputs "
                               "and the parameters; `lag(x, tau)` is the state x at t - tau (a delay equation, "
                               "solved by dde23; see docs/delays.md).",
    "system.residuals": "kind = \"implicit\": one residual per state, each an expression that is zero on the "
                        "solution, F(t, x, x') = 0, with der(x) for x' (MATLAB's ode15i form): `r = \"t*y^2*der(y)^3 "
                        "- y^3*der(y)^2 + t*(t^2 + 1)*der(y) - t^2*y\"`. A residual without der() is an algebraic "
                        "equation (an index-1 DAE). Solved by ode15i from initial values decic makes consistent "
                        "([initial] \"der(x)\" guesses, [initial.fixed]). See docs/implicit.md.",
    "system.residuals.<name>": "A residual, zero on the solution: an expression of t, the states, der(state) and the "
                               "parameters.",
    "system.function": "A Python function `def f(t, y)`, written \"file.py:name\" relative to the experiment file, "
                       "as a MATLAB function file (runs code: refused by `odelab grade` unless allowed).",
    "system.file": "kind = \"fmu\": the FMU (FMI 2.0 or 3.0), relative to the experiment file. Its states, inputs, "
                   "outputs and parameters are its own; loading it runs its machine code, so `odelab run` needs "
                   "--allow-native (see docs/fmi.md).",
    "system.interface": "kind = \"fmu\": `model-exchange` (default when offered: odelab's solvers step it, events "
                        "by its event indicators) or `co-simulation` (the FMU steps itself at the communication "
                        "step: [solver] h, else its DefaultExperiment's stepSize).",
    "system.inputs": "The input names (u); each needs an [inputs.<name>] signal.",
    "system.outputs": "Outputs: a table of expressions (`y = \"q*x\"`), the names of state-space outputs, or, for "
                      "a diagram, output name = block name.",
    "system.A": "State matrix of x' = Ax + Bu: TOML rows or a MATLAB matrix string \"[0 1; -k/m -b/m]\".",
    "system.B": "Input matrix of x' = Ax + Bu.",
    "system.C": "Output matrix of y = Cx + Du.",
    "system.D": "Feedthrough matrix of y = Cx + Du (default zeros).",
    "system.jacobian": "An analytic Jacobian of [system.equations] (row i: the derivatives of equation i), checked "
                       "against the equations at the initial state; by default odelab derives it exactly.",
    "system.algebraic_loops": "What a diagram's algebraic loop does (Simulink's diagnostic): `warning` (default: "
                              "solved by Newton's method, named once in a note), `none` (solved quietly) or `error` "
                              "(refused). See docs/blocks.md.",
    "initial": "Initial values of the states (default 0), numbers or expressions of the parameters.",
    "initial.<name>": "The initial value of state <name>; for an implicit system also \"der(<name>)\" = a guess of "
                      "its initial slope (default 0), which decic makes consistent.",
    "initial.fixed.<name>": "true: decic keeps the guess of <name> (a state's value, or \"der(state)\": its slope).",
    "initial.fixed": "kind = \"implicit\": what decic may not change, state = true (its value) or \"der(state)\" = "
                     "true (its slope); default: every state's value fixed, every slope free (MATLAB's fixed_y0, "
                     "fixed_yp0). Free an algebraic state's value (y3 = false) so decic can make it consistent.",
    "time": "The time span and output times (MATLAB's tspan).",
    "time.start": "The start of the span (t0).",
    "time.stop": "The end of the span (tf); a number or an expression such as \"pi\".",
    "time.output": "Output times: a list, or a MATLAB range string \"0:0.1:15\" (MATLAB's vector tspan).",
    "time.points": "A number of equally spaced output times over the span (linspace).",
    "exact": "The analytical solution, per state or output, for error tables.",
    "exact.<name>": "An expression of t and the parameters: the exact value of <name>.",
    "history": "Delay equations (lag(x, tau) in [system.equations], solved by dde23): each state's value for "
               "t <= t0, a number or an expression of t and the parameters; a state left out keeps its initial "
               "value there. See docs/delays.md.",
    "history.<name>": "The history of state <name>: x(t) for t <= t0, a number or an expression of t.",
    "solver": "The method and its options (MATLAB's odeset names work too).",
    "solver.method": "The method: MATLAB's ode45, ode23, ode113, ode78, ode89, ode15s, ode23s, ode23t, ode23tb, "
                     "dde23 (delay equations; `auto` picks it for lag()), ode15i (kind = \"implicit\", its default); "
                     "fixed-step euler, heun, midpoint, rk3, rk4; SciPy's RK23, RK45, DOP853, Radau, BDF, LSODA "
                     "(`odelab solvers` lists them).",
    "solver.estimate_error": "The global error estimate: a second solve at RelTol and AbsTol / 10 (same method; a "
                             "fixed-step method at h/2), giving each quantity's estimated max error and correct "
                             "digits (`est. error`), and `ok?` when the two solves disagree far beyond the tolerances. "
                             "Default: on for a case without a reference, off for a [sweep]'s cases (about twice the "
                             "time); `odelab run --estimate/--no-estimate` overrides. See docs/guide/trust.md.",
    "solver.zero_crossing": "Diagrams: locate the instants switching blocks (saturation, relay, switch...) change "
                            "formula and restart there (default true, Simulink's zero-crossing detection); false "
                            "steps over them. Each block's own `zero_crossing` key turns it off for that block.",
    "solver.backend": "Which engine runs an expression system: `auto` (compiled only when the run is long), "
                      "`python` or `compiled` (numba).",
    "reference": "What the errors are measured against.",
    "reference.method": "`auto` (the exact solution if given, the exact LTI response of a linear system, else a "
                        "high-accuracy solve), `exact`, `lti`, `high-accuracy` or `none`.",
    "reference.solver": "The method of the high-accuracy reference: `auto` (the default: SciPy's DOP853, switched "
                        "to Radau when its steps prove held by stability, i.e. the problem is stiff; the case's "
                        "notes say so), or a method name such as `DOP853`, `Radau`, `BDF`, `LSODA` or `ode15s`. "
                        "It is bounded by the run's --max-steps. See docs/guide/references.md.",
    "reference.rtol": "The high-accuracy reference's relative tolerance.",
    "reference.atol": "The high-accuracy reference's absolute tolerance.",
    "inputs": "The input signals u(t), one table per input name.",
    "inputs.<name>": "The signal of input <name>: a `type` and that type's keys.",
    "inputs.<name>.type": "The signal type; each type's keys are listed under inputs.<type>.",
    "inputs.step": "u = initial before `time`, final from `time` on (Simulink's Step block, whose default time is 1; "
                   "odelab's is 0).",
    "inputs.step.time": "The step time, in the units of t.",
    "inputs.step.initial": "The value before the step.",
    "inputs.step.final": "The value from the step on.",
    "inputs.ramp": "u = initial + slope (t - start) from `start` on, `initial` before (Simulink's Ramp).",
    "inputs.ramp.slope": "The slope, in units of u per unit of t.",
    "inputs.ramp.start": "The time the ramp starts.",
    "inputs.ramp.initial": "The value before the ramp starts.",
    "inputs.sine": "u = amplitude sin(frequency t + phase) + bias (Simulink's Sine Wave).",
    "inputs.sine.amplitude": "The amplitude.",
    "inputs.sine.frequency": "The angular frequency in rad/s (sin(0.2 t) is frequency = 0.2).",
    "inputs.sine.phase": "The phase in rad.",
    "inputs.sine.bias": "A constant added to the sine.",
    "inputs.pulse": "A rectangular pulse train of `amplitude`, on for `width` of each `period`, starting at "
                    "`delay` (Simulink's Pulse Generator, time based).",
    "inputs.pulse.amplitude": "The value while the pulse is on (0 while off).",
    "inputs.pulse.period": "The period, in the units of t.",
    "inputs.pulse.width": "The fraction of the period the pulse is on, between 0 and 1 (Simulink's Pulse width "
                          "is a percentage: 50 % is width = 0.5).",
    "inputs.pulse.delay": "The time of the first rising edge (Simulink's Phase delay).",
    "inputs.table": "Values read from a CSV file (an optional header row, then time in the first column and u in "
                    "the second), interpolated linearly between rows and held at the end values outside them by "
                    "default (`interpolation`, `extrapolation`).",
    "inputs.table.file": "The CSV file, relative to the experiment file.",
    "inputs.table.interpolation": "Between rows: `linear` (default), `flat` (each row held until the next), "
                                  "`nearest` or `cubic-spline` (MATLAB's spline), Simulink's lookup-table names.",
    "inputs.table.extrapolation": "Outside the rows: `clip` (default: the end values held) or `linear` (the end "
                                  "segments continued).",
    "inputs.expression": "u = an expression of t and the parameters.",
    "inputs.expression.expression": "The expression, e.g. \"t^2\" or \"sin(t)*exp(-t)\".",
    "inputs.constant": "u = a constant value.",
    "inputs.constant.value": "The value.",
    "linearize": "Linearisation about an operating point and the linear-against-nonlinear comparison.",
    "linearize.start": "`operating-point` (both models start at rest at the operating point) or `initial` "
                       "(both start from [initial]); when the file does not say, `initial` if it has an [initial] "
                       "table, else `operating-point`.",
    "linearize.drive": "The input whose steps are compared (default the first input).",
    "linearize.input": "The operating input (f̄ = 1 is `input = { f = 1 }`); the state x̄ solves f(x̄, f̄) = 0.",
    "linearize.state": "The operating state, when it is known instead of found.",
    "linearize.guess": "A starting guess for the operating state's search.",
    "linearize.fixed": "States held at given values while the operating point is found.",
    "linearize.amplitudes": "Step amplitudes on top of the operating input for the amplitude study.",
    "linearize.threshold": "The largest linearisation error, relative to the peak incremental response, that "
                           "counts as valid.",
    "linearize.quantity": "The state or output compared (default the first output, else the first state).",
    "linearize.step_time": "When the step on top of the operating input starts.",
    "analysis": "Control analysis of the linear (or linearised) system: stepinfo, Bode, poles.",
    "analysis.step_info": "MATLAB's stepinfo on the exact step response.",
    "analysis.bode": "A Bode plot: true, or a frequency range in rad/s.",
    "analysis.bode.from": "The lowest frequency, rad/s.",
    "analysis.bode.to": "The highest frequency, rad/s.",
    "analysis.bode.points": "The number of frequencies (log spaced).",
    "analysis.poles": "Poles with natural frequency and damping ratio, zeros and DC gains.",
    "analysis.input": "A nonlinear system's operating input for the linearisation (default 0).",
    "analysis.loop": "Diagrams: the block at whose input the loop is opened for gain and phase margins.",
    "blocks": "The blocks of a diagram (kind = \"diagram\"), each a table with a `type` and its keys.",
    "blocks.<name>": "One block: `type`, `input` or `inputs`, and the type's keys.",
    "elements": "The elements of a network (kind = \"network\"), each a table with a `type`, its nodes and its "
                "parameters; odelab derives the state equations (docs/networks.md).",
    "elements.<name>": "One element: `type`, `nodes = [a, b]` (or `node = a`), `nodes2` for a coupling, and the "
                       "type's parameters (numbers or expressions of [parameters]).",
    "plot": "How the report draws the solution: the time axis's scale and display multipliers per quantity.",
    "plot.t_scale": "The time axis: `log` (a process over many decades, such as Robertson's kinetics over "
                    "[0, 4e10]), `linear`, or `auto` (log when most output times lie in the first thousandth of the "
                    "span).",
    "plot.scale": "Display multipliers, e.g. `{ y2 = 1e4 }` draws 10^4 y2 (labelled so), for a quantity far "
                  "smaller than the others; the stored values are not changed.",
    "plot.scale.<name>": "The factor the report multiplies the quantity by.",
    "report": "The experiment's place in the report and a note for its readers (never what is computed).",
    "report.order": "Where the section stands: experiments with an order come first, lowest first (the lab "
                    "sheet's order); the rest follow, linearisation studies first, then alphabetically.",
    "report.note": "A paragraph at the head of the section (plain text; `**bold**` is kept).",
    "report.quote": "Stored cases, as \"experiment/case\", whose maximum relative errors the note quotes, each with "
                    "its time span and number of points (e.g. [\"exercise1/ode23\", \"exercise1_2pi/ode23\"]).",
    "units": "A unit per time, state, input, output or parameter, shown on the report's axes (`x = \"m\"`).",
    "units.<name>": "The unit of <name>, as text (\"m/s\"), shown as \"x (m)\"; a value with a unit given for "
                    "<name> ([parameters], [initial], t for [time]) is converted to it, and one that does not fit is "
                    "an error naming both.",
    "events": "Zero-crossing events (MATLAB's Events), one table per event, and `max_events`.",
    "events.max_events": "End the case cleanly after this many events (a Zeno guard; default 100).",
    "events.<name>": "One event: `when`, `direction`, `terminal`, `reset`, `exact`.",
    "events.<name>.when": "The event is a zero of this expression of t, the states and the parameters.",
    "events.<name>.direction": "`rising`, `falling` or `both` (MATLAB's 1, -1, 0 also work).",
    "events.<name>.terminal": "Stop (or, with a reset, restart) at the event: MATLAB's isterminal (true or false; 1 or 0 also work).",
    "events.<name>.reset": "States changed at the event, e.g. `{ v = \"-cr*v\" }`: the case restarts from them.",
    "events.<name>.exact": "The exact time of occurrence k = 0, 1, ..., to measure the event-time error.",
    "data": "Measured data (docs/fitting.md): a CSV file with a header row, the reference of every case (errors at "
            "the measured times).",
    "data.file": "The CSV file, relative to the experiment file and inside its folder.",
    "data.time": "The CSV column of the measured times (default \"t\").",
    "data.columns": "Model quantity (a state or output) = CSV column, e.g. { x = \"position\" } (default: the "
                    "columns named like a state or output).",
    "data.columns.<name>": "The CSV column measuring the state or output <name>.",
    "data.sigma": "The measurement noise (standard deviation, in the quantity's units) per quantity; [fit] then "
                  "weighs by 1/sigma and uses it for the uncertainties.",
    "data.sigma.<name>": "The standard deviation of the measurements of <name>.",
    "fit": "Estimate parameters from [data] by weighted least squares with exact sensitivities (docs/fitting.md); "
           "every case with [data] is fitted jointly.",
    "fit.parameters": "The parameters to estimate, e.g. { k = { initial = 2, lower = 0, upper = 10 } }.",
    "fit.parameters.<name>": "One fitted parameter of [parameters]: `initial`, `lower`, `upper`.",
    "fit.parameters.<name>.initial": "Where the fit starts (default: the value in [parameters]).",
    "fit.parameters.<name>.lower": "Lower bound (default none).",
    "fit.parameters.<name>.upper": "Upper bound (default none).",
    "fit.quantities": "The measured quantities to fit (default: every quantity [data] maps).",
    "fit.validate": "A second data set (CSV, read like [data]) to check the fitted model against.",
    "fit.method": "The solver of the states and sensitivities: an adaptive explicit method (default ode78).",
    "fit.rtol": "Its relative tolerance (default 1e-10: far below any data's relative noise).",
    "fit.atol": "Its absolute tolerance (default rtol times each case's largest measured value).",
    "fit.max_solves": "A fit that needs more model solves than this fails with its last iterate (default 500).",
    "case": "[[case]] tables: variants of the experiment, each deep-merged over the base, each with a `name`.",
    "case.name": "The case's name, shown in tables and used as its folder under runs/<experiment>/.",
    "problem": "[[problem]] tables: several systems run through the same cases, sweep and study; each has a "
               "`name` and replaces the base's tables of the same names.",
    "problem.name": "The problem's name; the experiment becomes <file>_<name>.",
    "sweep": "Run variants over lists or ranges of values: dotted keys (`\"solver.h\"`, `\"parameters.k\"`) with "
             "lists or ranges, plus `mode` and `store`.",
    "sweep.<key>": "A list of values, or a range: { from, to, count } (linspace), with log = true (logspace), or "
                   "{ from, to, step } (MATLAB's from:step:to).",
    "sweep.mode": "`product` (every combination, the default) or `zip` (the lists side by side).",
    "sweep.store": "`summary` (one table for the sweep, the default) or `all` (also every case's folder).",
    "study": "A study over a sweep: observed convergence order or work-precision.",
    "study.over": "The swept key on the x axis (default solver.h, else solver.rtol).",
    "study.error": "`max` (the largest error over the span) or `end` (the error at the final time).",
    "study.quantity": "The state or output whose error is studied (default the first output, else the first "
                      "state).",
}

def _matlab() -> dict[str, tuple[str, ...]]:
    """MATLAB's odeset spellings of [solver] keys, from the option registry (odelab.solvers.optionset)."""
    from odelab.solvers.optionset import OPTIONS

    return {f"solver.{o.name}": o.matlab for o in OPTIONS.values() if o.toml and o.matlab}


def _note(path: str) -> str:
    """A key's sentence: NOTES, or for a solver option its registry entry's."""
    if path in NOTES:
        return NOTES[path]
    if path.startswith("solver."):
        from odelab.solvers.optionset import OPTIONS

        option = OPTIONS.get(path.removeprefix("solver."))
        if option is not None:
            return option.doc
    return ""

# Tables the schema keeps free-form because another module checks them.
_FREE_FORM = {
    "case": ("table array", ("name",)),
    "problem": ("table array", ("name",)),
    "sweep": ("table", ("<key>", "mode", "store")),
    "study": ("table", ("kind", "over", "error", "quantity")),
    "events": ("table", ("max_events", "<name>")),
    "events.<name>": ("table", ("when", "direction", "terminal", "reset", "exact")),
    "initial.fixed": ("table", ("<name>",)),
}
_FREE_TYPES = {
    "case.name": "string", "problem.name": "string", "sweep.<key>": "list or range table",
    "sweep.mode": "string", "sweep.store": "string", "study.kind": "string", "study.over": "string",
    "study.error": "string", "study.quantity": "string", "events.max_events": "integer",
    "events.<name>.when": "expression", "events.<name>.direction": "string or -1, 0, 1",
    "events.<name>.terminal": "boolean", "events.<name>.reset": "table of expressions",
    "events.<name>.exact": "expression",
    "initial.fixed.<name>": "boolean",
}
_FREE_CHOICES = {
    "sweep.mode": ("product", "zip"), "sweep.store": ("summary", "all"),
    "study.kind": ("convergence", "work-precision"), "study.error": ("max", "end"),
    "events.<name>.direction": ("rising", "falling", "both"),
}
_FREE_DEFAULTS = {"sweep.mode": "product", "sweep.store": "summary", "events.max_events": "100"}


def _type_text(annotation) -> tuple[str, tuple[str, ...], object | None]:
    """(readable type, Literal choices, nested model) of a pydantic annotation."""
    from pydantic import BaseModel

    from odelab.experiment import schema

    if annotation == schema.Value:
        return "number or expression", (), None
    if annotation == schema.Matrix or (typing.get_origin(annotation) in (typing.Union, types.UnionType)
                                       and set(typing.get_args(annotation)) - {type(None)}
                                       == set(typing.get_args(schema.Matrix))):
        return "matrix (TOML rows of numbers or expressions, or a MATLAB string \"[0 1; -2 -3]\")", (), None
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        return _type_text(args[0])
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "table", (), annotation
    if origin is typing.Literal:
        kinds = {type(a).__name__ for a in args}
        return ("string" if kinds == {"str"} else "value"), tuple(str(a) for a in args), None
    if origin in (typing.Union, types.UnionType):
        parts, choices, nested = [], [], None
        for a in args:
            if a is type(None):
                continue
            text, ch, model = _type_text(a)
            nested = nested or model
            choices.extend(ch)
            if text not in parts:
                parts.append(text)
        if {"integer", "number"} <= set(parts):
            parts.remove("integer")
        if set(parts) >= {"number", "string"}:
            parts = ["number or expression" if p == "number" else p for p in parts if p != "string"]
        return " or ".join(parts), tuple(choices), nested
    if origin is list:
        inner, _, _ = _type_text(args[0]) if args else ("value", (), None)
        return f"list of {inner}s" if not inner.startswith("list") else f"list of {inner}", (), None
    if origin is dict:
        inner, _, model = _type_text(args[1]) if len(args) == 2 else ("value", (), None)
        return ("table of tables" if model is not None else f"table ({inner} each)"), (), model
    name = getattr(annotation, "__name__", str(annotation))
    mapped = {"StrictInt": "integer", "int": "integer", "StrictFloat": "number", "float": "number",
              "StrictStr": "string", "str": "string", "StrictBool": "boolean", "bool": "boolean",
              "Any": "value"}
    if name in mapped:
        return mapped[name], (), None
    if annotation is typing.Any:
        return "value", (), None
    # pydantic's Strict types are Annotated[int, Strict()] etc.
    meta = getattr(annotation, "__origin__", None)
    if meta is not None:
        return _type_text(meta)
    return name, (), None


def _default_text(info) -> str | None:
    from pydantic_core import PydanticUndefined

    if info.is_required():
        return "required"
    if info.default_factory is not None:
        return None
    value = info.default
    if value is None or value is PydanticUndefined:
        return None
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)


def _walk(model, prefix: str, out: list[KeyEntry]) -> None:
    for name, info in model.model_fields.items():
        key = info.alias or name
        path = f"{prefix}.{key}" if prefix else key
        text, choices, nested = _type_text(info.annotation)
        if path == "solver":  # validated by the model the option registry builds
            from odelab.experiment.schema import solver_model

            text, choices, nested = "table", (), solver_model()
        origin = typing.get_origin(info.annotation)
        is_dict = origin is dict or any(typing.get_origin(a) is dict for a in typing.get_args(info.annotation))
        children: tuple[str, ...] = ()
        if nested is not None and not is_dict:
            children = tuple(f.alias or n for n, f in nested.model_fields.items())
        elif is_dict:
            children = ("<name>",)
        out.append(KeyEntry(path, text, _default_text(info), choices, _note(path), _matlab().get(path, ()),
                            children))
        if path in _FREE_FORM or path == "inputs":
            continue
        if is_dict:
            member = f"{path}.<name>"
            if nested is not None:
                out.append(KeyEntry(member, "table", None, (), NOTES.get(member, ""),
                                    children=tuple(f.alias or n for n, f in nested.model_fields.items())))
                _walk(nested, member, out)
            else:
                inner = text.removeprefix("table (").removesuffix(" each)")
                out.append(KeyEntry(member, inner, None, (), NOTES.get(member, "")))
        elif nested is not None:
            _walk(nested, path, out)


def _inputs(out: list[KeyEntry]) -> None:
    """Each type of the signal registry, with its keys, defaults and units."""
    from odelab.experiment import schema
    from odelab.signals import SIGNALS

    kinds = tuple(SIGNALS)
    out.append(KeyEntry("inputs.<name>", "table", None, (), NOTES.get("inputs.<name>", ""),
                        children=("type", *sorted({k for cls in SIGNALS.values() for k in cls.KEYS}))))
    out.append(KeyEntry("inputs.<name>.type", "string", "required", kinds, NOTES.get("inputs.<name>.type", "")))
    fields = schema.input_signal_model().model_fields
    for kind, cls in SIGNALS.items():
        doc = " ".join((cls.__doc__ or "").strip().split("\n\n")[0].split()).replace("``", "`")
        out.append(KeyEntry(f"inputs.{kind}", "signal type", None, (), NOTES.get(f"inputs.{kind}", doc),
                            children=tuple(cls.KEYS)))
        for key, spec in cls.KEYS.items():
            text = _type_text(fields[key].annotation)[0] if key in fields else "value"
            shown = None if spec.default is None else repr(spec.default)
            path = f"inputs.{kind}.{key}"
            out.append(KeyEntry(path, text, "required" if spec.default is None else shown, (), NOTES.get(path, "")))


def _methods(out: list[KeyEntry]) -> None:
    """``solver.method``'s choices and one entry per method of the registry: what it can do, what it takes."""
    from odelab.solvers.registry import METHODS

    out[:] = [KeyEntry(e.path, e.type, e.default, ("auto", *METHODS), e.text, e.matlab, e.children)
              if e.path == "solver.method" else e for e in out]
    for name, m in METHODS.items():
        can = ", ".join(m.capabilities) or "none of events, dense output, a mass matrix, the compiled backend"
        out.append(KeyEntry(f"solver.method.{name}", "method", None, (),
                            f"{m.description} ({m.kind_label}; order {m.order_label}). Can do: {can}. "
                            f"Options: {', '.join(m.options)}. Defaults: {m.defaults}."))


def _blocks(out: list[KeyEntry]) -> None:
    """Each block type of the diagram registry, with its keys, defaults and meanings."""
    from odelab.signals import SIGNALS
    from odelab.systems.diagram.blocks import BLOCKS, REQUIRED

    out.append(KeyEntry("blocks.<name>.type", "string", "required", (*SIGNALS, *BLOCKS),
                        "The block type: a source (any input signal type, with that type's keys) or one of the "
                        "diagram blocks listed under blocks.<type>."))
    out.append(KeyEntry("blocks.<name>.input", "string", None, (),
                        "The block (or `block.port`) that feeds this block's single input."))
    out.append(KeyEntry("blocks.<name>.inputs", "list of strings", None, (),
                        "The blocks (or `block.port`s) that feed this block's inputs, in order."))
    for name, cls in BLOCKS.items():
        doc = " ".join((cls.__doc__ or "").strip().split("\n\n")[0].split()).replace("``", "`")
        out.append(KeyEntry(f"blocks.{name}", "block type", None, (), doc, children=tuple(cls.KEYS)))
        for key, spec in cls.KEYS.items():
            default = None if spec.default is REQUIRED else ("none" if spec.default is None else repr(spec.default))
            out.append(KeyEntry(f"blocks.{name}.{key}", spec.kind, default, (), spec.doc))


def _elements(out: list[KeyEntry]) -> None:
    """Each element type of the network registry, with its keys, defaults and meanings."""
    from odelab.systems.network.elements import ELEMENTS

    out.append(KeyEntry("elements.<name>.type", "string", "required", tuple(ELEMENTS),
                        "The element type (listed under elements.<type>)."))
    for name, cls in ELEMENTS.items():
        domain = cls.DOMAIN if cls.DOMAIN2 is None else f"{cls.DOMAIN} to {cls.DOMAIN2}"
        out.append(KeyEntry(f"elements.{name}", "element type", None, (),
                            f"{domain}: {cls.DOC}; variables {', '.join(cls.variables())}.",
                            children=tuple(cls.keys())))
        for key in cls.keys():
            if key in ("node", "nodes", "nodes2"):
                text = {"node": "The node it sits on (referenced to ground).",
                        "nodes": "Its two nodes [a, b]: across variables are measured from b to a (`node = a` is "
                                 "short for [a, \"ground\"]).",
                        "nodes2": "The node pair of its second side."}[key]
                out.append(KeyEntry(f"elements.{name}.{key}", "list of strings" if key != "node" else "string",
                                    "required", (), text))
            elif key == cls.LAW:
                out.append(KeyEntry(f"elements.{name}.{key}", "expression", None, (),
                                    f"A nonlinear law instead of the coefficient: an expression of its "
                                    f"`{cls.LAW_OF}` and of [parameters]."))
            else:
                p = cls.PARAMETERS[key]
                out.append(KeyEntry(f"elements.{name}.{key}", "number or expression",
                                    "required" if p.default is None else repr(p.default), (), p.doc + "."))
        if cls.GROUNDED:
            out.append(KeyEntry(f"elements.{name}.nodes", "list of strings", None, (),
                                "[a, \"ground\"] (the same as `node = a`)."))


def _free_form(out: list[KeyEntry]) -> None:
    known = {e.path for e in out}
    for path, (kind, children) in _FREE_FORM.items():
        if path not in known:
            out.append(KeyEntry(path, kind, None, (), NOTES.get(path, ""), children=children))
        else:  # the schema lists it as a free table: give it its children
            out[:] = [KeyEntry(e.path, kind if e.path == path else e.type, e.default, e.choices, e.text, e.matlab,
                               children if e.path == path else e.children) for e in out]
        for child in children:
            cpath = f"{path}.{child}"
            if cpath in _FREE_FORM:
                continue
            out.append(KeyEntry(cpath, _FREE_TYPES.get(cpath, "value"), _FREE_DEFAULTS.get(cpath),
                                _FREE_CHOICES.get(cpath, ()), NOTES.get(cpath, "")))


def _studies(out: list[KeyEntry]) -> None:
    """[study]'s keys and kinds, from the study-kind registry (odelab.experiment.studykinds)."""
    from odelab.experiment.study import study_keys
    from odelab.experiment.studykinds import STUDY_KINDS

    kinds = "; ".join(f"`{name}`: {kind.DOC}" for name, kind in STUDY_KINDS.items())
    replaced = {"study": lambda e: KeyEntry(e.path, e.type, e.default, e.choices, e.text, e.matlab, study_keys()),
                "study.kind": lambda e: KeyEntry(e.path, e.type, e.default, tuple(STUDY_KINDS),
                                                 f"The kind of study ({kinds}).", e.matlab, e.children)}
    out[:] = [replaced[e.path](e) if e.path in replaced else e for e in out]
    for name, kind in STUDY_KINDS.items():
        for key, default in kind.KEYS.items():
            out.append(KeyEntry(f"study.{key}", "value", None if default is None else repr(default), (),
                                f"A {name} study's: {kind.DOCS.get(key, '')}".rstrip(": ")))


_CACHE: list[tuple[KeyEntry, ...]] = []
_CACHED_FOR: list[tuple] = []  # the registries the cache was read from


def _registries() -> tuple:
    from odelab.experiment.studykinds import STUDY_KINDS
    from odelab.signals import SIGNALS
    from odelab.solvers.optionset import OPTIONS
    from odelab.solvers.registry import METHODS
    from odelab.systems.diagram.blocks import BLOCKS

    # by identity: a registry's entries are compared as the objects registered, never field by field
    registries = (SIGNALS, METHODS, OPTIONS, BLOCKS, STUDY_KINDS)
    return tuple((name, id(v)) for registry in registries for name, v in registry.items())


def entries() -> tuple[KeyEntry, ...]:
    """Every key of an experiment file, in the schema's order, then the free-form tables."""
    if _CACHED_FOR and _CACHED_FOR[0] != _registries():  # a type was registered since
        _CACHE.clear()
        _CACHED_FOR.clear()
    if not _CACHE:
        from odelab.experiment import schema

        _CACHED_FOR.append(_registries())

        out: list[KeyEntry] = []
        _walk(schema.Experiment, "", out)
        _inputs(out)
        _methods(out)
        _blocks(out)
        _elements(out)
        _free_form(out)
        _studies(out)
        seen: dict[str, KeyEntry] = {}
        for e in out:
            seen.setdefault(e.path, e)
        _CACHE.append(tuple(seen.values()))
    return _CACHE[0]


def find(key: str) -> KeyEntry | None:
    """The entry for ``key``; concrete names match their placeholder (``inputs.f.type`` -> ``inputs.<name>.type``)."""
    table = {e.path: e for e in entries()}
    key = key.strip().strip("[]").strip()
    if key in table:
        return table[key]
    for path, spellings in _matlab().items():  # solver.RelTol -> solver.rtol
        if key.lower() in {f"{path.split('.')[0]}.{m}".lower() for m in spellings}:
            return table[path]
    parts = key.split(".")
    if len(parts) == 3 and parts[0] in ("initial", "units", "exact") and f"{parts[0]}.<name>" in table:
        return table[f"{parts[0]}.<name>"]  # a network's state: "mass.x" = 0.1
    # inputs.f.type, system.equations.x, events.floor.when, sweep."solver.h"...
    for i in range(len(parts)):
        for placeholder in ("<name>", "<key>"):
            trial = ".".join([*parts[:i], placeholder, *parts[i + 1:]])
            if trial in table:
                return table[trial]
    if parts[0] == "sweep" and len(parts) > 1 and parts[1] not in ("mode", "store"):
        return table.get("sweep.<key>")
    return None


def _suggest(key: str) -> list[str]:
    paths = [e.path for e in entries()]
    if "." in key:
        parent = find(key.rsplit(".", 1)[0])
        if parent is not None and parent.children:
            close = difflib.get_close_matches(key.rsplit(".", 1)[1], parent.children, n=3, cutoff=0.6)
            return [f"{parent.path}.{c}" for c in close]
    close = difflib.get_close_matches(key, paths, n=3, cutoff=0.6)
    if not close:
        last = key.rsplit(".", 1)[-1]
        close = [p for p in paths if p.rsplit(".", 1)[-1] == last][:3]
    return close


def describe(entry: KeyEntry, width: int = 78) -> str:
    """The reference entry as plain text (what ``odelab explain`` prints)."""
    lines = [f"{entry.path}  ({entry.type})"]
    if entry.text:
        lines.append(textwrap.fill(entry.text, width, initial_indent="  ", subsequent_indent="  "))
    if entry.default is not None:
        lines.append(f"  default: {entry.default}")
    if entry.choices:
        lines.append(textwrap.fill(f"choices: {', '.join(entry.choices)}", width, initial_indent="  ",
                                   subsequent_indent="    ", break_on_hyphens=False))
    if entry.matlab:
        lines.append(f"  MATLAB: {', '.join(entry.matlab)} (also accepted)")
    if entry.children:
        lines.append(textwrap.fill(f"keys: {', '.join(entry.children)}", width, initial_indent="  ",
                                   subsequent_indent="        "))
    return "\n".join(lines)


def explain(key: str) -> str:
    """The reference entry of ``key``, or a :class:`LookupError` listing the nearest keys. ``import`` (and
    ``import.m``...) explains what `odelab import` reads (:func:`odelab.formats.explain_import`)."""
    if key.strip().split(".")[0] == "import":
        from odelab.formats import explain_import

        return explain_import(key.strip())
    entry = find(key)
    if entry is None:
        close = _suggest(key)
        hint = f" Did you mean {', '.join(f'`{c}`' for c in close)}?" if close else ""
        parent = find(key.rsplit(".", 1)[0]) if "." in key else None
        if parent is not None and parent.children:
            raise LookupError(f"no key `{key}` in experiment files.{hint} The keys of `{parent.path}` are: "
                              f"{', '.join(parent.children)}.")
        tables = sorted({e.path.split(".")[0] for e in entries()})
        raise LookupError(f"no key `{key}` in experiment files.{hint} Top-level keys and tables: "
                          f"{', '.join(tables)}.")
    return describe(entry)


def _md_text(text: str) -> str:
    """Prose for Markdown: `<name>` and other angle brackets outside code spans shown, not read as HTML."""
    parts = text.split("`")
    return "`".join(p if i % 2 else p.replace("<", "&lt;").replace(">", "&gt;") for i, p in enumerate(parts))


def _md_entry(e: KeyEntry) -> list[str]:
    facts = [f"*{_md_text(e.type)}*"]
    if e.default is not None:
        facts.append(f"default `{e.default}`")
    if e.choices:
        facts.append("choices " + ", ".join(f"`{c}`" for c in e.choices))
    if e.matlab:
        facts.append("MATLAB " + ", ".join(f"`{m}`" for m in e.matlab))
    lines = ["; ".join(facts) + "."]
    if e.text:
        lines += ["", _md_text(e.text)]
    if e.children:
        lines += ["", "Keys: " + ", ".join(f"`{c}`" for c in e.children) + "."]
    return lines + [""]


def markdown() -> str:
    """The key reference as a Markdown page (the documentation's reference/keys.md)."""
    lines = ["# Experiment file keys", "",
             "Generated from odelab's schema (`odelab.experiment.keyref`): every key an experiment file "
             "accepts, with its type, default and choices. `odelab explain KEY` prints the same entry in the "
             "terminal. `<name>` stands for a name you choose (a state, an input, an event); `inputs.<type>` "
             "and `blocks.<type>` list the keys of each signal and block type.", ""]
    groups: dict[str, list[KeyEntry]] = {}
    for e in entries():
        groups.setdefault(e.path.split(".")[0], []).append(e)
    for top, members in groups.items():
        lines += [f"## `{top}`", ""]
        for e in members:
            if e.path != top:
                lines += [f"### `{e.path}`", ""]
            lines += _md_entry(e)
    return "\n".join(lines)


def unknown_keys(data: dict, prefix: str = "") -> list[str]:
    """Key paths of a parsed experiment file (or a fragment of one) that the reference does not know.

    A signal's or block's keys are looked up under its ``type`` (``inputs.f.time`` is
    ``inputs.step.time`` for a step), so a key that its type does not take is reported.
    """
    out: list[str] = []
    for key, value in data.items():
        path = f"{prefix}.{key}" if prefix else str(key)
        parts = path.split(".")
        if len(parts) == 3 and parts[0] in ("inputs", "blocks", "elements") \
                and parts[2] not in ("type", "input", "inputs"):
            kind = data.get("type")
            if isinstance(kind, str):
                if find(f"inputs.{kind}.{parts[2]}") is None and find(f"blocks.{kind}.{parts[2]}") is None \
                        and find(f"elements.{kind}.{parts[2]}") is None:
                    out.append(f"{path} (for type {kind!r})")
                continue
        entry = find(path)
        if entry is None:
            out.append(path)
            continue
        if path in ("case", "problem") and isinstance(value, list):
            for item in value:
                if isinstance(item, dict):
                    out += [k for k in unknown_keys({k: v for k, v in item.items() if k != "name"})]
            continue
        typed = len(parts) == 2 and parts[0] in ("inputs", "blocks", "elements")  # its keys depend on its type
        if isinstance(value, dict) and (entry.children or typed) and not path.startswith("sweep"):
            out += unknown_keys(value, path)
    return out


# Names a MATLAB or Simulink user writes by habit that odelab spells or handles differently:
# the unknown-key message adds what to write instead.
MATLAB_NOTES: dict[str, str] = {
    "stats": "The step statistics are always printed and stored (steps, failed attempts, function "
             "evaluations, and the stiff solvers' Jacobians, LU decompositions and solves): remove `Stats`.",
    "outputfcn": "An OutputFcn is Python code, which an experiment file cannot hold: every output is stored in "
                 "trajectory.csv; in Python, odelab.ode45(..., OutputFcn=f) takes one.",
    "events": "Write each event as an [events.<name>] table with `when`, `direction` and `terminal`.",
    "jacobian": "An analytic Jacobian goes under [system] as `jacobian = [[...]]`; by default odelab derives the "
                "exact one from the equations.",
    "jpattern": "The exact Jacobian of an equation system is derived, so no sparsity pattern is needed.",
    "duty": "Simulink's Pulse Generator gives the pulse width as a percentage of the period; odelab's `width` is "
            "the fraction of the period: 50 % is width = 0.5.",
    "pulsewidth": "Simulink's Pulse Generator gives the pulse width as a percentage of the period; odelab's "
                  "`width` is the fraction of the period: 50 % is width = 0.5.",
    "width_percent": "The pulse's `width` is the fraction of the period the pulse is on: 50 % is width = 0.5.",
    "steptime": "The step's time is `time`.",
    "amp": "The amplitude is `amplitude`.",
    "freq": "The frequency is `frequency`, in rad/s.",
    "tspan": "The span goes in [time]: `start`, `stop` and optionally `output` (\"0:0.1:10\").",
    "y0": "Initial values go in [initial], one per state name.",
    "options": "Solver options go straight into [solver] (rtol, atol, or MATLAB's RelTol, AbsTol...).",
}


def keys_at(parent: str, node=None) -> tuple[str, ...]:
    """The keys a table at ``parent`` takes ("" for the top level), for messages.

    ``node`` is the table as written: a signal's or block's keys depend on its ``type``.
    """
    if not parent:
        return tuple(e.path for e in entries() if "." not in e.path)
    parts = parent.split(".")
    kind = node.get("type") if isinstance(node, dict) else None
    if len(parts) == 2 and parts[0] in ("inputs", "blocks") and isinstance(kind, str):
        for table in (f"{parts[0]}.{kind}", f"inputs.{kind}", f"blocks.{kind}"):
            entry = find(table)
            if entry is not None and entry.children:
                extra = ("type",) if parts[0] == "inputs" else ("type", "input", "inputs")
                return (*extra, *entry.children)
    entry = find(parent)
    return entry.children if entry is not None else ()


def unknown_key_message(key: str, node=None) -> str:
    """``unknown key `KEY`.`` with the closest valid key, the valid keys, and a note for MATLAB habits."""
    parent, _, leaf = key.rpartition(".")
    known = [k for k in keys_at(parent, node) if not k.startswith("<")]
    spellings = list(known)
    if parent == "solver":
        spellings += [m for path, names in _matlab().items() for m in names]
    close = difflib.get_close_matches(leaf, spellings, n=1, cutoff=0.6)
    if not close:
        close = [k for k in spellings if k.lower() == leaf.lower().replace("_", "")][:1]
    text = f"unknown key `{key}`."
    note = MATLAB_NOTES.get(leaf.lower())
    if note:
        text += f" {note}"
    elif close:
        text += f" Did you mean `{close[0]}`?"
    if known:
        where = f"[{parent}]" if parent else "the top level"
        kind = node.get("type") if isinstance(node, dict) else None
        if isinstance(kind, str) and parent.count(".") == 1 and parent.split(".")[0] in ("inputs", "blocks"):
            where = f"[{parent}] (type {kind!r})"
        text += f" Known keys in {where}: {', '.join(known)}."
        if parent == "solver":
            text += " MATLAB's odeset names (RelTol, AbsTol, MaxStep, InitialStep, Refine, NormControl, ...) work too."
    return text
