"""Exceptions raised by odelab.

Every error odelab raises on purpose derives from :class:`OdelabError`, and also from the
matching builtin (``ValueError`` for bad input, ``RuntimeError`` for internal faults), so
callers can catch either. The core never prints or exits: the CLI turns these into one
message and an exit code (2 for :class:`InputError`).

A failed integration is *not* an exception: the solvers return a
:class:`~odelab.solution.Solution` with ``status == "failed"`` and a message.
"""

from __future__ import annotations

__all__ = [
    "OdelabError",
    "InputError",
    "ExpressionError",
    "ExperimentError",
    "OdelabWarning",
    "SolverWarning",
    "few",
]


def few(names, *, shown: int = 6, sep: str = ", ", quote: bool = False) -> str:
    """A few of ``names`` and how many in all: "x0, x1, x2, ... (476,000 in all)".

    Messages name what is wrong; a list of half a million names (or a loop through 10,000
    blocks) is not a message. Lists up to ``shown + 2`` long are given whole.
    """
    names = list(names)
    text = [repr(n) if quote else str(n) for n in names[:shown if len(names) > shown + 2 else len(names)]]
    if len(names) > len(text):
        return f"{sep.join(text)}{sep}... ({len(names):,} in all)"
    return sep.join(text)


class OdelabError(Exception):
    """Base class of the errors odelab raises on purpose."""


class InputError(OdelabError, ValueError):
    """Bad input: a function argument or a value in an experiment file.

    Parameters
    ----------
    message
        What is wrong and how to fix it, e.g. "`rtol` must be positive; got -0.001."
    source
        The file the value came from, if any.
    key
        The TOML key path (``solver.rtol``) or argument name, if any.
    """

    def __init__(self, message: str, *, source: str | None = None, key: str | None = None):
        super().__init__(message)
        self.message = message
        self.source = source
        self.key = key

    def located(self, *, source: str | None = None, key: str | None = None) -> "InputError":
        """Fill in where the error happened, keeping what is already known; returns self."""
        if self.source is None and source is not None:
            self.source = source
        if self.key is None and key is not None:
            self.key = key
        return self

    def __str__(self) -> str:
        prefix = f"{self.source}: " if self.source else ""
        return prefix + self.message


class ExperimentError(InputError):
    """An experiment file is unreadable or invalid (TOML syntax, schema, values)."""


class ExpressionError(InputError):
    """An expression of the safe expression language is invalid.

    Besides the message it carries the expression text and the 0-based column of the
    offending part, and renders a caret under it.
    """

    def __init__(
        self,
        message: str,
        *,
        expression: str,
        column: int | None = None,
        source: str | None = None,
        key: str | None = None,
    ):
        super().__init__(message, source=source, key=key)
        self.expression = expression
        self.column = column

    def caret(self) -> str:
        """The offending line of the expression and a caret under the column (two lines), or ''.

        ``column`` counts characters from the start of the whole text, so for a multi-line
        TOML string the line holding it is shown, with the caret at its place in that line.
        """
        if self.column is None:
            return ""
        start = self.expression.rfind("\n", 0, self.column) + 1
        end = self.expression.find("\n", self.column)
        line = self.expression[start : end if end >= 0 else len(self.expression)]
        col = self.column - start
        if len(line) > 120:  # show a window around the column of a long line
            left = max(0, col - 60)
            line, col = line[left : left + 120], col - left
        return f"    {line}\n    {' ' * col}^"

    def __str__(self) -> str:
        head = super().__str__()
        if self.key and f"`{self.key}`" not in head:
            head = head.replace(self.message, f"`{self.key}`: {self.message}", 1)
        tail = self.caret()
        return f"{head}\n{tail}" if tail else head


class OdelabWarning(UserWarning):
    """Base class of the warnings odelab issues."""


class SolverWarning(OdelabWarning):
    """An integration failed (MATLAB prints "Warning: Failure at t=..."); the partial solution is returned.

    Library users who check ``sol.status`` can silence it:
    ``warnings.simplefilter("ignore", odelab.SolverWarning)``.
    """
