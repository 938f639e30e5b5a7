"""The elements of a physical network: one class per element type (Close & Frederick's
elements of the five domains and the couplings between them).

Each class declares once what it is: its TOML ``type`` name, its domain (two for a
coupling), its role in the derivation, its parameters with their defaults, the name of the
nonlinear law it may take instead of its coefficient (``force = "k1*x + k3*x^3"``) and of the
variable that law is written in. Nothing else in odelab lists element types: the TOML
builder, the messages, the derivation, the drawing and docs/networks.md follow
:data:`ELEMENTS`.

Sign conventions (those of the textbook's linear graphs). An element with ``nodes = [a, b]``
measures its across variable from b to a (``v = v_a - v_b``; a spring's stretch
``x = x_a - x_b``). Passive elements use the passive convention: their through variable flows
through them from a to b (a spring's force ``k*x`` pulls a toward b; a resistor's current
flows from a to b). Sources use the generator convention: their through variable is what
they deliver into node a (a force source pushes a in the positive direction; a current
source drives its current into a; a voltage source's ``i`` leaves it at a).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Any, ClassVar

from odelab.exceptions import InputError

__all__ = ["DOMAINS", "ELEMENTS", "Domain", "Element", "NetworkError", "element_class"]


class NetworkError(InputError):
    """A network that cannot be derived: the message names the elements and the fix."""


@dataclass(frozen=True)
class Domain:
    """One energy domain: its across and through variables (and the across's integral)."""

    name: str
    across: str  # v, w, v, p, T
    through: str  # f, tau, i, q, q
    integral: str | None  # x, theta: the displacement of a mechanical node
    across_word: str
    through_word: str
    node_law: str  # how the node law reads in words


DOMAINS = {
    "translational": Domain("translational", "v", "f", "x", "velocity", "force",
                            "the forces on it sum to zero (D'Alembert)"),
    "rotational": Domain("rotational", "w", "tau", "theta", "angular velocity", "torque",
                         "the torques on it sum to zero"),
    "electrical": Domain("electrical", "v", "i", None, "voltage", "current",
                         "the currents into it sum to zero (Kirchhoff)"),
    "fluid": Domain("fluid", "p", "q", None, "pressure", "flow",
                    "the flows into it sum to zero (continuity)"),
    "thermal": Domain("thermal", "T", "q", None, "temperature", "heat flow",
                      "the heat flows into it sum to zero"),
}


@dataclass(frozen=True)
class Parameter:
    """A coefficient of an element: its default and meaning."""

    default: Any
    doc: str


class Element:
    """Base class of the element types. Instances hold one element's nodes and parameters.

    Parameters and source values are numbers or expression-language strings; they are parsed
    by odelab's expression parser when the network is derived, never evaluated as Python.
    """

    TYPE: ClassVar[str] = ""
    DOMAIN: ClassVar[str] = ""
    DOMAIN2: ClassVar[str | None] = None  # couplings: the domain of nodes2
    ROLE: ClassVar[str] = ""  # across-store, through-store, dissipator, across-source, through-source,
    #                           transformer, gyrator
    GROUNDED: ClassVar[bool] = False  # a mass, an inertia, a fluid or thermal capacitance
    PARAMETERS: ClassVar[dict[str, Parameter]] = {}
    LAW: ClassVar[str | None] = None  # the key of a nonlinear law (force, torque, current, flow)
    LAW_OF: ClassVar[str | None] = None  # the element variable that law is written in
    DOC: ClassVar[str] = ""
    #: words a student writes for this element (its quantity's name, another book's): suggested first
    ALSO: ClassVar[tuple[str, ...]] = ()

    def __init__(self, name: str | None = None, *, node: str | None = None, nodes=None, nodes2=None,
                 **values: Any):
        self.name = name
        if node is not None and nodes is not None:
            raise NetworkError(f"element {name!r}: give `node` or `nodes`, not both.", key="nodes")
        if node is not None:
            nodes = [node, "ground"]
        if nodes is None:
            raise NetworkError(f"element {name!r} ({self.TYPE}) needs its nodes: `nodes = [\"a\", \"b\"]` "
                               f"(or `node = \"a\"` for [\"a\", \"ground\"]).", key="nodes")
        self.nodes = _node_pair(nodes, name, "nodes")
        if self.DOMAIN2 is not None:
            if nodes2 is None:
                raise NetworkError(f"element {name!r} ({self.TYPE}) couples two node pairs: give `nodes2 = "
                                   f"[\"c\", \"ground\"]` for its second side.", key="nodes2")
            self.nodes2 = _node_pair(nodes2, name, "nodes2")
        elif nodes2 is not None:
            raise NetworkError(f"element {name!r}: `nodes2` is for couplings (lever, gear, rack-pinion, "
                               f"dc-motor); a {self.TYPE} has one node pair.", key="nodes2")
        else:
            self.nodes2 = None
        if self.GROUNDED and "ground" not in self.nodes:
            raise NetworkError(f"element {name!r}: a {self.TYPE} is referenced to ground; write `node = "
                               f"\"{self.nodes[0]}\"` (its nodes are [\"{self.nodes[0]}\", \"ground\"]).",
                               key="nodes")
        if self.GROUNDED and self.nodes[0] == "ground":
            self.nodes = (self.nodes[1], "ground")
        self.law = None
        given = dict(values)
        if self.LAW is not None and self.LAW in given:
            self.law = given.pop(self.LAW)
            if not isinstance(self.law, (str, int, float)) or isinstance(self.law, bool):
                raise NetworkError(f"element {name!r}: `{self.LAW}` is a law, an expression string of "
                                   f"{self.LAW_OF}; got {self.law!r}.", key=self.LAW)
            clash = [p for p in self.PARAMETERS if p in given]
            if clash:
                raise NetworkError(f"element {name!r}: give `{clash[0]}` or the law `{self.LAW}`, not both.",
                                   key=clash[0])
        self.values: dict[str, Any] = {}
        for key, value in given.items():
            if key not in self.PARAMETERS:
                raise NetworkError(_unknown_key(self, name, key), key=key)
            if isinstance(value, bool) or not isinstance(value, (int, float, str)):
                raise NetworkError(f"element {name!r}: `{key}` must be a number or an expression string; got "
                                   f"{value!r}.", key=key)
            self.values[key] = value
        for key, param in self.PARAMETERS.items():
            if key not in self.values and not (self.law is not None and key != "value"):
                if param.default is None:
                    raise NetworkError(f"element {name!r} ({self.TYPE}) needs `{key}`: {param.doc}.", key=key)
                self.values[key] = param.default

    # -- what the element is -----------------------------------------------------------------

    @classmethod
    def keys(cls) -> list[str]:
        """Every key of this type in a TOML table (for messages)."""
        keys = ["node" if cls.GROUNDED else "nodes"]
        if cls.DOMAIN2:
            keys.append("nodes2")
        keys += list(cls.PARAMETERS)
        if cls.LAW:
            keys.append(cls.LAW)
        return keys

    @classmethod
    def variables(cls) -> tuple[str, ...]:
        """The element variables usable as ``name.variable``."""
        d = DOMAINS[cls.DOMAIN]
        own = tuple(v for v in (d.integral, d.across, d.through) if v)
        if cls.DOMAIN2 is None:
            return own
        d2 = DOMAINS[cls.DOMAIN2]
        second = tuple(v for v in (d2.integral, d2.across, d2.through) if v)
        if cls.DOMAIN2 == cls.DOMAIN:
            second = tuple(v + "2" for v in second)
        return own + second

    def describe(self) -> str:
        """``spring from p to ground`` / ``mass at p``."""
        a, b = self.nodes
        where = f"at {a}" if self.GROUNDED or (b == "ground" and self.ROLE.endswith("source")) else f"from {a} to {b}"
        if self.nodes2 is not None:
            where = f"{self.nodes[0]}-{self.nodes[1]} to {self.nodes2[0]}-{self.nodes2[1]}"
        return f"{self.TYPE} {where}"

    def __repr__(self) -> str:
        args = [repr(self.name)] if self.name else []
        args.append(f"nodes={list(self.nodes)!r}")
        if self.nodes2:
            args.append(f"nodes2={list(self.nodes2)!r}")
        args += [f"{k}={v!r}" for k, v in self.values.items()]
        if self.law is not None:
            args.append(f"{self.LAW}={self.law!r}")
        return f"{type(self).__name__}({', '.join(args)})"


def _node_pair(nodes, name, key) -> tuple[str, str]:
    if isinstance(nodes, str):
        nodes = [nodes, "ground"]
    if (not isinstance(nodes, (list, tuple)) or len(nodes) != 2
            or not all(isinstance(n, str) and n.strip() for n in nodes)):
        raise NetworkError(f"element {name!r}: `{key}` must be two node names, e.g. [\"p\", \"ground\"]; got "
                           f"{nodes!r}.", key=key)
    if nodes[0] == nodes[1]:
        raise NetworkError(f"element {name!r}: `{key}` joins node {nodes[0]!r} to itself; an element joins two "
                           "different nodes.", key=key)
    if any(len(n) > 64 or any(c in n for c in "\"\n\r\t") for n in nodes):
        raise NetworkError(f"element {name!r}: node names are short names on one line; got {nodes!r}.", key=key)
    return (nodes[0], nodes[1])


# what a student may write for a coefficient, by its meaning
_MEANINGS = {"mass": "m", "stiffness": "k", "spring_constant": "k", "damping": "b", "friction": "b",
             "resistance": "R", "capacitance": "C", "inductance": "L", "inertia": "J", "inertance": "I",
             "ratio": "n", "radius": "r", "constant": "K", "value": "value", "torque": "torque",
             "current": "current", "flow": "flow", "force": "force"}


def _unknown_key(cls_or_self, name, key) -> str:
    known = cls_or_self.keys()
    close = difflib.get_close_matches(key, known, n=1)
    meant = _MEANINGS.get(key.lower()) or _MEANINGS.get(key)
    if meant in known and not close:
        close = [meant]
    hint = f" Did you mean `{close[0]}`?" if close else ""
    return (f"element {name!r}: `{key}` is not a key of a {cls_or_self.TYPE}; a {cls_or_self.TYPE} takes "
            f"{', '.join(known)}.{hint}")


def _p(doc: str, default: Any = 1) -> Parameter:
    return Parameter(default, doc)


_VALUE = {"value": Parameter(None, "its value, a number or an expression of inputs, parameters and t")}


# --- translational ---------------------------------------------------------------------------

class Mass(Element):
    TYPE, DOMAIN, ROLE, GROUNDED = "mass", "translational", "across-store", True
    ALSO = ('point-mass',)
    PARAMETERS = {"m": _p("mass (kg)")}
    DOC = "m dv/dt = f, the net force on it; dx/dt = v"


class Spring(Element):
    TYPE, DOMAIN, ROLE = "spring", "translational", "through-store"
    ALSO = ('stiffness', 'linear-spring')
    PARAMETERS = {"k": _p("stiffness (N/m)")}
    LAW, LAW_OF = "force", "x"
    DOC = "f = k x, x = x_a - x_b its stretch"


class Damper(Element):
    TYPE, DOMAIN, ROLE = "damper", "translational", "dissipator"
    ALSO = ('damping', 'dashpot', 'viscous-damper')
    PARAMETERS = {"b": _p("damping coefficient (N s/m)")}
    LAW, LAW_OF = "force", "v"
    DOC = "f = b v, v = v_a - v_b"


class ForceSource(Element):
    TYPE, DOMAIN, ROLE = "force-source", "translational", "through-source"
    ALSO = ('force',)
    PARAMETERS = dict(_VALUE)
    DOC = "f = value, a force on a in the positive direction (and its reaction on b)"


class VelocitySource(Element):
    TYPE, DOMAIN, ROLE = "velocity-source", "translational", "across-source"
    ALSO = ('velocity',)
    PARAMETERS = dict(_VALUE)
    DOC = "v_a - v_b = value"


# --- rotational ------------------------------------------------------------------------------

class Inertia(Element):
    TYPE, DOMAIN, ROLE, GROUNDED = "inertia", "rotational", "across-store", True
    ALSO = ('moment-of-inertia', 'flywheel')
    PARAMETERS = {"J": _p("moment of inertia (kg m^2)")}
    DOC = "J dw/dt = tau, the net torque on it; dtheta/dt = w"


class TorsionSpring(Element):
    TYPE, DOMAIN, ROLE = "torsion-spring", "rotational", "through-store"
    PARAMETERS = {"k": _p("torsional stiffness (N m/rad)")}
    LAW, LAW_OF = "torque", "theta"
    DOC = "tau = k theta, theta = theta_a - theta_b its twist"


class RotationalDamper(Element):
    TYPE, DOMAIN, ROLE = "rotational-damper", "rotational", "dissipator"
    PARAMETERS = {"b": _p("rotational damping (N m s/rad)")}
    LAW, LAW_OF = "torque", "w"
    DOC = "tau = b w, w = w_a - w_b"


class TorqueSource(Element):
    TYPE, DOMAIN, ROLE = "torque-source", "rotational", "through-source"
    ALSO = ('torque',)
    PARAMETERS = dict(_VALUE)
    DOC = "tau = value, a torque on a in the positive direction"


class SpeedSource(Element):
    TYPE, DOMAIN, ROLE = "speed-source", "rotational", "across-source"
    PARAMETERS = dict(_VALUE)
    DOC = "w_a - w_b = value"


# --- electrical ------------------------------------------------------------------------------

class Resistor(Element):
    TYPE, DOMAIN, ROLE = "resistor", "electrical", "dissipator"
    ALSO = ('resistance',)
    PARAMETERS = {"R": _p("resistance (ohm)")}
    LAW, LAW_OF = "current", "v"
    DOC = "i = v/R, v = v_a - v_b"


class Capacitor(Element):
    TYPE, DOMAIN, ROLE = "capacitor", "electrical", "across-store"
    ALSO = ('capacitance',)
    PARAMETERS = {"C": _p("capacitance (F)")}
    DOC = "C dv/dt = i"


class Inductor(Element):
    TYPE, DOMAIN, ROLE = "inductor", "electrical", "through-store"
    ALSO = ('inductance', 'coil')
    PARAMETERS = {"L": _p("inductance (H)")}
    DOC = "L di/dt = v"


class VoltageSource(Element):
    TYPE, DOMAIN, ROLE = "voltage-source", "electrical", "across-source"
    ALSO = ('voltage', 'battery')
    PARAMETERS = dict(_VALUE)
    DOC = "v_a - v_b = value; i is the current it delivers out of a"


class CurrentSource(Element):
    TYPE, DOMAIN, ROLE = "current-source", "electrical", "through-source"
    ALSO = ('current',)
    PARAMETERS = dict(_VALUE)
    DOC = "i = value, driven into a (out of b)"


# --- fluid -----------------------------------------------------------------------------------

class FluidCapacitance(Element):
    TYPE, DOMAIN, ROLE, GROUNDED = "fluid-capacitance", "fluid", "across-store", True
    PARAMETERS = {"C": _p("fluid capacitance (m^3/Pa; a tank's area / (rho g))")}
    DOC = "C dp/dt = q, the net flow into it"


class FluidResistance(Element):
    TYPE, DOMAIN, ROLE = "fluid-resistance", "fluid", "dissipator"
    PARAMETERS = {"R": _p("fluid resistance (Pa s/m^3)")}
    LAW, LAW_OF = "flow", "p"
    DOC = "q = p/R, p = p_a - p_b"


class FluidInertance(Element):
    TYPE, DOMAIN, ROLE = "fluid-inertance", "fluid", "through-store"
    PARAMETERS = {"I": _p("fluid inertance (Pa s^2/m^3)")}
    DOC = "I dq/dt = p"


class PressureSource(Element):
    TYPE, DOMAIN, ROLE = "pressure-source", "fluid", "across-source"
    PARAMETERS = dict(_VALUE)
    DOC = "p_a - p_b = value"


class FlowSource(Element):
    TYPE, DOMAIN, ROLE = "flow-source", "fluid", "through-source"
    PARAMETERS = dict(_VALUE)
    DOC = "q = value, into a"


# --- thermal ---------------------------------------------------------------------------------

class ThermalCapacitance(Element):
    TYPE, DOMAIN, ROLE, GROUNDED = "thermal-capacitance", "thermal", "across-store", True
    PARAMETERS = {"C": _p("thermal capacitance (J/K)")}
    DOC = "C dT/dt = q, the net heat flow into it"


class ThermalResistance(Element):
    TYPE, DOMAIN, ROLE = "thermal-resistance", "thermal", "dissipator"
    PARAMETERS = {"R": _p("thermal resistance (K/W)")}
    DOC = "q = T/R, T = T_a - T_b"


class HeatSource(Element):
    TYPE, DOMAIN, ROLE = "heat-source", "thermal", "through-source"
    PARAMETERS = dict(_VALUE)
    DOC = "q = value, into a"


class TemperatureSource(Element):
    TYPE, DOMAIN, ROLE = "temperature-source", "thermal", "across-source"
    PARAMETERS = dict(_VALUE)
    DOC = "T_a - T_b = value"


# --- couplings -------------------------------------------------------------------------------

class Lever(Element):
    TYPE, DOMAIN, DOMAIN2, ROLE = "lever", "translational", "translational", "transformer"
    PARAMETERS = {"n": _p("ratio of the arms: v2 = v/n, f2 = n f")}
    DOC = "v2 = v/n, f2 = n f (an ideal lever, n:1)"


class Gear(Element):
    TYPE, DOMAIN, DOMAIN2, ROLE = "gear", "rotational", "rotational", "transformer"
    PARAMETERS = {"n": _p("gear ratio n:1: w2 = w/n, tau2 = n tau")}
    DOC = "w2 = w/n, tau2 = n tau (an ideal n:1 reduction)"


class RackPinion(Element):
    TYPE, DOMAIN, DOMAIN2, ROLE = "rack-pinion", "rotational", "translational", "transformer"
    PARAMETERS = {"r": _p("pinion radius (m): v = r w, f = tau/r")}
    DOC = "v = r w, f = tau/r (the rack's velocity and force)"


class DCMotor(Element):
    TYPE, DOMAIN, DOMAIN2, ROLE = "dc-motor", "electrical", "rotational", "gyrator"
    PARAMETERS = {"K": _p("motor constant (N m/A = V s/rad)")}
    DOC = "tau = K i, v = K w (an ideal gyrator: torque from current, back-emf from speed)"


ELEMENTS: dict[str, type[Element]] = {cls.TYPE: cls for cls in (
    Mass, Spring, Damper, ForceSource, VelocitySource,
    Inertia, TorsionSpring, RotationalDamper, TorqueSource, SpeedSource,
    Resistor, Capacitor, Inductor, VoltageSource, CurrentSource,
    FluidCapacitance, FluidResistance, FluidInertance, PressureSource, FlowSource,
    ThermalCapacitance, ThermalResistance, HeatSource, TemperatureSource,
    Lever, Gear, RackPinion, DCMotor)}


def suggest_element(word: str) -> str | None:
    """The element type a student most likely means: one whose ``ALSO`` words hold ``word`` (a resistance
    is a resistor before it is a fluid or thermal resistance), else the closest type name."""
    key = word.strip().lower().replace("_", "-").replace(" ", "-")
    for cls in ELEMENTS.values():
        if key in cls.ALSO:
            return cls.TYPE
    words = {w: cls.TYPE for cls in ELEMENTS.values() for w in cls.ALSO}
    close = difflib.get_close_matches(key, [*ELEMENTS, *words], n=1)
    return (words.get(close[0], close[0])) if close else None


def element_class(kind: Any, name: str = "") -> type[Element]:
    """The class of an element type name, or a NetworkError with the valid types (did-you-mean)."""
    if isinstance(kind, str) and kind in ELEMENTS:
        return ELEMENTS[kind]
    close = suggest_element(str(kind))
    hint = f" Did you mean {close!r}?" if close else ""
    where = f"element {name!r}: " if name else ""
    raise NetworkError(f"{where}{kind!r} is not an element type; the types are {', '.join(ELEMENTS)}.{hint}",
                       key="type")
