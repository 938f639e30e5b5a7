"""Delay equations from expressions: ``lag(x, tau)`` in ``[system.equations]``, solved by dde23.

``lag(x, tau)`` is the state ``x`` at ``t - tau``, for a constant ``tau > 0`` (a number or an
expression of the parameters). :class:`DelayEquations` turns the equations of an experiment
file into what :func:`odelab.dde23` takes: the lags (one per distinct value, in the order they
first appear), ``ddefun(t, y, Z)`` (each ``lag(x, tau)`` reads ``Z[x, tau's column]``) and the
history (a number or an expression of ``t`` per state, ``[history]``; a state without one keeps
its initial value for ``t <= t0``).

The rewriting works on the parsed tree: every ``lag(x, tau)`` becomes a plain name bound to its
column of ``Z``, so the equations compile to the same generated numpy function as any other
equations (:func:`odelab.expressions.compile_vector`). Neutral equations (a delayed
derivative) and lags that depend on the state or on time are refused, with the reason.
"""

from __future__ import annotations

import ast
import difflib
import math
from collections.abc import Mapping

import numpy as np

from odelab.exceptions import ExpressionError, InputError
from odelab.expressions import compile_expression, compile_vector
from odelab.expressions.compile import PortableState, _unknown_name_error
from odelab.expressions.parse import LAG, parse_expression
from odelab.solvers.registry import DELAY_METHOD

__all__ = ["DelayEquations", "uses_lag"]


def uses_lag(texts) -> bool:
    """Whether any of the expressions ``texts`` calls ``lag(...)`` (a cheap test before parsing)."""
    return any(isinstance(t, str) and LAG + "(" in t.replace(" ", "") for t in texts)


def _lag_calls(tree: ast.AST) -> list[ast.Call]:
    return [node for node in ast.walk(tree)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == LAG]


class DelayEquations(PortableState):
    """``x' = f(t, x, x(t - tau_1), ...)`` from expressions with ``lag(x, tau)``.

    Parameters
    ----------
    equations
        State name -> expression of its derivative (in ``t``, the states, the parameters and
        ``lag(state, tau)``), in the order of the states.
    parameters
        Constants the expressions and the lags may use.
    history
        State name -> a number or an expression of ``t`` (and the parameters): the solution for
        ``t <= t0``. States not listed keep their initial value there.
    source
        The experiment file, for messages (keys ``system.equations.<state>``, ``history.<state>``).

    Attributes
    ----------
    states, lags
        The state names and the distinct lags (floats, in order of first appearance).
    terms
        One ``(state, tau)`` per distinct ``lag(...)`` term.
    """

    #: What :func:`odelab.solve` runs for this system (any other method is refused, naming it).
    method = DELAY_METHOD

    def __init__(self, equations: Mapping[str, object], *, parameters: Mapping[str, float] | None = None,
                 history: Mapping[str, object] | None = None, source: str | None = None):
        params = {k: float(v) for k, v in (parameters or {}).items()}
        self.states = tuple(equations)
        states = self.states
        index = {s: i for i, s in enumerate(states)}
        lags: list[float] = []
        terms: list[tuple[str, float]] = []
        names: dict[tuple[int, int], str] = {}
        used = set(states) | set(params) | {"t"}
        texts = []
        keys = []
        for s in states:
            key = f"system.equations.{s}"
            keys.append(key)
            known = ["t", *states, *params]
            parsed = parse_expression(equations[s], key=key, source=source, names=known)
            error = _unknown_name_error(parsed, known, key, source)
            if error is not None:
                raise error
            tree = parsed.tree
            used |= set(parsed.names)
            for call in _lag_calls(tree):
                target, tau_node = call.args
                column = parsed.column(call.col_offset)
                if _lag_calls(tau_node) or _lag_calls(target):
                    raise ExpressionError("a lag inside a lag (`lag(lag(x, a), b)`) is `lag(x, a + b)`: write it so",
                                          expression=parsed.text, column=column, source=source, key=key)
                if not (isinstance(target, ast.Name) and target.id in index):
                    raise ExpressionError(
                        f"the first argument of `lag` is a state ({', '.join(states)}): `lag(x, tau)` is x at "
                        "t - tau; a delayed expression is the expression of delayed states "
                        "(`lag(x, 1) + lag(v, 1)`, not `lag(x + v, 1)`)",
                        expression=parsed.text, column=parsed.column(target.col_offset), source=source, key=key)
                tau_text = ast.unparse(tau_node)
                tau_names = {n.id for n in ast.walk(tau_node) if isinstance(n, ast.Name)}
                moving = sorted(tau_names & ({"t"} | set(states)))
                if moving:
                    raise ExpressionError(
                        f"the lag `{tau_text}` depends on {moving[0]}: odelab's dde23 takes constant lags only (a "
                        "number or an expression of the parameters); a state-dependent lag needs MATLAB's ddesd",
                        expression=parsed.text, column=parsed.column(tau_node.col_offset), source=source, key=key)
                try:
                    tau = float(compile_expression(tau_text, names=list(params), key=key, source=source)(**params))
                except ExpressionError as exc:
                    raise ExpressionError(f"the lag `{tau_text}`: {exc.message}", expression=parsed.text,
                                          column=parsed.column(tau_node.col_offset), source=source, key=key) from None
                if not (math.isfinite(tau) and tau > 0):
                    raise ExpressionError(
                        f"the lag `{tau_text}` is {tau:g}; a lag must be a positive constant (the state now is "
                        f"`{target.id}` itself, not `lag({target.id}, 0)`)",
                        expression=parsed.text, column=parsed.column(tau_node.col_offset), source=source, key=key)
                j = next((k for k, v in enumerate(lags) if v == tau), None)
                if j is None:
                    lags.append(tau)
                    j = len(lags) - 1
                pair = (index[target.id], j)
                if pair not in names:
                    base = f"lag{len(names)}_{target.id}"
                    while base in used:
                        base += "_"
                    used.add(base)
                    names[pair] = base
                    terms.append((target.id, tau))
                replacement = ast.Name(id=names[pair], ctx=ast.Load())
                ast.copy_location(replacement, call)
                _replace(tree, call, replacement)
            texts.append(ast.unparse(tree))
        self.lags = np.array(lags, dtype=float)
        self.terms = tuple(terms)
        self.equations = {s: str(equations[s]) for s in states}
        pairs = list(names)
        self._rows = np.array([p[0] for p in pairs], dtype=np.intp)
        self._cols = np.array([p[1] for p in pairs], dtype=np.intp)
        self._F = compile_vector(texts, args=["t", *states, *names.values()], constants=params, keys=keys,
                                 source=source)
        self._n = len(states)

        self.history_texts: dict[str, str] = {}
        self._history = []
        history = dict(history or {})
        for name in history:
            if name not in index:
                close = difflib.get_close_matches(name, states, n=1)
                hint = f" Did you mean {close[0]!r}?" if close else ""
                raise InputError(f"`history.{name}`: {name!r} is not a state ({', '.join(states)}).{hint}",
                                 source=source, key=f"history.{name}")
        for s in states:
            if s in history:
                text = history[s]
                fn = compile_expression(text, names=["t", *params], key=f"history.{s}", source=source)
                self._history.append((index[s], fn))
                self.history_texts[s] = str(text)
        self._params = params

    def ddefun(self, t, y, Z):
        """dy/dt at ``t`` for the state ``y`` (n,) and the delayed states ``Z`` (n, k)."""
        return self._F(t, *y, *Z[self._rows, self._cols])

    def history(self, y0: np.ndarray):
        """The history for an initial state ``y0``: a constant vector when no state has a
        ``[history]`` expression, else ``history(t)``; and whether ``y0`` differs from it at ``t0``."""
        y0 = np.asarray(y0, dtype=float)
        if not self._history:
            return y0.copy()
        params = self._params
        entries = list(self._history)

        def history(t):
            values = y0.copy()
            for i, fn in entries:
                values[i] = float(fn(t=t, **params))
            return values

        return history

    def __call__(self, t, y):
        raise InputError("this system has delayed states (lag(...) in its equations): it is solved by dde23, "
                         "which gives the delayed values; use method = \"dde23\".", key="fun")

    def describe(self) -> str:
        """One line: the lags and the delayed states."""
        terms = ", ".join(f"{s}(t - {tau:g})" for s, tau in self.terms)
        return f"delay equations: {terms}"


def _replace(tree: ast.AST, old: ast.AST, new: ast.AST) -> None:
    """Replace the node ``old`` by ``new`` in ``tree`` (wherever it is a child)."""
    for parent in ast.walk(tree):
        for field, value in ast.iter_fields(parent):
            if value is old:
                setattr(parent, field, new)
                return
            if isinstance(value, list):
                for i, item in enumerate(value):
                    if item is old:
                        value[i] = new
                        return
