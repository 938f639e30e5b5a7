"""The syntax tree of the MATLAB subset odelab reads: expressions, statements, functions and files.

Every node records its line; an expression also records how deep its subtree is (``depth``),
checked against :data:`MAX_DEPTH` as the parser builds it, so everything that walks the tree
later (the evaluator, the translator) recurses a bounded number of times.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["MAX_DEPTH", "Expr", "Num", "Str", "Id", "EndIndex", "Colon", "Binary", "Unary", "Postfix", "Index",
           "Field", "DynField", "Matrix", "Range", "AnonFn", "FuncHandle", "Stmt", "Assign", "ExprStmt", "Command",
           "If", "For", "While", "Switch", "Break", "Continue", "Return", "Global", "TryCatch", "Arguments", "Function",
           "SourceFile", "Tilde"]

MAX_DEPTH = 120
"""The deepest expression tree odelab reads (a chain ``a + b + c ...`` adds a level per term)."""


@dataclass(eq=False, slots=True)
class Expr:
    line: int
    depth: int = field(default=1, kw_only=True)


@dataclass(eq=False, slots=True)
class Num(Expr):
    value: float
    text: str
    imaginary: bool = False


@dataclass(eq=False, slots=True)
class Str(Expr):
    value: str
    double: bool = False  # "..." (a MATLAB string) rather than '...' (a char array)


@dataclass(eq=False, slots=True)
class Id(Expr):
    name: str


@dataclass(eq=False, slots=True)
class EndIndex(Expr):
    """``end`` inside an index: the last index of that dimension."""


@dataclass(eq=False, slots=True)
class Colon(Expr):
    """``:`` alone as an index: every element of that dimension."""


@dataclass(eq=False, slots=True)
class Tilde(Expr):
    """``~`` as an output placeholder: ``[~, y] = ode45(...)``."""


@dataclass(eq=False, slots=True)
class Binary(Expr):
    op: str  # + - * / \ ^ .* ./ .\ .^ == ~= < <= > >= & | && ||
    left: Expr
    right: Expr


@dataclass(eq=False, slots=True)
class Unary(Expr):
    op: str  # - + ~
    operand: Expr


@dataclass(eq=False, slots=True)
class Postfix(Expr):
    op: str  # ' or .'
    operand: Expr


@dataclass(eq=False, slots=True)
class Index(Expr):
    """``a(i, j)`` (a call or an index: MATLAB's syntax does not tell them apart) or ``c{i}``."""

    target: Expr
    args: list[Expr]
    brace: bool = False


@dataclass(eq=False, slots=True)
class Field(Expr):
    target: Expr
    name: str


@dataclass(eq=False, slots=True)
class DynField(Expr):
    target: Expr
    name: Expr


@dataclass(eq=False, slots=True)
class Matrix(Expr):
    rows: list[list[Expr]]
    cell: bool = False


@dataclass(eq=False, slots=True)
class Range(Expr):
    start: Expr
    step: Expr | None
    stop: Expr


@dataclass(eq=False, slots=True)
class AnonFn(Expr):
    params: list[str]
    body: Expr
    text: str = ""  # the source text, for notes


@dataclass(eq=False, slots=True)
class FuncHandle(Expr):
    name: str


@dataclass(eq=False, slots=True)
class Stmt:
    line: int
    text: str = field(default="", kw_only=True)  # the statement's source (its first line), for notes


@dataclass(eq=False, slots=True)
class Assign(Stmt):
    targets: list[Expr]  # Id, Index, Field chains, Tilde
    value: Expr
    multi: bool = False  # [a, b] = ...


@dataclass(eq=False, slots=True)
class ExprStmt(Stmt):
    expr: Expr


@dataclass(eq=False, slots=True)
class Command(Stmt):
    """Command syntax: ``hold on``, ``format long``, ``clear all``."""

    name: str
    words: tuple[str, ...]


@dataclass(eq=False, slots=True)
class If(Stmt):
    clauses: list[tuple[Expr, list[Stmt]]]
    orelse: list[Stmt] | None = None


@dataclass(eq=False, slots=True)
class For(Stmt):
    var: Expr
    iterable: Expr
    body: list[Stmt]


@dataclass(eq=False, slots=True)
class While(Stmt):
    cond: Expr
    body: list[Stmt]


@dataclass(eq=False, slots=True)
class Switch(Stmt):
    subject: Expr
    cases: list[tuple[Expr, list[Stmt]]]
    otherwise: list[Stmt] | None = None


@dataclass(eq=False, slots=True)
class Break(Stmt):
    pass


@dataclass(eq=False, slots=True)
class Continue(Stmt):
    pass


@dataclass(eq=False, slots=True)
class Return(Stmt):
    pass


@dataclass(eq=False, slots=True)
class Global(Stmt):
    names: list[str]
    persistent: bool = False


@dataclass(eq=False, slots=True)
class Arguments(Stmt):
    """A function's ``arguments ... end`` block: each argument and its default (None: required)."""

    entries: list[tuple[Expr, Expr | None]]


@dataclass(eq=False, slots=True)
class TryCatch(Stmt):
    body: list[Stmt]
    handler: list[Stmt]


@dataclass(eq=False, slots=True)
class Function:
    name: str
    inputs: list[str]
    outputs: list[str]
    body: list[Stmt]
    line: int
    nested: list["Function"] = field(default_factory=list)
    parent: "Function | None" = field(default=None, repr=False)
    file: str = ""


@dataclass(eq=False, slots=True)
class SourceFile:
    """A parsed ``.m`` file: a script (statements, maybe local functions) or a function file."""

    path: str
    script: list[Stmt] | None  # None for a function file
    functions: list[Function]
    lines: list[str] = field(default_factory=list, repr=False)

    @property
    def main(self) -> Function | None:
        return self.functions[0] if self.script is None and self.functions else None

    def function(self, name: str) -> Function | None:
        for fn in self.functions:
            if fn.name == name:
                return fn
        return None
