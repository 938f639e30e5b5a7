"""Values with units (``L = "100 cm"``, ``k = "3 N/m"``, ``m = "250 g"``), converted with pint.

A number followed by a unit is converted to the unit the file's ``[units]`` table declares for
that name, or, when it declares none, to SI base units; the conversion is said in the run's notes
and in resolved.toml. A unit that does not fit the declared one (a length where [units] says
seconds) is an error naming both. pint (the field's unit library) is imported only when a value
with a unit appears: it costs most of a second.

The text is checked before pint sees it: at most :data:`MAX_UNIT_CHARS` characters of letters,
digits, ``* / ^ . ( ) µ Ω °`` and spaces, brackets at most :data:`MAX_UNIT_DEPTH` deep, a unit
that starts with a letter; pint's own parser reads units as data (names looked up in its registry),
never as code.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from decimal import Decimal

from odelab.exceptions import InputError

__all__ = ["UnitValue", "split_unit_value", "convert", "MAX_UNIT_CHARS", "MAX_UNIT_DEPTH"]

MAX_UNIT_CHARS = 40
MAX_UNIT_DEPTH = 3

_VALUE = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-zµμΩ°%(].*?)\s*$")
_UNIT_CHARS = re.compile(r"^[A-Za-z0-9µμΩ°%_*/^.() \-]+$")


@dataclass(frozen=True)
class UnitValue:
    """A value converted from a unit: ``given`` (the text), ``value`` in ``unit``."""

    given: str
    value: float
    unit: str

    def note(self, name: str) -> str:
        return f"{name} = {self.given} is {self.value:.10g} {self.unit} (converted by pint)"


def split_unit_value(text: object) -> tuple[float, str] | None:
    """``"100 cm"`` -> (100.0, "cm"); None for anything that is not a number followed by a unit."""
    if not isinstance(text, str):
        return None
    m = _VALUE.match(text)
    if m is None:
        return None
    number, unit = m.groups()
    if not re.search(r"[A-Za-zµμΩ°%]", unit):
        return None
    return float(number), unit


@functools.lru_cache(maxsize=1)
def _registry():
    import pint

    # Decimal arithmetic: 10 µF is 1e-05 F, not 9.999999999999999e-06 (10 * 1e-6 in floats)
    return pint.UnitRegistry(autoconvert_offset_to_baseunit=True, non_int_type=Decimal)


def _check_text(unit: str, where: str) -> None:
    depth = deepest = 0
    for ch in unit:
        depth += ch == "("
        depth -= ch == ")"
        deepest = max(deepest, depth)
    if (len(unit) > MAX_UNIT_CHARS or not _UNIT_CHARS.match(unit) or deepest > MAX_UNIT_DEPTH or depth != 0
            or not re.match(r"^[(]*[A-Za-zµμΩ°%]", unit)):
        shown = unit if len(unit) <= MAX_UNIT_CHARS else unit[:MAX_UNIT_CHARS] + "..."
        raise InputError(f"{where}: {shown!r} is not a unit odelab reads: write one unit expression such as \"m\", "
                         f"\"N/m\", \"m/s^2\" or \"kg*m^2\" (at most {MAX_UNIT_CHARS} characters, brackets at most "
                         f"{MAX_UNIT_DEPTH} deep, no + or -).", key=where.strip("`"))


def _units(unit: str, where: str):
    from pint.errors import PintError

    _check_text(unit, where)
    try:
        parsed = _registry().parse_units(unit.replace("^", "**").replace("μ", "µ"))
    except (PintError, ValueError, TypeError, AttributeError, SyntaxError, RecursionError) as exc:
        why = "it is not a unit pint knows" if "not defined" in str(exc) else "pint cannot read it"
        raise InputError(f"{where}: {unit!r} ({why}); write a unit such as \"cm\", \"N/m\", \"kg\" or \"rad/s\".",
                         key=where.strip("`")) from None
    return parsed


def convert(name: str, text: str, declared: str | None, where: str) -> UnitValue:
    """The value of ``text`` (a number and a unit) in ``declared`` if [units] gives one, else in SI base units.

    Raises
    ------
    InputError
        The unit is not one pint knows, does not fit the declared unit, or the number is not finite.
    """
    from pint.errors import PintError

    number, unit = split_unit_value(text) or (None, None)
    if number is None:
        raise InputError(f"{where} is {text!r}, not a number followed by a unit.", key=where.strip("`"))
    if not math.isfinite(number):
        raise InputError(f"{where} is {text!r}: {number!r} is not a finite number.", key=where.strip("`"))
    given = _units(unit, where)
    registry = _registry()
    quantity = registry.Quantity(Decimal(_VALUE.match(text).group(1)), given)
    if declared is not None:
        target = _units(declared, f"`units.{name}`")
        if given.dimensionality != target.dimensionality:
            raise InputError(f"{where} is {text!r}, a {_kind(given)}, but [units] gives {name} in {declared!r}, a "
                             f"{_kind(target)}: the two do not fit. Correct the value's unit or the one in [units].",
                             key=where.strip("`"))
        try:
            value, shown = float(quantity.to(target).magnitude), declared
        except PintError as exc:
            raise InputError(f"{where} is {text!r}: {exc}", key=where.strip("`")) from None
    else:
        coherent = _coherent(unit)
        base = quantity.to(coherent) if coherent is not None else quantity.to_base_units()
        value, shown = float(base.magnitude), unit_name(base.units)
    if not math.isfinite(value):
        raise InputError(f"{where} is {text!r}, which is {value!r} in {shown}: not a finite number.",
                         key=where.strip("`"))
    return UnitValue(given=text.strip(), value=value, unit=shown)


# SI's coherent units: each factor of a unit is converted to its own coherent SI unit (cm to m, µF to F,
# kN/mm to N/m, ft/s^2 to m/s^2, g to kg, min to s), which keeps the unit a student recognises; a factor
# with no such unit becomes SI base units
_COHERENT = ("m", "s", "A", "K", "mol", "cd", "rad", "kg", "N", "J", "W", "Pa", "Hz", "C", "V", "F", "ohm", "S",
             "Wb", "T", "H", "sr")


def _coherent(unit: str):
    """The unit ``unit`` is converted to (a pint Unit), or None for SI base units."""
    registry = _registry()
    coherent = {registry.get_name(c): registry.parse_units(c) for c in _COHERENT}
    by_dimension = {str(registry.parse_units(c).dimensionality): registry.parse_units(c)
                    for c in ("m", "kg", "s", "A", "K", "mol", "cd")}  # a factor of one base dimension: ft, min, g
    try:
        given = registry.parse_units(unit.replace("^", "**").replace("μ", "µ"))
    except Exception:  # noqa: BLE001 - checked before: not reached
        return None
    out = registry.parse_units("")
    for name, power in given._units.items():
        factor = None
        try:
            (_, base, suffix), *_ = registry.parse_unit_name(name)
            factor = coherent.get(base) if not suffix else None
        except Exception:  # noqa: BLE001
            factor = None
        if factor is None:
            factor = by_dimension.get(str(registry.parse_units(name).dimensionality))
        if factor is None:  # rpm, %, L...: its SI base units (rpm is rad/s, % a plain number)
            factor = registry.Quantity(1, name).to_base_units().units
        out = out * factor ** power
    return out


def unit_name(units) -> str:
    return _si_text(units).replace("Ω", "ohm")


def _kind(units) -> str:
    dims = str(units.dimensionality)
    return "dimensionless number" if dims == "dimensionless" else f"quantity of {dims}"


def _si_text(units) -> str:
    text = f"{units:~}".replace(" ** ", "^").replace("**", "^").replace(" * ", "*").replace(" / ", "/")
    return text or "(dimensionless)"
