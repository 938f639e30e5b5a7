"""Control flow and failures of reading a MATLAB file: what a statement raises instead of a value."""

from __future__ import annotations

from odelab.formats.matlab import nodes as n

__all__ = ["Failure", "ErrorCalled", "BreakLoop", "ContinueLoop", "ReturnNow", "assigned_names"]


class Failure(Exception):
    """A statement odelab cannot read; its targets become :class:`~.values.Unknown`."""


class ErrorCalled(Exception):
    """``error(...)`` was reached: MATLAB would stop there."""

    def __init__(self, message: str, line: int):
        super().__init__(message)
        self.line = line


class BreakLoop(Exception):
    pass


class ContinueLoop(Exception):
    pass


class ReturnNow(Exception):
    pass


def assigned_names(body: list[n.Stmt]) -> set[str]:
    """The variables a block assigns (at any depth), read from its syntax (iteratively)."""
    names: set[str] = set()
    stack = list(body)
    while stack:
        stmt = stack.pop()
        if isinstance(stmt, n.Assign):
            for target in stmt.targets:
                node = target
                while isinstance(node, (n.Index, n.Field, n.DynField)):
                    node = node.target
                if isinstance(node, n.Id):
                    names.add(node.name)
        elif isinstance(stmt, n.If):
            for _, block in stmt.clauses:
                stack.extend(block)
            stack.extend(stmt.orelse or [])
        elif isinstance(stmt, (n.For, n.While)):
            if isinstance(stmt, n.For):
                names.add(stmt.var.name)
            stack.extend(stmt.body)
        elif isinstance(stmt, n.Switch):
            for _, block in stmt.cases:
                stack.extend(block)
            stack.extend(stmt.otherwise or [])
        elif isinstance(stmt, n.TryCatch):
            stack.extend(stmt.body + stmt.handler)
    return names
