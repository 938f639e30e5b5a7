"""The expression signal: u = an expression of t and the parameters, as an experiment file
writes it."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from odelab.signals.base import Function, SignalContext, SignalKey


@dataclass(frozen=True, repr=False)
class Expression(Function):
    """u = an expression of t and the parameters, as an experiment file writes it (``type = "expression"``).

    ``text``, ``key`` and ``params`` are the checked expression, its key path and the
    parameter values it was compiled with: the compiled backend generates it from them.
    """

    TOML: ClassVar[str] = "expression"
    KEYS: ClassVar[Mapping[str, SignalKey]] = {"expression": SignalKey(None, kind="expression", unit="u")}

    text: str = ""
    key: str = ""
    params: Mapping[str, float] | None = None

    @classmethod
    def from_toml(cls, values: Mapping[str, Any], ctx: SignalContext) -> Expression:
        from odelab import expressions

        params = dict(ctx.params)
        text = str(values["expression"])
        compiled = expressions.compile_expression(values["expression"], names=["t", *params],
                                                  key=f"{ctx.key}.expression")

        def expression_signal(t, _e=compiled, _p=params):
            return _e(t=t, **_p)

        return cls(expression_signal, label=text, text=text, key=f"{ctx.key}.expression", params=params)

    @classmethod
    def describe(cls, name: str, values: Mapping[str, Any]) -> str:
        return f"{name} = {values.get('expression')}"

    def compiled_reason(self) -> str | None:
        return None

    def numba_source(self, slot) -> str:
        from odelab.expressions import parse_expression
        from odelab.solvers.compiled.codegen import expression_source

        params = dict(self.params or {})
        parsed = parse_expression(self.text, key=self.key, names=["t", *params])  # a parameter `e` shadows e
        used = [name for name in params if name in set(parsed.names)]
        rename = {"t": "_tu", **dict(zip(used, slot(*(params[name] for name in used))))}
        return f"({expression_source(parsed, rename)})"


