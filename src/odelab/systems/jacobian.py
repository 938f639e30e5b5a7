"""Exact Jacobians ``df/dy`` of expression systems, for the stiff solvers.

An experiment's equations are known expressions, so the stiff solvers need not pay finite
differences for them (n extra evaluations per Jacobian, and an error of sqrt(eps)):

* :func:`complex_step_jacobian` differentiates the equations by complex step
  (Squire & Trapp, SIAM Review 40(1), 1998): ``df/dy_j = Im f(y + i h e_j) / h`` with
  ``h = 1e-200``, exact to rounding since nothing is subtracted. The expression compiler's
  complex-step variant is used (its functions are analytic continuations; ``abs``, ``sign``,
  comparisons differentiate as their real counterparts), and all n columns go through one
  vectorised call of the compiled function;
* :func:`expression_jacobian` compiles a user's analytic ``jacobian = [[...]]`` matrix of
  expressions.

Both return ``J(t, y) -> (n, n) ndarray``, the form ``odelab.ode15s(..., jacobian=J)`` takes;
the complex-step one also carries ``J.pattern()``, its structure from the equations.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import numpy as np

from odelab.expressions import compile_vector, parse_expression
from odelab.expressions.compile import Portable

__all__ = ["ComplexStepJacobian", "MatrixJacobian", "complex_step_jacobian", "expression_jacobian"]

_H = 1e-200  # complex step: any tiny h works, as there is no subtractive cancellation


def complex_step_jacobian(equations: Sequence[str], states: Sequence[str], parameters: Mapping[str, float],
                          *, keys: Sequence[str] | None = None, source: str | None = None,
                          compiled=None) -> ComplexStepJacobian:
    """``J(t, y)`` of the right-hand sides ``equations`` (one per state) by complex step. ``compiled``: the
    equations compiled already with ``complex_step=True`` over ``t`` and the states with these parameters
    (a NonlinearSystem's twin, :meth:`~odelab.systems.nonlinear.NonlinearSystem.expression_parts`), used
    instead of compiling them again on first use."""
    jacobian = ComplexStepJacobian(tuple(equations), tuple(states), dict(parameters),
                                   None if keys is None else tuple(keys), source)
    jacobian._compiled = compiled
    return jacobian


class ComplexStepJacobian:
    """``J(t, y)`` by complex step on the equations' texts, compiled on first use (only the stiff solvers call
    it); ``pattern()`` is where ``J`` can be nonzero. Pickles as its texts (a built case travels to Dask)."""

    source = "complex step on the equations"

    def __init__(self, equations: tuple, states: tuple, parameters: dict, keys: tuple | None, file: str | None):
        self.equations, self.states, self.parameters, self.keys, self.file = equations, states, parameters, keys, file
        self._steps = 1j * _H * np.eye(len(states))
        self._compiled = None
        self._pattern = None

    def __getstate__(self):
        return {**self.__dict__, "_compiled": None}

    def __call__(self, t, y):
        if self._compiled is None:
            self._compiled = compile_vector(list(self.equations), args=["t", *self.states],
                                            constants=dict(self.parameters), keys=self.keys, source=self.file,
                                            complex_step=True)
        n = len(self.states)
        Y = np.asarray(y, dtype=float)[:, None] + self._steps  # column j perturbs state j
        out = np.asarray(self._compiled(complex(t), *Y), dtype=complex)
        return np.broadcast_to(out, (n, n)).imag / _H

    def pattern(self):
        """Where ``J`` can be nonzero: entry (i, j) where equation i names state j (the stiff solvers factor
        banded when it allows, :mod:`odelab.solvers.banded`)."""
        if self._pattern is None:
            from odelab.solvers.banded import structural_pattern

            known = {"t", *self.states, *self.parameters}
            parsed = [parse_expression(text, key=self.keys[i] if self.keys else None, source=self.file,
                                       names=known) for i, text in enumerate(self.equations)]
            self._pattern = structural_pattern([p.names for p in parsed], self.states)
        return self._pattern


def expression_jacobian(matrix: Sequence[Sequence[str | float]], states: Sequence[str],
                        parameters: Mapping[str, float], *, key: str = "system.jacobian", source: str | None = None):
    """``J(t, y)`` from an n-by-n matrix of expressions in ``t``, the states and parameters."""
    n = len(states)
    texts = [entry for row in matrix for entry in row]
    keys = [f"{key}[{i}][{j}]" for i in range(n) for j in range(n)]
    return MatrixJacobian(compile_vector(texts, args=["t", *states], constants=dict(parameters), keys=keys,
                                         source=source), n)


class MatrixJacobian(Portable):
    """``J(t, y)`` from compiled expressions of its n*n entries, row by row."""

    __slots__ = ("F", "n")
    source = "the analytic jacobian in the file"

    def __init__(self, F, n: int):
        self.F, self.n = F, n

    def __call__(self, t, y):
        return np.asarray(self.F(t, *np.asarray(y, dtype=float)), dtype=float).reshape(self.n, self.n)
