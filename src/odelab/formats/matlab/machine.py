"""The interpreter assembled: its built-ins, statements and expressions, which it calls but does not import."""

from __future__ import annotations

from odelab.formats.matlab import branches, builtins, evaluate, results
from odelab.formats.matlab.interp import Hooks, Interpreter

__all__ = ["HOOKS", "make_interpreter"]

HOOKS = Hooks(builtins=builtins.BUILTINS, command=builtins.command, run_if=branches.run_if,
              run_switch=branches.run_switch, run_for=branches.run_for, run_while=branches.run_while,
              expressions=evaluate.EXPRESSIONS, index_result=results.index_result,
              result_numbers=results.result_numbers)


def make_interpreter(source, notes, **kwargs) -> Interpreter:
    """An :class:`~.interp.Interpreter` of ``source`` with odelab's built-ins (see :mod:`.builtins`)."""
    return Interpreter(source, notes, HOOKS, **kwargs)
