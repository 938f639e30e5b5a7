"""Where a block's names come from: the workspace, then the masks of the subsystems around it.

A block parameter ``k`` means the innermost masked subsystem's ``k`` if it has one, else the
next mask out, else the workspace's ``k`` (Simulink's rule). Each binding that is a number
becomes one entry of the experiment's ``[parameters]`` (so a student can change ``m`` in one
place and sweep it), named after the variable; an inner mask's ``k`` that would collide with an
outer ``k`` is named after its subsystem (``plant_k``). Arrays are written out as their numbers.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from odelab.formats.simulink.mexpr import V, text_of

__all__ = ["Parameter", "Parameters", "Scope", "identifier"]


def identifier(text: str) -> str:
    """A block's or a variable's name made a valid identifier: ASCII letters, digits and ``_``, not starting
    with a digit (``"Transfer Fcn 1"`` -> ``Transfer_Fcn_1``)."""
    out = re.sub(r"[^A-Za-z0-9_]+", "_", text.strip()).strip("_")
    if not out:
        out = "block"
    if out[0].isdigit():
        out = "b_" + out
    return out


@dataclass
class Parameter:
    name: str
    value: float | str | None  # None: nobody sets it (a gap)
    comment: str
    used_by: list[str] = field(default_factory=list)


class Parameters:
    """The experiment's [parameters], in the order they are first used."""

    def __init__(self):
        self.entries: dict[str, Parameter] = {}
        self.taken: set[str] = set()

    def new(self, wanted: str, value, comment: str, owner: str = "") -> str:
        name = identifier(wanted)
        if name in self.taken:
            name = identifier(f"{owner}_{wanted}") if owner else name
        base, n = name, 2
        while name in self.taken:
            name = f"{base}_{n}"
            n += 1
        self.taken.add(name)
        self.entries[name] = Parameter(name, value, comment)
        return name


class Scope:
    """Names visible to the blocks of one system: a subsystem's mask, then its parent's scope."""

    def __init__(self, parent: "Scope | None", bindings: dict | None = None, params: Parameters | None = None,
                 where: str = ""):
        self.parent = parent
        self.params = params if params is not None else parent.params
        self.raw = dict(bindings or {})  # name -> (np.ndarray, comment) or (V, comment) not yet made parameters
        self.made: dict[str, V] = {}
        self.where = where

    def lookup(self, name: str, user: str = "") -> V | None:
        scope = self
        while scope is not None:
            if name in scope.made:
                found = scope.made[name]
                scope._use(name, found, user)
                return found
            if name in scope.raw:
                found = scope._make(name)
                scope._use(name, found, user)
                return found
            scope = scope.parent
        return None

    def _use(self, name, found: V, user: str):
        if found.sym is not None and found.scalar:
            entry = self.params.entries.get(str(found.sym[0, 0]))
            if entry is not None and user and user not in entry.used_by:
                entry.used_by.append(user)

    def _make(self, name: str) -> V:
        value, comment = self.raw.pop(name)
        if isinstance(value, V):
            if value.scalar and value.sym is not None and re.fullmatch(r"[A-Za-z_]\w*", str(value.sym[0, 0])):
                made = value  # a mask parameter that is another parameter: the same one
            elif value.scalar:
                text = text_of(value) if value.sym is not None else float(value.num[0, 0])
                pname = self.params.new(name, text, comment, self.where)
                made = V(value.num.copy(), np.array([[pname]], dtype=object))
            else:
                made = value
        else:
            num = np.atleast_2d(np.asarray(value, dtype=float))
            if num.size == 1 and np.isfinite(num[0, 0]):
                pname = self.params.new(name, float(num[0, 0]), comment, self.where)
                made = V(num, np.array([[pname]], dtype=object))
            else:
                made = V(num)
        self.made[name] = made
        return made
