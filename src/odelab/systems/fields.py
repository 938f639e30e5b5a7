"""A built system's right-hand sides and event functions as objects that pickle, not closures.

A case's ``fun(t, x)``, a system's ``f(t, x, u)``, its inputs ``u(t)`` and its [events]'
functions are small frozen dataclasses over compiled expressions
(:func:`odelab.expressions.compile_vector`'s functions), matrices and signals. Each pickles
field by field (:class:`odelab.expressions.compile.Portable`: a compiled function travels as its
texts and is compiled again where it is unpickled), so that a built case can be sent to another
process, a Dask worker, instead of the worker loading the experiment file again. The outputs
``y = g(t, x, u)`` are in :mod:`odelab.systems.outputs`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from odelab.expressions.compile import Portable

__all__ = ["ExpressionField", "LinearField", "InputField", "SignalColumns", "EventValues", "EventReset",
           "ExactTime", "ExactSolution"]


@dataclass(frozen=True, eq=False)
class ExpressionField(Portable):
    """``x' = F(t, *x)``: a system of equations without inputs (``F`` is compile_vector's function of t and
    the states)."""

    F: Any

    def __call__(self, t, x):
        return self.F(t, *x)


@dataclass(frozen=True, eq=False)
class LinearField:
    """``x' = A x``: a linear system without inputs."""

    A: np.ndarray

    def __call__(self, t, x):
        return self.A @ x


@dataclass(frozen=True, eq=False)
class InputField(Portable):
    """``F(t, *x, *u)`` called as ``f(t, x, u)`` (a NonlinearSystem's dynamics or outputs); ``nx`` states."""

    F: Any
    nx: int

    def __call__(self, t, x, u):
        return self.F(t, *x[:self.nx], *u)


@dataclass(frozen=True, eq=False)
class SignalColumns:
    """The inputs at the times ``t`` (k,), one column per signal: (k, m)."""

    signals: tuple

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        return np.column_stack([np.broadcast_to(np.asarray(s(t), dtype=float), t.shape) for s in self.signals])


@dataclass(frozen=True, eq=False)
class EventValues(Portable):
    """The [events]' ``when`` values at (t, x), as floats."""

    F: Any

    def __call__(self, t, x):
        return np.asarray(self.F(t, *x), dtype=float)


@dataclass(frozen=True, eq=False)
class EventReset(Portable):
    """An event's reset: the states at ``index`` set to ``F(t, *x)``, the others kept."""

    F: Any
    index: np.ndarray

    def __call__(self, t, x):
        new = np.array(x, dtype=float)
        new[self.index] = np.asarray(self.F(t, *x), dtype=float)
        return new


@dataclass(frozen=True, eq=False)
class ExactTime:
    """An event's ``exact`` time of its ``k``-th occurrence (a compiled expression of k and the parameters)."""

    expression: Any
    parameters: dict

    def __call__(self, k):
        return float(self.expression(k=k, **self.parameters))


@dataclass(frozen=True, eq=False)
class ExactSolution:
    """[exact]: ``{name: values at t}`` from compiled expressions of t and the parameters."""

    expressions: dict
    parameters: dict

    def __call__(self, t):
        return {name: np.broadcast_to(np.asarray(fn(t=t, **self.parameters), dtype=float), np.shape(t)).astype(float)
                for name, fn in self.expressions.items()}
