"""Physical networks: a system described by its elements; odelab derives the equations.

``Network(elements, outputs=...)`` takes elements (:mod:`.elements`, one class per type), checks
the graph (:mod:`.graph`), derives the state equations symbolically as Close & Frederick do
(:mod:`.derive`, with SymPy) and compiles them to the system odelab already runs: a
:class:`~odelab.systems.statespace.StateSpace` when the network is linear, otherwise a
:class:`~odelab.systems.nonlinear.NonlinearSystem` of expression-language equations compiled by
odelab's own safe compiler. SymPy is imported only when a network is derived.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from odelab.systems.network.elements import (
    DOMAINS,
    ELEMENTS,
    Capacitor,
    CurrentSource,
    Damper,
    DCMotor,
    Element,
    FlowSource,
    FluidCapacitance,
    FluidInertance,
    FluidResistance,
    ForceSource,
    Gear,
    HeatSource,
    Inductor,
    Inertia,
    Lever,
    Mass,
    NetworkError,
    PressureSource,
    RackPinion,
    Resistor,
    RotationalDamper,
    SpeedSource,
    Spring,
    TemperatureSource,
    ThermalCapacitance,
    ThermalResistance,
    TorqueSource,
    TorsionSpring,
    VelocitySource,
    VoltageSource,
    element_class,
)

__all__ = ["Network", "NetworkError", "ELEMENTS", "DOMAINS", "Element", "element_class",
           "Mass", "Spring", "Damper", "ForceSource", "VelocitySource",
           "Inertia", "TorsionSpring", "RotationalDamper", "TorqueSource", "SpeedSource",
           "Resistor", "Capacitor", "Inductor", "VoltageSource", "CurrentSource",
           "FluidCapacitance", "FluidResistance", "FluidInertance", "PressureSource", "FlowSource",
           "ThermalCapacitance", "ThermalResistance", "HeatSource", "TemperatureSource",
           "Lever", "Gear", "RackPinion", "DCMotor"]


#: The largest network derived: the symbolic solve grows as the cube of the elements (a ladder
#: of 40 elements takes about 10 s on a loaded 2-core machine).
MAX_ELEMENTS = 120


def _check_element_name(name) -> str:
    if not isinstance(name, str) or not name.isascii() or not name.isidentifier() or name.startswith("_") \
            or name == "ground" or name == "t":
        raise NetworkError(f"element name {name!r}: names are identifiers (letters, digits, _), not starting "
                           "with _ and not `t` or `ground`, so that `name.variable` can be written in "
                           "expressions.", key=f"elements.{name}")
    return name


class Network:
    """A network of elements, derived into state equations and compiled into a system.

    Parameters
    ----------
    elements
        ``{name: element}`` (e.g. ``{"mass": Mass(node="p", m="m")}``), or a list of elements
        created with their names (``Mass("mass", node="p", m="m")``).
    outputs
        ``{name: expression}`` of element variables (``mass.x``), inputs and parameters.
    parameters
        ``{name: value}``: the values of the names the elements' coefficients use.
    """

    def __init__(self, elements, outputs: Mapping[str, str] | None = None,
                 parameters: Mapping[str, float] | None = None):
        if isinstance(elements, Mapping):
            items = list(elements.items())
        else:
            items = [(getattr(e, "name", None), e) for e in elements]
        self.elements: dict[str, Element] = {}
        for name, el in items:
            if not isinstance(el, Element):
                raise NetworkError(f"element {name!r} is {el!r}, not an element (Mass, Spring, Resistor...).",
                                   key=f"elements.{name}")
            _check_element_name(name)
            if name in self.elements:
                raise NetworkError(f"two elements are named {name!r}; rename one.", key=f"elements.{name}")
            el.name = name
            self.elements[name] = el
        if not self.elements:
            raise NetworkError("a network needs elements, e.g. {\"mass\": Mass(node=\"p\", m=1)}.", key="elements")
        if len(self.elements) > MAX_ELEMENTS:
            raise NetworkError(f"the network has {len(self.elements)} elements; odelab derives networks of at most "
                               f"{MAX_ELEMENTS} (a symbolic derivation grows with the cube of the size): split it, "
                               "or write its equations as kind = \"ode\".", key="elements")
        self.outputs = dict(outputs or {})
        self.parameters = dict(parameters or {})
        self._derivation = None

    @classmethod
    def from_tables(cls, tables: Mapping[str, Mapping[str, Any]], outputs=None, parameters=None) -> "Network":
        """A network from TOML-like tables ``{name: {"type": "mass", "node": "p", "m": "m"}}``."""
        elements = {}
        for name, spec in tables.items():
            key = f"elements.{name}"
            if not isinstance(spec, Mapping):
                raise NetworkError(f"`{key}` must be a table, e.g. {name} = {{ type = \"mass\", node = \"p\", m = 1 }}"
                                   f"; got {spec!r}.", key=key)
            _check_element_name(name)
            kind = spec.get("type")
            if kind is None:
                raise NetworkError(f"`{key}.type` is required: one of {', '.join(ELEMENTS)}.", key=f"{key}.type")
            try:
                cls_ = element_class(kind, name)
                elements[name] = cls_(name, **{k: v for k, v in spec.items() if k != "type"})
            except NetworkError as exc:
                sub = exc.key if exc.key and not exc.key.startswith("elements") else None
                raise NetworkError(exc.message, key=f"{key}.{sub}" if sub else (exc.key or key)) from None
            except TypeError as exc:  # pragma: no cover - keyword clash such as a duplicated name
                raise NetworkError(f"`{key}`: {exc}", key=key) from None
        return cls(elements, outputs=outputs, parameters=parameters)

    # -- the derivation ---------------------------------------------------------------------

    def derive(self):
        """The symbolic derivation (a :class:`~.derive.Derivation`), computed once."""
        if self._derivation is None:
            from odelab.systems.network.derive import derive

            self._derivation = derive(self.elements, self.outputs, tuple(self.parameters))
        return self._derivation

    @property
    def states(self) -> tuple[str, ...]:
        return self.derive().states

    @property
    def inputs(self) -> tuple[str, ...]:
        return self.derive().inputs

    def equations(self) -> dict[str, str]:
        """``{state: derivative}`` in the expression language."""
        return self.derive().equation_texts()

    def matrices(self, parameters: Mapping[str, float] | None = None):
        """A, B, C, D as float arrays for a linear network (None for a nonlinear one)."""
        d = self.derive()
        if not d.linear:
            return None
        values = self._values(parameters)
        return {k: _evaluate(m, values, f"the {k} matrix") for k, m in d.matrices.items()}

    def compile(self, parameters: Mapping[str, float] | None = None):
        """The system odelab runs: a StateSpace if linear, else a NonlinearSystem."""
        d = self.derive()
        values = self._values(parameters)
        if d.linear:
            from odelab.systems.statespace import StateSpace

            m = self.matrices(values)
            return StateSpace(m["A"], m["B"], m["C"], m["D"], states=list(d.states), inputs=list(d.inputs),
                              outputs=list(d.outputs))
        from odelab.systems.nonlinear import NonlinearSystem

        return NonlinearSystem.from_expressions(d.equation_texts(), inputs=d.inputs,
                                                outputs=d.output_texts() or None, parameters=values)

    def _values(self, parameters):
        values = dict(self.parameters)
        if parameters:
            values.update(parameters)
        missing = [p for p in self.derive().parameters if p not in values]
        if missing:  # pragma: no cover - derive() takes its parameter names from these values
            raise NetworkError(f"parameter {missing[0]!r} has no value.", key="parameters")
        return {k: float(v) for k, v in values.items()}

    def describe(self, width: int = 80) -> str:
        """The derivation as text: element laws, interconnection laws, states, state equations
        (and A, B, C, D and the transfer functions of a linear network)."""
        from odelab.systems.network.show import derivation_text

        return derivation_text(self, self._values(None), width=width)


def _evaluate(matrix, values, what):
    """A SymPy matrix of parameters -> floats, through odelab's expression compiler."""
    import numpy as np

    from odelab.expressions.compile import compile_expression
    from odelab.systems.network.symbolic import to_text

    out = np.zeros(matrix.shape, dtype=float)
    for i in range(matrix.shape[0]):
        for j in range(matrix.shape[1]):
            text = to_text(matrix[i, j])
            fn = compile_expression(text, names=list(values), key=what)
            out[i, j] = float(fn(**{n: values[n] for n in fn.names}))
    return out
