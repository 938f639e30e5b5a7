"""A right-hand side read as equations: the function called with the time and the states as symbols.

``f(t, y)`` is called (never run: read, by :mod:`.interp`) with ``t`` the time and ``y`` the
vector of states; what it returns, element by element, is each state's derivative in odelab's
expression language. A name the function gives a state (``S = y(1)``) names it; otherwise the
states are ``y1``, ``y2``... after the function's own name for the vector. The events function
(``[value, isterminal, direction] = events(t, y)``) and a mass matrix function ``M(t, y)`` are
read the same way.
"""

from __future__ import annotations

import keyword
from dataclasses import dataclass, field

from odelab.formats.matlab import nodes as n
from odelab.formats.matlab.flow import ErrorCalled
from odelab.formats.matlab.values import (
    Arr,
    Deriv,
    FuncValue,
    ResultRef,
    State,
    Str,
    Time,
    TooBig,
    Unknown,
    Unsupported,
)

__all__ = ["Reading", "read_function", "state_names", "uses_flag", "definition_site", "element_gap"]


@dataclass
class Reading:
    """What a function returned when read with symbolic t and y: its outputs, or why not."""

    outputs: list = field(default_factory=list)
    gap: Unknown | None = None
    names: dict[int, tuple[str, int]] = field(default_factory=dict)  # state -> (name, line)
    base: str = ""  # the function's name for the state vector
    lines: dict[int, int] = field(default_factory=dict)


def uses_flag(interp, fv: FuncValue) -> bool:
    """MATLAB 5's ODE-file protocol: ``f(t, y, flag, p1, ...)`` called by name (``ode45('f', ...)``)."""
    if not fv.from_string:
        return False
    from odelab.formats.matlab.scope import Scope

    fn = interp.find_function(fv.name, Scope(fv.file or interp.src))
    return isinstance(fn, n.Function) and len(fn.inputs) >= 3


def read_function(interp, fv: FuncValue, states: int, extras: list, nargout: int, *, with_state: bool = True,
                  time_only: bool = False, flag: str | None = None, derivatives: bool = False) -> Reading:
    """Call ``fv(t, y, extras...)`` on symbols (``flag`` inserts MATLAB 5's flag argument; ``derivatives`` passes
    y' as ode15i's third argument, ``f(t, y, yp)``)."""
    t = Arr.scalar(Time())
    y = Arr(states, 1, items=[State(i) for i in range(states)])
    args = [t] if time_only else [t, y]
    if derivatives:
        args.append(Arr(states, 1, items=[Deriv(i) for i in range(states)]))
    if flag is not None:
        args.append(Str(flag))
    args.extend(extras)
    interp.state_vector = y
    interp.state_names = {}
    interp.state_base = ""
    interp.assign_log = []
    try:
        outputs = interp.call_value(fv, args, nargout, fv.line, mode="rhs")
    except (Unsupported, TooBig) as exc:
        return Reading(gap=Unknown(str(exc), fv.line, fv.file))
    except ErrorCalled as exc:
        return Reading(gap=Unknown(f"the function calls error({exc.args[0]!r}) (line {exc.line})", exc.line, fv.file))
    finally:
        interp.state_vector = None
    reading = Reading(outputs=list(outputs), names=dict(interp.state_names), base=interp.state_base)
    reading.lines = _element_lines(interp, fv, states)
    for value in outputs[:max(nargout, 1)]:
        if isinstance(value, Unknown):
            reading.gap = value
            break
    return reading


def _element_lines(interp, fv: FuncValue, states: int) -> dict[int, int]:
    """The line that last set each element of the function's output (``dy(2) = ...``, or ``dy = [...]``)."""
    fn = interp.find_function(fv.name, fv.closure if fv.closure is not None else _scope_of(interp, fv)) \
        if fv.params is None else None
    if not isinstance(fn, n.Function) or not fn.outputs:
        return {}
    out = fn.outputs[0]
    lines: dict[int, int] = {}
    for function, name, position, line in interp.assign_log:
        if function is not fn or name != out:
            continue
        if position is None:
            lines = {i: line for i in range(states)}
        elif 0 <= position < states:
            lines[position] = line
    return lines


def _scope_of(interp, fv: FuncValue):
    from odelab.formats.matlab.scope import Scope

    return Scope(fv.file or interp.src)


def state_names(reading: Reading, count: int, reserved: set[str]) -> list[str]:
    """Each state's name: the one the function gives it, else y1, y2... (the function's name for the vector)."""
    base = reading.base if reading.base and reading.base.isidentifier() else "y"
    names: list[str] = []
    given = {}
    used_names: dict[str, int] = {}
    for index, (name, _) in reading.names.items():
        used_names[name] = used_names.get(name, 0) + 1
    for index, (name, _) in sorted(reading.names.items()):
        ok = (name.isidentifier() and name.isascii() and not keyword.iskeyword(name) and name not in reserved
              and not name.startswith("_") and used_names[name] == 1 and index < count)
        if ok:
            given[index] = name
    if count == 1 and base not in reserved and not keyword.iskeyword(base):
        return [given.get(0, base)]
    for i in range(count):
        names.append(given.get(i, f"{base}{i + 1}"))
    if len(set(names)) != len(names):  # a given name equal to a default one (x2 = y(1)): defaults for all
        names = [f"{base}{i + 1}" for i in range(count)]
    return names


def definition_site(interp, fv: FuncValue) -> tuple[str, int, str]:
    """Where a handle's function is written: (file, line, name) of `function ... = f(...)`, or of `@(...)`."""
    if fv.params is not None:
        return fv.file, fv.line, fv.text
    from odelab.formats.matlab.scope import Scope

    fn = interp.find_function(fv.name, fv.closure if fv.closure is not None else Scope(fv.file or interp.src))
    if isinstance(fn, n.Function):
        return fn.file or fv.file, fn.line, fn.name
    return fv.file, fv.line, fv.name


def element_gap(item) -> str | None:
    """Why one element of a right-hand side is not an equation (it reads a solver's result), or None."""
    for leaf in item.leaves():
        if isinstance(leaf, ResultRef):
            return "it uses a value from a solver's result"
    return None
