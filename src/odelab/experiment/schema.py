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

Number = Union[StrictInt, StrictFloat]
Value = Union[StrictInt, StrictFloat, StrictStr]
Matrix = Union[Value, list[Value], list[list[Value]]]

__all__ = ["Experiment", "SOLVER_KEYS"]

# [solver] keys, after MATLAB's names are mapped to odelab's (see odelab.solvers.options).
SOLVER_KEYS = ("method", "rtol", "atol", "max_step", "initial_step", "refine", "norm_control", "h", "max_steps",
               "max_order", "bdf", "vectorized",
               "nonnegative", "mass", "mstate_dependence", "backend", "zero_crossing")


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class System(_Section):
    """[system]: what is integrated."""

    kind: Literal["ode", "state-space", "diagram", "network"] = "ode"
    states: list[StrictStr] | None = None
    equations: dict[str, Value] | None = None
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
    """[solver]: method and options (MATLAB's odeset names are mapped before validation)."""

    method: StrictStr = "ode45"
    rtol: Number | None = None
    atol: Union[Number, list[Number], None] = None
    max_step: Number | None = None
    initial_step: Number | None = None
    refine: StrictInt | None = None
    norm_control: Union[StrictBool, Literal["on", "off"], None] = None
    h: Number | None = None
    max_steps: StrictInt | None = None
    max_order: StrictInt | None = None  # ode15s's MaxOrder
    bdf: Union[StrictBool, Literal["on", "off"], None] = None  # ode15s's BDF
    vectorized: Union[StrictBool, Literal["on", "off"], None] = None
    nonnegative: list[StrictStr] | None = None  # state names; compiled to indices by the loader
    mass: Matrix | None = None  # expressions of t, the states and the parameters
    mstate_dependence: Literal["none", "weak", "strong"] | None = None
    backend: Literal["auto", "python", "compiled"] = "auto"  # see odelab.solvers.compiled
    zero_crossing: StrictBool = True  # diagrams: locate switching blocks' crossings (odelab.systems.diagram.zerocross)


class Reference(_Section):
    """[reference]: what errors are measured against."""

    method: Literal["auto", "exact", "lti", "high-accuracy", "none"] = "auto"
    solver: StrictStr = "auto"  # DOP853, or Radau once the problem proves stiff (analysis/reference.py)
    rtol: Number = 1e-12
    atol: Number = 1e-14


# How a signal key is given (odelab.signals.SignalKey.kind) -> its type in the schema
_SIGNAL_KEY_TYPES = {"number": Number, "text": StrictStr, "expression": Value}
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
    method: StrictStr = "ode78"  # the solver of states and sensitivities
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
    initial: dict[str, Value] = Field(default_factory=dict)
    time: Time
    exact: dict[str, Value] | None = None
    history: dict[str, Value] | None = None  # [history]: x(t) for t <= t0 of delay equations (experiment/delays.py)
    solver: Solver = Field(default_factory=Solver)
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
