"""``odeset`` and ``odeget``: MATLAB's options struct, with MATLAB's names matched as MATLAB matches them.

``odeset('reltol', 1e-4)`` and ``odeset('RelT', 1e-4)`` both set ``RelTol`` (case-insensitive, a unique
prefix); ``odeset(old, 'Name', value)`` and ``odeset(old, new)`` update. Which of these odelab
translates, and into which ``[solver]`` key, is :mod:`.translate`'s business.
"""

from __future__ import annotations

import numpy as np

from odelab.formats.matlab.values import Arr, Str, Struct, Unknown, Unsupported

__all__ = ["ODESET_NAMES", "odeset", "odeget", "odeset_field", "canonical_option"]

ODESET_NAMES = ("AbsTol", "BDF", "Events", "InitialSlope", "InitialStep", "Jacobian", "JConstant", "JPattern",
                "Mass", "MassSingular", "MaxOrder", "MaxStep", "MinStep", "MStateDependence", "MvPattern",
                "NonNegative", "NormControl", "OutputFcn", "OutputSel", "Refine", "RelTol", "Stats", "Vectorized")


def canonical_option(name: str) -> str:
    """MATLAB's spelling of an odeset name given in any case or as a unique prefix."""
    lower = name.lower()
    for known in ODESET_NAMES:
        if known.lower() == lower:
            return known
    matches = [k for k in ODESET_NAMES if k.lower().startswith(lower)]
    if len(matches) == 1:
        return matches[0]
    if not matches:
        raise Unsupported(f"`{name}` is not an odeset option (MATLAB's are {', '.join(ODESET_NAMES)})")
    raise Unsupported(f"`{name}` is ambiguous among odeset's options {', '.join(matches)}")


def odeset(interp, args: list, nargout: int, node, scope) -> list:
    fields: dict = {}
    k = 0
    while k < len(args) and isinstance(args[k], Struct):
        fields.update(args[k].fields)
        k += 1
    while k < len(args) and isinstance(args[k], Unknown):
        return [args[k]]
    rest = args[k:]
    if len(rest) % 2:
        raise Unsupported("odeset takes name-value pairs: a name is missing its value")
    for name, value in zip(rest[::2], rest[1::2]):
        if not isinstance(name, Str):
            raise Unsupported(interp.why_not_number(name, "an odeset option name"))
        fields[canonical_option(name.text)] = value
    return [Struct(fields, odeset=True)]


def odeset_field(options: Struct, name: str):
    """``options.RelTol`` of an odeset struct that does not set it: [] as MATLAB gives."""
    canonical_option(name)
    return Arr(0, 0, data=np.zeros((0, 0)))


def odeget(interp, args: list, nargout: int, node, scope) -> list:
    if len(args) < 2 or not isinstance(args[0], Struct) or not isinstance(args[1], Str):
        raise Unsupported("odeget(options, 'Name') with a constant name")
    name = canonical_option(args[1].text)
    if name in args[0].fields:
        return [args[0].fields[name]]
    return [args[2] if len(args) > 2 else Arr(0, 0, data=np.zeros((0, 0)))]
