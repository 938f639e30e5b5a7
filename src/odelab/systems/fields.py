"""A built system's right-hand sides and event functions as objects that pickle, not closures.

A case's ``fun(t, x)``, a system's ``f(t, x, u)``, its inputs ``u(t)`` and its [events]'
functions are small typed objects over compiled expressions
(:func:`odelab.expressions.compile_vector`'s functions), matrices and signals. Each pickles
field by field (:class:`odelab.expressions.compile.Portable`: a compiled function travels as its
texts and is compiled again where it is unpickled), so that a built case can be sent to another
process, a Dask worker, instead of the worker loading the experiment file again. The outputs
``y = g(t, x, u)`` are in :mod:`odelab.systems.outputs`.
"""

from __future__ import annotations

import numpy as np

from odelab.expressions.compile import Portable

__all__ = ["ExpressionField", "LinearField", "InputField", "SignalColumns", "EventValues", "EventReset",
           "ExactTime", "ExactSolution"]

# Plain classes with __slots__, not dataclasses: a dataclass costs its module ~2.7 M instructions to
# create (its generated methods are compiled at import), and these are imported by every run.


class ExpressionField(Portable):
    """``x' = F(t, *x)``: a system of equations without inputs (``F`` is compile_vector's function of t and
    the states)."""

    __slots__ = ("F",)

    def __init__(self, F):
        self.F = F

    def __call__(self, t, x):
        return self.F(t, *x)


class LinearField(Portable):
    """``x' = A x``: a linear system without inputs."""

    __slots__ = ("A",)

    def __init__(self, A: np.ndarray):
        self.A = A

    def __call__(self, t, x):
        return self.A @ x


class InputField(Portable):
    """``F(t, *x, *u)`` called as ``f(t, x, u)`` (a NonlinearSystem's dynamics or outputs); ``nx`` states."""

    __slots__ = ("F", "nx")

    def __init__(self, F, nx: int):
        self.F, self.nx = F, nx

    def __call__(self, t, x, u):
        return self.F(t, *x[:self.nx], *u)


class SignalColumns(Portable):
    """The inputs at the times ``t`` (k,), one column per signal: (k, m)."""

    __slots__ = ("signals",)

    def __init__(self, signals: tuple):
        self.signals = signals

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        return np.column_stack([np.broadcast_to(np.asarray(s(t), dtype=float), t.shape) for s in self.signals])


class EventValues(Portable):
    """The [events]' ``when`` values at (t, x), as floats."""

    __slots__ = ("F",)

    def __init__(self, F):
        self.F = F

    def __call__(self, t, x):
        return np.asarray(self.F(t, *x), dtype=float)


class EventReset(Portable):
    """An event's reset: the states at ``index`` set to ``F(t, *x)``, the others kept."""

    __slots__ = ("F", "index")

    def __init__(self, F, index: np.ndarray):
        self.F, self.index = F, index

    def __call__(self, t, x):
        new = np.array(x, dtype=float)
        new[self.index] = np.asarray(self.F(t, *x), dtype=float)
        return new


class ExactTime(Portable):
    """An event's ``exact`` time of its ``k``-th occurrence (a compiled expression of k and the parameters)."""

    __slots__ = ("expression", "parameters")

    def __init__(self, expression, parameters: dict):
        self.expression, self.parameters = expression, parameters

    def __call__(self, k):
        return float(self.expression(k=k, **self.parameters))


class ExactSolution(Portable):
    """[exact]: ``{name: values at t}`` from compiled expressions of t and the parameters."""

    __slots__ = ("expressions", "parameters")

    def __init__(self, expressions: dict, parameters: dict):
        self.expressions, self.parameters = expressions, parameters

    def __call__(self, t):
        return {name: np.broadcast_to(np.asarray(fn(t=t, **self.parameters), dtype=float), np.shape(t)).astype(float)
                for name, fn in self.expressions.items()}
