"""A built system's outputs y = g(t, x, u) as objects, not closures rebuilt per system kind.

``output_fn(t, x, u=None)`` takes the times (k,), the states (k, n) and the inputs (k, m) or
None, and returns the outputs (k, p). Two kinds cover every system odelab builds:
:class:`LinearOutputs` (``y = x C^T + u D^T``: state-space models and linear networks) and
:class:`ExpressionOutputs` (compiled expressions of t, the states and the inputs: equation
systems, nonlinear networks, implicit systems). Both are small classes that pickle:
the linear one with its matrices, the other with its expressions' texts (compiled again where it
is unpickled: :class:`odelab.expressions.compile.Portable`).
"""

from __future__ import annotations

import numpy as np

from odelab.expressions.compile import Portable

__all__ = ["LinearOutputs", "ExpressionOutputs"]


class LinearOutputs(Portable):
    """y = C x + D u, row by row: ``x @ C.T (+ u @ D.T)``."""

    __slots__ = ("C", "D")

    def __init__(self, C: np.ndarray, D: np.ndarray):
        self.C, self.D = C, D

    def __call__(self, t, x, u=None):
        y = x @ self.C.T
        if u is not None and self.D.size:
            y = y + u @ self.D.T
        return y


class ExpressionOutputs(Portable):
    """y = g(t, x, u) from compiled expressions (``compile_vector``'s function of t, the states and the
    inputs, in that order), ``count`` of them."""

    __slots__ = ("G", "count")

    def __init__(self, G, count: int):
        self.G, self.count = G, count

    def __call__(self, t, x, u=None):
        cols = [t, *x.T] + ([] if u is None else [*u.T])
        return np.asarray(self.G(*cols), dtype=float).reshape(self.count, -1).T
