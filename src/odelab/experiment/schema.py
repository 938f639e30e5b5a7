"""The experiment file schema (pydantic models).

The models check structure and types only: which keys exist, which are tables, lists,
numbers or strings. Meaning (expressions, shapes, tolerances) is checked by the loader, which
knows the key paths, so every message can name the file, the key, the value and the fix.

A value written ``Value`` is a number or a string in the expression language (``stop = "pi"``).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union

from pydantic import (BaseModel, ConfigDict, Field, StrictBool, StrictFloat, StrictInt, StrictStr, WrapValidator,
                      create_model)

from odelab.solvers.optionset import OPTIONS
from odelab.solvers.registry import DEFAULT_METHOD, SENSITIVITY_METHOD

Number = Union[StrictInt, StrictFloat]
Value = Union[StrictInt, StrictFloat, StrictStr]
Matrix = Union[Value, list[Value], list[list[Value]]]

__all__ = ["Experiment", "SOLVER_KEYS", "solver_model"]


class _Section(BaseModel):
    # defer_build: a model's validator is built when it is first used, not when its class is defined. A file is
    # validated by Experiment (its sections built into Experiment's validator), so the sections' own validators
    # and every model's serializer, never used, are not built at each start (about 15 ms of `odelab run`).
    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)


class System(_Section):
    """[system]: what is integrated."""

    kind: Literal["ode", "state-space", "diagram", "network", "implicit", "fmu"] = "ode"
    file: StrictStr | None = None  # kind = "fmu": the FMU (experiment/kinds/fmu.py)
    interface: Literal["model-exchange", "co-simulation"] | None = None  # kind = "fmu"
    states: list[StrictStr] | None = None
    equations: dict[str, Value] | None = None
    residuals: dict[str, Value] | None = None  # kind = "implicit": F(t, x, der(x)) = 0 (experiment/kinds/implicit.py)
    function: StrictStr | None = None
    inputs: list[StrictStr] | None = None
    outputs: Union[dict[str, Value], list[StrictStr], None] = None
    A: Matrix | None = None
    B: Matrix | None = None
    C: Matrix | None = None
    D: Matrix | None = None
    jacobian: list[list[Value]] | None = None  # analytic df/dx of [system.equations], row i = d(eq_i)/dx
    algebraic_loops: Literal["warning", "none", "error", "solve"] | None = None  # diagrams (Simulink's diagnostic)


class Time(_Section):
    """[time]: the span and the output times."""

    start: Value = 0
    stop: Value
    output: Union[list[Value], StrictStr, None] = None  # a list, or a MATLAB range "0:0.1:15"
    points: StrictInt | None = None


class Solver(_Section):
    """[solver]: the method, then the solver options of the option registry (see :func:`solver_model`)."""

    method: StrictStr = DEFAULT_METHOD


# The [solver] keys that are not solver options: which engine runs, and the diagrams' zero crossings.
_SOLVER_RUN_KEYS: dict[str, Any] = {
    "backend": (Literal["auto", "python", "compiled"], "auto"),  # see odelab.solvers.compiled
    "zero_crossing": (StrictBool, True),  # diagrams: locate switching blocks' crossings (systems/diagram/zerocross)
    # the global error estimate (a second solve at tighter tolerances, odelab.run.estimate); None: the default
    "estimate_error": (Optional[StrictBool], None),
}
# How an option is given in a file (odelab.solvers.optionset.SolverOption.toml) -> its type in the schema;
# "state names" are compiled to indices and a "matrix" of expressions to numbers by the loader.
_OPTION_TYPES: dict[str, Any] = {
    "number": Number, "numbers": Union[Number, list[Number]], "integer": StrictInt,
    "switch": Union[StrictBool, Literal["on", "off"]], "state names": list[StrictStr], "matrix": Matrix,
    "text": StrictStr,
}
_SOLVER_MODELS: dict[tuple, type[BaseModel]] = {}


def solver_model() -> type[BaseModel]:
    """The model of [solver]: ``method``, every option of :data:`odelab.solvers.optionset.OPTIONS` that a file can
    give (MATLAB's names are mapped to odelab's before validation), ``backend`` and ``zero_crossing``. Rebuilt when
    an option is registered, so a solver option is one declaration in one file."""
    shape = tuple((o.name, o.toml, o.choices) for o in OPTIONS.values() if o.toml)
    model = _SOLVER_MODELS.get(shape)
    if model is None:
        fields: dict[str, Any] = {}
        for name, toml, choices in shape:
            kind = Literal[choices] if toml == "choice" else _OPTION_TYPES[toml]
            fields[name] = (Optional[kind], None)
        model = create_model("Solver", __base__=Solver, __doc__=Solver.__doc__, **fields, **_SOLVER_RUN_KEYS)
        _SOLVER_MODELS.clear()  # one registry at a time
        _SOLVER_MODELS[shape] = model
    return model


def __getattr__(name: str):
    if name == "SOLVER_KEYS":  # [solver] keys, after MATLAB's names are mapped to odelab's: read from the registry
        return tuple(solver_model().model_fields)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _solver(value: Any, handler) -> BaseModel:
    model = solver_model()
    return value if isinstance(value, model) else model.model_validate(value)


#: [solver]: validated by the model of the option registry as it is now.
SolverTable = Annotated[Any, WrapValidator(_solver)]


class Reference(_Section):
    """[reference]: what errors are measured against."""

    method: Literal["auto", "exact", "lti", "high-accuracy", "none"] = "auto"
    solver: StrictStr = "auto"  # DOP853, or Radau once the problem proves stiff (analysis/reference.py)
    rtol: Number = 1e-12
    atol: Number = 1e-14


# How a signal key is given (odelab.signals.SignalKey.kind) -> its type in the schema
_SIGNAL_KEY_TYPES = {"number": Number, "text": StrictStr, "expression": Value, "numbers": list[Number]}
_SIGNAL_MODELS: dict[tuple, type[BaseModel]] = {}


def input_signal_model() -> type[BaseModel]:
    """The model of one [inputs.<name>] table, built from the signal registry (:data:`odelab.signals.SIGNALS`).

    ``type`` is one of the registered types and the other keys are every type's keys (which of
    them apply to the given type is checked when the signal is built). Rebuilt when a type is
    registered, so a signal type is one class in one file.
    """
    from odelab.signals import SIGNALS

    shape = tuple((name, tuple((k, spec.kind) for k, spec in cls.KEYS.items())) for name, cls in SIGNALS.items())
    model = _SIGNAL_MODELS.get(shape)
    if model is None:
        fields: dict[str, Any] = {"type": (Literal[tuple(SIGNALS)], ...)}
        for cls in SIGNALS.values():
            for k, spec in cls.KEYS.items():
                fields.setdefault(k, (Optional[_SIGNAL_KEY_TYPES[spec.kind]], None))
        model = create_model("InputSignal", __base__=_Section, __doc__="One entry of [inputs]: u(t) for one input "
                             "name.", **fields)
        _SIGNAL_MODELS.clear()  # one registry at a time
        _SIGNAL_MODELS[shape] = model
    return model


def _input_signal(value: Any, handler) -> BaseModel:
    model = input_signal_model()
    return value if isinstance(value, model) else model.model_validate(value)


#: One entry of [inputs]: validated by the model of the signal registry as it is now.
InputSignal = Annotated[Any, WrapValidator(_input_signal)]


class Linearize(_Section):
    """[linearize]: operating point, the linear-versus-nonlinear comparison, the amplitude study."""

    start: Literal["operating-point", "initial"] = "operating-point"
    drive: StrictStr | None = None
    input: dict[str, Value] | None = None
    state: dict[str, Value] | None = None
    guess: dict[str, Value] | None = None
    fixed: dict[str, Value] | None = None
    amplitudes: list[Number] | None = None
    threshold: Number = 0.05
    quantity: StrictStr | None = None
    step_time: Number = 0.0


class BodeRange(_Section):
    """[analysis] bode = { from = 0.01, to = 100 }: the frequency range in rad/s."""

    from_: Number = Field(0.01, alias="from")
    to: Number = 100.0
    points: StrictInt = 200


class Analysis(_Section):
    """[analysis]: control analysis of the (linear or linearised) system."""

    step_info: StrictBool = False
    bode: Union[StrictBool, BodeRange] = False
    poles: StrictBool = False
    input: dict[str, Value] | None = None  # operating input of a nonlinear system (default 0)
    loop: StrictStr | None = None  # diagrams: the block at whose input the loop is opened for margins


class Data(_Section):
    """[data]: measured data, a CSV file with a header row (checked by experiment/data.py)."""

    file: StrictStr
    time: StrictStr = "t"
    columns: dict[str, StrictStr] | None = None  # model quantity = CSV column (default: same names)
    sigma: dict[str, Number] | None = None  # measurement noise per quantity


class FitParameter(_Section):
    """One entry of [fit] parameters: k = { initial = 2, lower = 0, upper = 10 }."""

    initial: Value | None = None  # default: the value in [parameters]
    lower: Number | None = None
    upper: Number | None = None


class Fit(_Section):
    """[fit]: which parameters to estimate from [data] (checked and run by experiment/fit.py)."""

    parameters: dict[str, FitParameter] | None = None  # required: checked by experiment/fit.py with its message
    quantities: list[StrictStr] | None = None  # default: every quantity [data] maps
    validate_: StrictStr | None = Field(None, alias="validate")  # a second data set to check the fitted model against
    method: StrictStr = SENSITIVITY_METHOD  # the solver of states and sensitivities
    rtol: Number = 1e-10
    atol: Number | None = None  # default: rtol times each measured quantity's scale
    max_solves: StrictInt = 500


class Plot(_Section):
    """[plot]: how the report draws the solution (never what is computed)."""

    t_scale: Literal["auto", "linear", "log"] = "auto"  # auto: log when the output times span many decades
    scale: dict[str, Number] | None = None  # display multipliers per quantity: y2 = 1e4 draws 10^4 y2


class Report(_Section):
    """[report]: where the experiment's section stands in the report and a note for its readers."""

    order: StrictInt | None = None  # sections with an order come first, lowest first (the lab sheet's order)
    note: StrictStr | None = None  # a paragraph above the section's figures; **bold** is kept
    quote: list[StrictStr] | None = None  # "experiment/case": stored maximum relative errors the note quotes


def _initial_entry(value, handler):
    """An [initial] entry is a value; a table ([initial.fixed] of an implicit system) passes through, checked
    with its meaning by experiment/kinds/implicit.py."""
    return value if isinstance(value, dict) else handler(value)


#: One entry of [initial]: a number or expression (the table [initial.fixed] passes through).
InitialEntry = Annotated[Value, WrapValidator(_initial_entry)]


class Experiment(_Section):
    """A whole experiment file, or one case after merging it over the base."""

    name: StrictStr | None = None
    title: StrictStr | None = None
    description: StrictStr | None = None
    # How the case is expected to end: "max-steps" marks a case that shows a solver stopped by
    # its step limit on purpose (stiff.toml's ode45); "failure" any failed integration.
    expect: Literal["success", "max-steps", "failure"] | None = None
    parameters: dict[str, Value] = Field(default_factory=dict)
    system: System
    # [initial]: the states' values; an implicit system's "der(x)" guesses and [initial.fixed] too
    initial: dict[str, InitialEntry] = Field(default_factory=dict)
    time: Time
    exact: dict[str, Value] | None = None
    history: dict[str, Value] | None = None  # [history]: x(t) for t <= t0 of delay equations (experiment/delays.py)
    solver: SolverTable = Field(default_factory=lambda: solver_model()())
    reference: Reference = Field(default_factory=Reference)
    inputs: dict[str, InputSignal] | None = None
    linearize: Linearize | None = None
    analysis: Analysis | None = None
    blocks: dict[str, dict[str, Any]] | None = None  # kind = "diagram"; checked by experiment/diagram.py
    elements: dict[str, dict[str, Any]] | None = None  # kind = "network"; checked by systems/network
    plot: Plot | None = None
    report: Report | None = None
    units: dict[str, StrictStr] | None = None  # [units]: x = "m", f = "N", t = "s": axis labels
    events: dict[str, Any] | None = None  # checked and compiled by experiment/events.py
    data: Data | None = None  # [data]: measurements, the reference of every case (experiment/data.py)
    fit: Fit | None = None  # [fit]: taken out of the file by the loader and checked by experiment/fit.py
