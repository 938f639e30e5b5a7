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

__all__ = ["complex_step_jacobian", "expression_jacobian"]

_H = 1e-200  # complex step: any tiny h works, as there is no subtractive cancellation


def complex_step_jacobian(equations: Sequence[str], states: Sequence[str], parameters: Mapping[str, float],
                          *, keys: Sequence[str] | None = None, source: str | None = None):
    """``J(t, y)`` of the right-hand sides ``equations`` (one per state) by complex step."""
    from odelab.expressions import compile_vector

    n = len(states)
    steps = 1j * _H * np.eye(n)
    compiled = []  # compiled on first use: only the stiff solvers call it

    def jacobian(t, y):
        if not compiled:
            compiled.append(compile_vector(list(equations), args=["t", *states], constants=dict(parameters),
                                           keys=keys, source=source, complex_step=True))
        Y = np.asarray(y, dtype=float)[:, None] + steps  # column j perturbs state j
        out = np.asarray(compiled[0](complex(t), *Y), dtype=complex)
        return np.broadcast_to(out, (n, n)).imag / _H

    structure = []

    def pattern():
        """Where ``J`` can be nonzero: entry (i, j) where equation i names state j (the stiff
        solvers factor banded when it allows, :mod:`odelab.solvers.banded`)."""
        if not structure:
            from odelab.expressions import parse_expression
            from odelab.solvers.banded import structural_pattern

            known = {"t", *states, *parameters}
            parsed = [parse_expression(text, key=keys[i] if keys else None, source=source, names=known)
                      for i, text in enumerate(equations)]
            structure.append(structural_pattern([p.names for p in parsed], states))
        return structure[0]

    jacobian.source = "complex step on the equations"
    jacobian.pattern = pattern
    return jacobian


def expression_jacobian(matrix: Sequence[Sequence[str | float]], states: Sequence[str],
                        parameters: Mapping[str, float], *, key: str = "system.jacobian", source: str | None = None):
    """``J(t, y)`` from an n-by-n matrix of expressions in ``t``, the states and parameters."""
    from odelab.expressions import compile_vector

    n = len(states)
    texts = [entry for row in matrix for entry in row]
    keys = [f"{key}[{i}][{j}]" for i in range(n) for j in range(n)]
    F = compile_vector(texts, args=["t", *states], constants=dict(parameters), keys=keys, source=source)

    def jacobian(t, y):
        return np.asarray(F(t, *np.asarray(y, dtype=float)), dtype=float).reshape(n, n)

    jacobian.source = "the analytic jacobian in the file"
    return jacobian
