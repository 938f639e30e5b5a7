"""Workspaces: the variables of a script or of one call of a function, and the interpreter's budgets and notes.

A nested function's workspace reaches its parent's variables (MATLAB shares them); a
``global`` name lives in the interpreter's one global workspace.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from odelab.exceptions import ExperimentError
from odelab.formats.base import Note

__all__ = ["Scope", "Budget", "Notes", "MAX_CALL_DEPTH", "MAX_STATEMENTS", "MAX_ITERATIONS"]

MAX_CALL_DEPTH = 24
"""Function calls nest at most 24 deep (a driver, its helpers, the right-hand side and what it calls)."""

MAX_STATEMENTS = 300_000
"""The most statements one import executes (loops unrolled included)."""

MAX_ITERATIONS = 100_000
"""The most loop iterations one import unrolls."""


class Scope:
    """One workspace. ``mode`` is "script" (a driver: solver calls are cases, plotting is ignored) or "rhs"
    (a right-hand side, events or mass function being translated)."""

    def __init__(self, file: str, *, function: Any = None, parent: "Scope | None" = None, mode: str = "script",
                 nargin: int = 0, nargout: int = 0):
        self.vars: dict[str, Any] = {}
        self.globals: set[str] = set()
        self.assigned: set[str] = set()  # names assigned before (a constant's first assignment names a parameter)
        self.file = file
        self.function = function
        self.parent = parent  # a nested function's parent workspace
        self.mode = mode
        self.nargin = nargin
        self.nargout = nargout
        self.loop_depth = 0
        self.branch_depth = 0
        self.state_names: dict[int, tuple[str, int]] = {}  # state index -> (name, line): `S = y(1)`
        self.end_stack: list[int] = []  # the extent `end` stands for, innermost last

    def owner(self, name: str) -> "Scope | None":
        """The workspace that holds ``name`` (this one or a parent's), or None."""
        scope: Scope | None = self
        while scope is not None:
            if name in scope.vars:
                return scope
            scope = scope.parent
        return None

    def get(self, name: str, globals_: dict) -> Any:
        if name in self.globals:
            return globals_.get(name)
        owner = self.owner(name)
        return owner.vars[name] if owner is not None else None

    def has(self, name: str, globals_: dict) -> bool:
        if name in self.globals:
            return name in globals_
        return self.owner(name) is not None

    def set(self, name: str, value: Any, globals_: dict) -> None:
        if name in self.globals:
            globals_[name] = value
            return
        owner = self.owner(name)
        (owner or self).vars[name] = value


@dataclass
class Budget:
    """What one import may spend: statements executed, loop iterations unrolled."""

    statements: int = MAX_STATEMENTS
    iterations: int = MAX_ITERATIONS

    def statement(self, line: int, src: str) -> None:
        self.statements -= 1
        if self.statements < 0:
            raise ExperimentError(f"line {line}: the file executes more than {MAX_STATEMENTS:,} statements when "
                                  "read (loops unrolled); odelab translates ODE code, not long computations. "
                                  "Write the experiment file by hand.", source=src)

    def loop(self, count: int, line: int, src: str) -> None:
        self.iterations -= count
        if self.iterations < 0:
            raise ExperimentError(f"line {line}: the loop runs {count:,} times; odelab unrolls at most "
                                  f"{MAX_ITERATIONS:,} loop iterations in a file. Write the experiment file by "
                                  "hand (a parameter study is a [sweep]).", source=src)


@dataclass
class Notes:
    """The import table's rows, each once."""

    rows: list[Note] = field(default_factory=list)
    seen: set = field(default_factory=set)
    main: str = ""  # the imported file: rows about it leave `file` empty

    def add(self, line: int, construct: str, outcome: str, detail: str, file: str = "") -> None:
        shown_file = "" if not file or file == self.main else file
        key = (shown_file, line, construct, outcome)
        if key in self.seen:
            return
        self.seen.add(key)
        self.rows.append(Note(f"line {line}" if line else "file", construct, outcome, detail, shown_file))
