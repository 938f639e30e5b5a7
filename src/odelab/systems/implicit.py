"""Fully implicit systems ``F(t, x, x') = 0`` from expressions: ``der(x)`` in [system.residuals].

An experiment file writes one residual per state, each an expression that is zero on the
solution, with ``der(x)`` for ``x'``::

    [system]
    kind = "implicit"
    states = ["y"]
    [system.residuals]
    r = "t*y^2*der(y)^3 - y^3*der(y)^2 + t*(t^2 + 1)*der(y) - t^2*y"

A residual without ``der()`` is an algebraic equation (a DAE, as Robertson's
``y1 + y2 + y3 - 1``). :class:`ImplicitSystem` checks the residuals (one per state, every
``der()`` of a state, some ``der()`` somewhere, every state used), rewrites each ``der(x)`` as a
plain name on the parsed tree and compiles them into one generated function, as
:mod:`odelab.systems.delay` does for ``lag()``; its partial derivatives ``dF/dx`` and ``dF/dx'``
are exact, by complex step (Squire & Trapp, SIAM Review 40(1), 1998) through the compiler's
complex-step variant, all 2n columns in one vectorised call. The system is solved by MATLAB's
ode15i (:func:`odelab.ode15i`) from initial values made consistent by decic
(:func:`odelab.decic`); :func:`odelab.solve` runs it like any other system when it carries its
consistent slope (:meth:`ImplicitSystem.with_start`).
"""

from __future__ import annotations

import ast
import copy
import difflib
from collections.abc import Mapping, Sequence

import numpy as np

from odelab.exceptions import ExpressionError, InputError
from odelab.expressions import compile_vector
from odelab.expressions.compile import PortableState, _unknown_name_error
from odelab.expressions.parse import DER, parse_expression
from odelab.solvers.optionset import DEFAULT_ATOL, DEFAULT_RTOL

__all__ = ["ImplicitSystem", "uses_der"]

_H = 1e-200  # the complex step: nothing is subtracted, so any tiny step is exact to rounding


def uses_der(texts) -> bool:
    """Whether any of the expressions ``texts`` calls ``der(...)`` (a cheap test before parsing)."""
    return any(isinstance(t, str) and DER + "(" in t.replace(" ", "") for t in texts)


def _der_calls(tree: ast.AST) -> list[ast.Call]:
    return [node for node in ast.walk(tree)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == DER]


def _replace(tree: ast.AST, old: ast.AST, new: ast.AST) -> None:
    for parent in ast.walk(tree):
        for name, value in ast.iter_fields(parent):
            if value is old:
                setattr(parent, name, new)
                return
            if isinstance(value, list):
                for i, item in enumerate(value):
                    if item is old:
                        value[i] = new
                        return


class ImplicitSystem(PortableState):
    """``F(t, x, x') = 0``: residual expressions in ``t``, the states, ``der(state)`` and the parameters.

    Parameters
    ----------
    residuals
        Residual name -> expression (zero on the solution), one per state.
    states
        The state names.
    parameters
        Constants the expressions may use.
    source
        The experiment file, for messages (keys ``system.residuals.<name>``).

    Attributes
    ----------
    states, names
        The states and the residuals' names; ``differential`` the states whose ``der()`` appears.
    """

    def __init__(self, residuals: Mapping[str, object], states: Sequence[str], *,
                 parameters: Mapping[str, float] | None = None, source: str | None = None):
        params = {k: float(v) for k, v in (parameters or {}).items()}
        self.states = tuple(states)
        self.names = tuple(residuals)
        n = len(self.states)
        if len(self.names) != n:
            raise InputError(
                f"[system.residuals] has {len(self.names)} residual{'s' if len(self.names) != 1 else ''} for "
                f"{n} state{'s' if n != 1 else ''} ({', '.join(self.states)}): an implicit system needs exactly one "
                "residual (an equation F = 0) per state, as many equations as unknowns.",
                source=source, key="system.residuals")
        derivative = {s: f"der_{s}" for s in self.states}
        used_names = set(self.states) | set(params) | {"t"}
        for s in self.states:
            while derivative[s] in used_names:
                derivative[s] += "_"
            used_names.add(derivative[s])
        known = ["t", *self.states, *params]
        texts, keys = [], []
        seen_der: set[str] = set()
        seen_states: set[str] = set()
        for name in self.names:
            key = f"system.residuals.{name}"
            keys.append(key)
            parsed = parse_expression(residuals[name], key=key, source=source, names=known)
            tree = parsed.tree
            for call in _der_calls(tree):
                target = call.args[0]
                if target.id not in self.states:
                    what = ("time" if target.id == "t" else "a parameter" if target.id in params
                            else "not a name this system knows")
                    close = difflib.get_close_matches(target.id, self.states, n=1)
                    hint = f"; did you mean `der({close[0]})`?" if close else ""
                    raise ExpressionError(
                        f"`der({target.id})`: {target.id} is {what}, not a state; der() takes a state "
                        f"({', '.join(self.states)}){hint}",
                        expression=parsed.text, column=parsed.column(target.col_offset), source=source, key=key)
                seen_der.add(target.id)
                replacement = ast.Name(id=derivative[target.id], ctx=ast.Load())
                ast.copy_location(replacement, call)
                _replace(tree, call, replacement)
            error = _unknown_name_error(parsed, known, key, source)
            if error is not None:
                raise error
            seen_states |= set(parsed.names) & set(self.states)
            texts.append(ast.unparse(tree))
        if not seen_der:
            raise InputError(
                "[system.residuals] uses no der(): nothing is differentiated, so this is an algebraic system, not "
                "a differential equation; write each state's derivative as der(x), e.g. "
                f"r = \"der({self.states[0]}) + {self.states[0]}\" for {self.states[0]}' = -{self.states[0]}.",
                source=source, key="system.residuals")
        unused = [s for s in self.states if s not in seen_states]
        if unused:
            raise InputError(
                f"state {unused[0]!r} appears in no residual (neither {unused[0]} nor der({unused[0]})): the "
                "equations cannot determine it; use it in a residual or remove it from `system.states`.",
                source=source, key="system.states")
        self.differential = tuple(s for s in self.states if s in seen_der)
        self.residuals = {name: str(residuals[name]) for name in self.names}
        self.parameters = params
        args = ["t", *self.states, *(derivative[s] for s in self.states)]
        self._F = compile_vector(texts, args=args, constants=params, keys=keys, source=source)
        self._complex = []  # the complex-step variant, compiled on first use
        self._complex_recipe = (texts, args, params, keys, source)
        self._n = n
        self.t0 = self.y0 = self.yp0 = None
        self.fixed_y0 = self.fixed_yp0 = None

    # --- F and its partial derivatives ---------------------------------------------------------

    def __getstate__(self):
        """Pickled with its residuals as their texts (compiled again where it is unpickled: a Dask worker)."""
        return {**super().__getstate__(), "_complex": []}

    def residual(self, t, y, yp) -> np.ndarray:
        """``F(t, y, y')`` (n,)."""
        return np.asarray(self._F(t, *y, *yp), dtype=float).reshape(self._n)

    def partials(self, t, y, yp):
        """``(dF/dy, dF/dy')`` at ``(t, y, y')``, exact to rounding (complex step, one vectorised call)."""
        if not self._complex:
            texts, args, params, keys, source = self._complex_recipe
            self._complex.append(compile_vector(texts, args=args, constants=params, keys=keys, source=source,
                                                complex_step=True))
        n = self._n
        steps = 1j * _H * np.eye(n)
        zeros = np.zeros((n, n))
        Y = np.asarray(y, dtype=float)[:, None] + np.hstack([steps, zeros])  # columns 0..n-1 perturb y
        YP = np.asarray(yp, dtype=float)[:, None] + np.hstack([zeros, steps])  # columns n..2n-1 perturb y'
        out = self._complex[0](complex(t), *Y, *YP)
        rows = [np.broadcast_to(np.asarray(row, dtype=complex), (2 * n,)) for row in out]
        J = np.vstack(rows).imag / _H
        return J[:, :n].copy(), J[:, n:].copy()

    # --- the start ------------------------------------------------------------------------------

    def with_start(self, t0: float, y0, yp0, fixed_y0=None, fixed_yp0=None) -> "ImplicitSystem":
        """This system carrying consistent initial values (``F(t0, y0, yp0) = 0``) and which
        components decic may change at a restart (an event's reset): a shallow copy."""
        other = copy.copy(self)
        other.t0, other.y0, other.yp0 = float(t0), np.array(y0, dtype=float), np.array(yp0, dtype=float)
        other.fixed_y0 = None if fixed_y0 is None else np.array(fixed_y0, dtype=int)
        other.fixed_yp0 = None if fixed_yp0 is None else np.array(fixed_yp0, dtype=int)
        return other

    def start(self, t0: float, y0, rtol=DEFAULT_RTOL, atol=DEFAULT_ATOL):
        """Consistent ``(y0, yp0)`` to start at ``(t0, y0)``: the carried ones when they are these, else
        decic's from the carried slope (a restart after an event's reset moves the states)."""
        y0 = np.asarray(y0, dtype=float)
        if self.yp0 is None:
            raise InputError("this implicit system has no initial slope: give der() values in [initial] (or call "
                             "odelab.decic), then odelab.ode15i(system.residual, tspan, y0, yp0).", key="fun")
        if self.t0 == float(t0) and np.array_equal(self.y0, y0):
            return self.y0, self.yp0
        from odelab.solvers.implicit.decic import decic

        fixed = self.fixed_y0 if self.fixed_y0 is not None else np.ones(self._n, dtype=int)
        y, yp, _ = decic(self.residual, t0, y0, fixed, self.yp0, self.fixed_yp0,
                         {"RelTol": rtol, "AbsTol": atol, "Jacobian": self.partials})
        return y, yp

    def __call__(self, t, y):
        raise InputError("this system is fully implicit (der() in [system.residuals]): it is solved by ode15i, from "
                         "y and y' together; use method = \"ode15i\".", key="fun")

    def describe(self) -> str:
        algebraic = [s for s in self.states if s not in self.differential]
        extra = f", algebraic: {', '.join(algebraic)}" if algebraic else ""
        return f"fully implicit: {len(self.names)} residual{'s' if len(self.names) != 1 else ''} F(t, x, x') = 0{extra}"
