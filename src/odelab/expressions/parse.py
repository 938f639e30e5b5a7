"""Reading and validating expressions: character checks, MATLAB-operator translation, the
AST whitelist, :func:`parse_expression` and its error messages."""

from __future__ import annotations

import ast
import difflib
import io
import keyword
import math
import numbers
import re
import tokenize
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from odelab.exceptions import ExpressionError
from odelab.expressions.functions import (
    _ARITY,
    _BINARY,
    _COMPARATORS,
    _FUNCTION_LIST,
    _UNARY,
    CONSTANTS,
    FUNCTIONS,
    shadowed_constants,
)

#: Longest accepted expression, in characters; longer text is rejected before parsing.
MAX_LENGTH = 2000

#: Deepest accepted nesting, counted in brackets and, separately, in levels of the syntax tree
#: (each operator of a chain such as ``a+b+c`` adds a level). Python's own parser and compiler
#: recurse on the tree, so this keeps them far from ``RecursionError``.
MAX_DEPTH = 200

# Brackets are limited more tightly than tree levels: CPython's tokenizer refuses 200 levels.
_MAX_BRACKETS = 100

#: ``lag(x, tau)``, a delayed state: parsed here, given meaning only in [system.equations] by
#: :mod:`odelab.systems.delay` (compiling it anywhere else is refused, see compile.py).
LAG = "lag"

#: ``der(x)``, a state's derivative x': parsed here, given meaning only in [system.residuals] of a
#: fully implicit system by :mod:`odelab.systems.implicit` (refused anywhere else, see compile.py).
DER = "der"


# --------------------------------------------------------------------------------------------
# Parsing and validation
# --------------------------------------------------------------------------------------------

_LOGIC_HINT = (
    "combine conditions with a chained comparison (`0 < t < 1`), a product "
    "(`(t > 1)*(x < 0)`) or `where(cond, a, b)`"
)
_LOOKALIKES = {
    "\u2212": "-",
    "\u2013": "-",
    "\u00d7": "*",
    "\u00b7": "*",
    "\u22c5": "*",
    "\u00f7": "/",
    "\u03c0": "pi",
    "\u2264": "<=",
    "\u2265": ">=",
    "\u2260": "!=",
}
_BAD_CHARACTER = re.compile(r"[^\t\n\r\x20-\x7e]")
_MATLAB_LOGIC = re.compile(r"&&|\|\|")
_MATLAB_ELEMENTWISE = re.compile(r"\.[\^*/]")
_NAME_RUN = re.compile(r"[A-Za-z0-9_]*\Z")

_FORBIDDEN_NODES: dict[type, str] = {
    ast.Attribute: "attribute access (`.`) is not allowed in expressions",
    ast.Subscript: "indexing (`[...]`) is not allowed in expressions",
    ast.Slice: "indexing (`[...]`) is not allowed in expressions",
    ast.Lambda: "lambda functions are not allowed in expressions",
    ast.ListComp: "comprehensions (`... for ... in ...`) are not allowed in expressions",
    ast.SetComp: "comprehensions (`... for ... in ...`) are not allowed in expressions",
    ast.DictComp: "comprehensions (`... for ... in ...`) are not allowed in expressions",
    ast.GeneratorExp: "comprehensions (`... for ... in ...`) are not allowed in expressions",
    ast.List: "lists (`[...]`) are not allowed in expressions; an expression is one value",
    ast.Tuple: "tuples (`,`) are not allowed in expressions; an expression is one value",
    ast.Set: "sets (`{...}`) are not allowed in expressions",
    ast.Dict: "dicts (`{...}`) are not allowed in expressions",
    ast.JoinedStr: "f-strings are not allowed in expressions",
    ast.FormattedValue: "f-strings are not allowed in expressions",
    ast.NamedExpr: "assignments (`:=`) are not allowed in expressions",
    ast.IfExp: "conditional expressions (`a if c else b`) are not allowed; write `where(c, a, b)`",
    ast.BoolOp: f"`and`/`or` are not allowed; {_LOGIC_HINT}",
    ast.Starred: "starred arguments (`*`) are not allowed in expressions",
    ast.Await: "`await` is not allowed in expressions",
    ast.Yield: "`yield` is not allowed in expressions",
    ast.YieldFrom: "`yield` is not allowed in expressions",
}
_FORBIDDEN_OPERATORS: dict[type, str] = {
    ast.Mod: "`%`",
    ast.FloorDiv: "`//`",
    ast.MatMult: "`@`",
    ast.BitAnd: "`&`",
    ast.BitOr: "`|`",
    ast.BitXor: "`^`",
    ast.LShift: "`<<`",
    ast.RShift: "`>>`",
}


@dataclass(frozen=True)
class ParsedExpression:
    """A syntactically valid expression of the language, not yet bound to names.

    Attributes
    ----------
    text
        The expression as the user wrote it.
    names
        The free names it uses: variables, excluding the constants and the functions. A
        constant that a file's own names shadow (a parameter ``e``) is a free name of the
        expression :meth:`binding` returns.
    constants
        The constants it names that are still constants (``pi``, ``e``).
    tree
        Its :class:`ast.Expression`; ``^`` is already ``**`` there, and column offsets refer to
        that translated text (map them with :meth:`column`).
    key, source
        Where the text came from (TOML key path and file), used in later errors.
    """

    text: str
    names: frozenset[str]
    tree: ast.Expression = field(repr=False, compare=False)
    key: str | None = field(default=None, repr=False, compare=False)
    source: str | None = field(default=None, repr=False, compare=False)
    # first occurrence of each free name, in source order: (name, offset in the translated text)
    _occurrences: tuple[tuple[str, int], ...] = field(default=(), repr=False, compare=False)
    _columns: tuple[int, ...] = field(default=(0,), repr=False, compare=False)
    _depth: int = field(default=1, repr=False, compare=False)
    constants: frozenset[str] = field(default=frozenset(), repr=False, compare=False)
    _constant_occurrences: tuple[tuple[str, int], ...] = field(default=(), repr=False, compare=False)

    def binding(self, names) -> "ParsedExpression":
        """This expression where ``names`` (the names bound where it is used: states,
        parameters...) are known: a constant they shadow (:func:`shadowed_constants`) is a free
        name, as a MATLAB variable ``e`` or ``pi`` is. Without shadowing, ``self``."""
        shadowed = shadowed_constants(names) & self.constants if self.constants else frozenset()
        if not shadowed:
            return self
        occurrences = [*self._occurrences, *((n, o) for n, o in self._constant_occurrences if n in shadowed)]
        occurrences.sort(key=lambda item: item[1])
        return replace(self, names=self.names | shadowed, constants=self.constants - shadowed,
                       _occurrences=tuple(occurrences),
                       _constant_occurrences=tuple((n, o) for n, o in self._constant_occurrences
                                                   if n not in shadowed))

    def column(self, offset: int) -> int:
        """The column in :attr:`text` of an offset into the translated (``**``) text."""
        return self._columns[max(0, min(offset, len(self._columns) - 1))]


class _Reader:
    """The text being parsed, its Python translation and the map back to user columns."""

    def __init__(self, text: str, key: str | None, source: str | None):
        self.text = text
        self.key = key
        self.source = source
        self.python = text
        self.columns: list[int] = list(range(len(text) + 1))

    def error(self, message: str, offset: int | None = None, *, column: int | None = None):
        if offset is not None:
            column = self.columns[max(0, min(offset, len(self.columns) - 1))]
        return ExpressionError(
            message, expression=self.text, column=column, source=self.source, key=self.key
        )

    def after(self, offset: int) -> int:
        """The offset of the first token after ``offset`` that is not a space or ``)``."""
        python = self.python
        while offset < len(python) and python[offset] in " )":
            offset += 1
        return offset


def _as_text(value: Any, key: str | None, source: str | None) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, (bool, np.bool_)):
        raise ExpressionError(
            f"booleans are not numbers; got {str(value).lower()}; write 1 or 0",
            expression=str(value).lower(),
            column=0,
            source=source,
            key=key,
        )
    if isinstance(value, numbers.Integral):
        try:
            return repr(int(value))
        except ValueError:  # more digits than Python converts to text
            raise ExpressionError(
                f"the integer is too long; an expression has at most {MAX_LENGTH} characters",
                expression="<integer>",
                column=None,
                source=source,
                key=key,
            ) from None
    if isinstance(value, numbers.Real):
        number = float(value)
        if not math.isfinite(number):
            raise ExpressionError(
                f"a number in an expression must be finite; got {number}",
                expression=str(number),
                column=0,
                source=source,
                key=key,
            )
        return repr(number)
    description = f"{type(value).__name__} {value!r}"
    raise ExpressionError(
        f"an expression must be a string or a number; got {description[:80]}",
        expression=repr(value)[:200],
        column=None,
        source=source,
        key=key,
    )


def _check_characters(reader: _Reader) -> None:
    text = reader.text
    if len(text) > MAX_LENGTH:
        raise reader.error(
            f"expression is {len(text)} characters long; the limit is {MAX_LENGTH}. "
            "Split it into parameters or outputs",
            column=MAX_LENGTH,
        )
    bad = _BAD_CHARACTER.search(text)
    if bad:
        ch = bad.group()
        if ord(ch) < 128:
            message = f"control character U+{ord(ch):04X} is not allowed in expressions"
        else:
            message = f"character `{ch}` (U+{ord(ch):04X}) is not allowed; expressions are ASCII"
            if ch in _LOOKALIKES:
                message += f"; write `{_LOOKALIKES[ch]}`"
        raise reader.error(message, column=bad.start())
    if not text.strip():
        raise reader.error("empty expression; write a number or a formula such as `-k*x`", column=0)

    if "~=" in text:
        raise reader.error("`~=` is MATLAB's not-equal; write `!=`", column=text.index("~="))
    logic = _MATLAB_LOGIC.search(text)
    if logic:
        raise reader.error(f"`{logic.group()}` is not supported; {_LOGIC_HINT}", column=logic.start())
    for match in _MATLAB_ELEMENTWISE.finditer(text):
        # `x.^2` is MATLAB; `2.*x` is the number `2.` times x in both languages
        before = text[: match.start()]
        run = _NAME_RUN.search(before).group()
        if before.endswith((")", "]")) or (run and not run[0].isdigit()):
            op = match.group()
            raise reader.error(
                f"`{op}` is MATLAB's elementwise operator; write `{op[1:]}` "
                "(every operation here is elementwise)",
                column=match.start(),
            )

    depth = 0
    for i, ch in enumerate(text):
        if ch in "([{":
            depth += 1
            if depth > _MAX_BRACKETS:
                raise reader.error(
                    f"brackets are nested more than {_MAX_BRACKETS} deep; "
                    "simplify the expression or split it into parameters",
                    column=i,
                )
        elif ch in ")]}":
            depth = max(0, depth - 1)


def _translate(reader: _Reader) -> set[int]:
    """Turn the text into Python: ``^`` becomes ``**``; return the offsets of those ``**``.

    The replacement is made on tokens (a ``^`` inside a string stays as it is, to be rejected
    with the string) and keeps a map from offsets in the Python text to the user's columns.
    """
    # tabs and line breaks (TOML multi-line strings) are spaces; leading spaces would be an
    # "unexpected indent" to Python
    flat = reader.text.translate({9: " ", 10: " ", 13: " "})
    start = len(flat) - len(flat.lstrip(" "))
    body = flat[start:]
    carets: set[int] = set()
    try:
        for token in tokenize.generate_tokens(io.StringIO(body).readline):
            if token.type == tokenize.OP and token.string == "^":
                carets.add(token.start[1])
            elif token.type == tokenize.COMMENT:
                raise reader.error(
                    "comments (`#`) are not allowed in expressions", column=start + token.start[1]
                )
    except (tokenize.TokenError, SyntaxError):
        pass  # unbalanced brackets or a bad token: the parser reports it, with its position

    pieces: list[str] = []
    columns: list[int] = []
    translated: set[int] = set()
    for i, ch in enumerate(body):
        if i in carets:
            translated.add(len(columns))
            pieces.append("**")
            columns += [start + i, start + i]
        else:
            pieces.append(ch)
            columns.append(start + i)
    columns.append(len(reader.text))
    reader.python = "".join(pieces)
    reader.columns = columns
    return translated


def _parse_tree(reader: _Reader) -> ast.Expression:
    python = reader.python
    try:
        with warnings.catch_warnings():
            # e.g. "'int' object is not callable" for `2(x+1)`, reported as an error below;
            # the core never prints
            warnings.simplefilter("ignore")
            return ast.parse(python, mode="eval")
    except SyntaxError as exc:
        if exc.lineno in (None, 1) and exc.offset and exc.offset > 0:
            offset = exc.offset - 1
        else:  # at the end of the text
            offset = len(python)
        from odelab.expressions.matlab import syntax_hint

        hint = syntax_hint(reader.text, reader.key)
        if hint is not None:  # a MATLAB habit: say what to write instead of Python's message
            raise reader.error(hint, column=0) from None
        raise reader.error(f"syntax error: {_plain_syntax(exc.msg, reader.text)}", offset) from None
    except (RecursionError, MemoryError):
        raise reader.error(_too_deep_message(), column=0) from None


# Python's parser messages, in the expression language's words (no Python term reaches a user).
_SYNTAX_WORDS = (
    ("was never closed", "a bracket is opened here and never closed: add the closing bracket"),
    ("unmatched", "a closing bracket with no opening one"),
    ("does not match opening parenthesis", "the brackets do not match: each ( needs a ), each [ a ]"),
    ("invalid decimal literal", "a number runs into a name: write `2*x`, not `2x`"),
    ("leading zeros", "a number cannot start with 0 (write 7, not 007)"),
    ("forgot a comma", "two values stand side by side: put an operator between them (`a*b`, not `a b`)"),
    ("invalid character", "this character is not part of the expression language (use + - * / ^ and ASCII names)"),
    ("unexpected EOF", "the expression ends too early: an operand is missing at the end"),
    ("invalid syntax", "an operator or an operand is missing or out of place here"),
)


def _plain_syntax(message: str, text: str) -> str:
    """What Python's ``SyntaxError`` message means, said without Python's words."""
    if "string literal" in message or "unterminated" in message:
        if "'" in text:
            return ("a quote or prime (') is not part of the expression language: a derivative is the equation's "
                    "left-hand side (under [system.equations], `y = \"...\"` is dy/dt), and the transpose of a "
                    "matrix is written out")
        return "text in quotes is not allowed inside an expression"
    for fragment, words in _SYNTAX_WORDS:
        if fragment in message:
            return words
    return "this is not a valid expression"


def _too_deep_message() -> str:
    return (
        f"expression is nested too deeply (more than {MAX_DEPTH} levels; each bracket, call and "
        "operator of a chain such as `a+b+c` adds one); split it into parameters or outputs"
    )


def _measure_depth(reader: _Reader, tree: ast.Expression) -> int:
    deepest = 0
    stack: list[tuple[ast.AST, int]] = [(tree.body, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_DEPTH:
            if isinstance(node, ast.BinOp):  # point at the operator, not the chain's start
                offset = reader.after(node.left.end_col_offset)
            else:
                offset = getattr(node, "col_offset", 0)
            raise reader.error(_too_deep_message(), offset)
        deepest = max(deepest, depth)
        for child in reversed(list(ast.iter_child_nodes(node))):
            stack.append((child, depth + isinstance(child, ast.expr)))
    return deepest


def _did_you_mean(name: str, candidates: Iterable[str]) -> str:
    candidates = list(dict.fromkeys(candidates))
    same_but_case = [c for c in candidates if c.lower() == name.lower()]
    if same_but_case:
        return f"did you mean `{same_but_case[0]}`? (names are case-sensitive)"
    close = difflib.get_close_matches(name, candidates, n=1, cutoff=0.7)
    return f"did you mean `{close[0]}`?" if close else ""


def _forbidden_node_column(reader: _Reader, node: ast.AST) -> int:
    """Offset of the token that makes ``node`` forbidden (its `.`, `[`, `,`, `if`, `and`...)."""
    if isinstance(node, (ast.Attribute, ast.Subscript)):
        return reader.after(node.value.end_col_offset)
    if isinstance(node, ast.BoolOp):
        return reader.after(node.values[0].end_col_offset)
    if isinstance(node, ast.IfExp):
        return reader.after(node.body.end_col_offset)
    if isinstance(node, ast.Tuple) and node.elts:
        return reader.after(node.elts[0].end_col_offset)
    return getattr(node, "col_offset", 0)


def _check_call(reader: _Reader, node: ast.Call) -> list[ast.AST]:
    func = node.func
    if not isinstance(func, ast.Name):
        if type(func) in _FORBIDDEN_NODES:
            raise reader.error(_FORBIDDEN_NODES[type(func)], _forbidden_node_column(reader, func))
        paren = reader.after(func.end_col_offset)
        if isinstance(func, ast.Call):
            raise reader.error(
                "calling the result of a call (`f(x)(y)`) is not allowed", paren
            )
        raise reader.error(
            "only the listed functions can be called; to multiply, write `*` "
            "(e.g. `2*(x + 1)`, not `2(x + 1)`)",
            paren,
        )
    name = func.id
    if name == LAG and name not in FUNCTIONS:
        return _check_lag(reader, node)
    if name == DER and name not in FUNCTIONS:
        return _check_der(reader, node)
    if name not in FUNCTIONS:
        from odelab.expressions.matlab import indexing_hint

        matlab = indexing_hint(name, node.args)
        if matlab is not None:
            raise reader.error(matlab, func.col_offset)
        hint = _did_you_mean(name, FUNCTIONS)
        hint = f"{hint} Allowed: " if hint else "allowed: "
        raise reader.error(
            f"`{name}` is not an allowed function; {hint}{_FUNCTION_LIST}", func.col_offset
        )
    for argument in node.args:
        if isinstance(argument, ast.Starred):
            raise reader.error(_FORBIDDEN_NODES[ast.Starred], argument.col_offset)
    for kw in node.keywords:
        if kw.arg is None:
            raise reader.error("`**` unpacking is not allowed in function calls", kw.col_offset)
        raise reader.error(
            f"keyword arguments (`{kw.arg}=`) are not allowed; pass arguments by position",
            kw.col_offset,
        )
    arity, got = _ARITY[name], len(node.args)
    if isinstance(arity, tuple):
        if got < arity[0] or (arity[1] is not None and got > arity[1]):
            takes = f"{arity[0]} or more" if arity[1] is None else f"{arity[0]} or {arity[1]}"
            raise reader.error(f"`{name}` takes {takes} arguments; got {got}", func.col_offset)
    elif got != arity:
        plural = "argument" if arity == 1 else "arguments"
        what = " (condition, value if true, value if false)" if name == "where" else ""
        raise reader.error(f"`{name}` takes {arity} {plural}{what}; got {got}", func.col_offset)
    return list(node.args)


def _check_lag(reader: _Reader, node: ast.Call) -> list[ast.AST]:
    """``lag(x, tau)``: two positional arguments, the first a plain name (the delayed state)."""
    if node.keywords or len(node.args) != 2 or any(isinstance(a, ast.Starred) for a in node.args):
        raise reader.error(f"`lag` takes 2 arguments (a state and its lag), e.g. `lag(x, 0.5)`; got "
                           f"{len(node.args) + len(node.keywords)}", node.func.col_offset)
    if not isinstance(node.args[0], ast.Name):
        raise reader.error("the first argument of `lag` is a state name: `lag(x, tau)` is x at t - tau",
                           node.args[0].col_offset)
    return list(node.args)


def _check_der(reader: _Reader, node: ast.Call) -> list[ast.AST]:
    """``der(x)``: one positional argument, a plain name (the state whose derivative it is)."""
    if node.keywords or len(node.args) != 1 or any(isinstance(a, ast.Starred) for a in node.args):
        raise reader.error(f"`der` takes 1 argument (a state), e.g. `der(x)` for x'; got "
                           f"{len(node.args) + len(node.keywords)}", node.func.col_offset)
    argument = node.args[0]
    if (isinstance(argument, ast.Call) and isinstance(argument.func, ast.Name) and argument.func.id == DER):
        raise reader.error("`der(der(x))` is a second derivative; write the system in first order, with a state "
                           "for der(x) (v = der(x), then der(v))", node.func.col_offset)
    if not isinstance(argument, ast.Name):
        raise reader.error("the argument of `der` is a state name: `der(x)` is x' (the derivative of an expression "
                           "is the expression of the states' derivatives)", argument.col_offset)
    return list(node.args)


def _check_power(reader: _Reader, node: ast.BinOp, carets: set[int]) -> None:
    """Reject ``a^b^c`` (and ``a^-b^c``, ``a**b^c``): MATLAB and Python group them differently."""
    outer = reader.after(node.left.end_col_offset)
    right, start = node.right, outer + 2
    # operands are unparenthesised when no `(` lies between the operator and their first token
    while isinstance(right, ast.UnaryOp) and "(" not in reader.python[start : right.col_offset]:
        start, right = right.col_offset + 1, right.operand
    if not (isinstance(right, ast.BinOp) and isinstance(right.op, ast.Pow)):
        return
    if "(" in reader.python[start : right.col_offset]:
        return
    inner = reader.after(right.left.end_col_offset)
    if outer in carets or inner in carets:
        raise reader.error(
            "chained powers like `a^b^c` are ambiguous: MATLAB groups them left to right, "
            "Python right to left; add parentheses: `(a^b)^c` or `a^(b^c)`",
            outer if outer in carets else inner,
        )


def _is_dotted_name(node: ast.AST) -> bool:
    """``element.variable`` (``mass.x``, ``C1.v``): a plain name of two parts, neither starting
    with ``_`` nor a function or constant. It is one free name; nothing is ever looked up on
    an object (the compilers turn it into a plain identifier, see :func:`python_name`)."""
    return (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
            and not node.value.id.startswith("_") and not node.attr.startswith("_")
            and node.value.id not in FUNCTIONS and node.value.id not in CONSTANTS)


def python_name(name: str) -> str:
    """The Python identifier standing for a name in generated code: the name itself, or for a
    dotted name ``a.b`` the identifier ``_d<len(a)>_a_b`` (unique, and no user name starts
    with ``_``)."""
    head, dot, tail = name.partition(".")
    return f"_d{len(head)}_{head}_{tail}" if dot else name


def is_dotted_name(name: str) -> bool:
    """Whether ``name`` is a valid dotted name ``element.variable`` of the language."""
    head, dot, tail = name.partition(".") if isinstance(name, str) else ("", "", "")
    return bool(dot) and all(part.isascii() and part.isidentifier() and not part.startswith("_")
                             and not keyword.iskeyword(part) for part in (head, tail)) \
        and head not in FUNCTIONS and head not in CONSTANTS


def _validate(reader: _Reader, tree: ast.Expression, carets: set[int]):
    """Check every node against the whitelist, in source order; return the free names."""
    occurrences: dict[str, int] = {}
    constants: dict[str, int] = {}
    stack: list[ast.AST] = [tree.body]
    while stack:
        node = stack.pop()
        children: list[ast.AST] = []
        if isinstance(node, ast.Constant):
            value = node.value
            if isinstance(value, bool):
                message = "booleans (`True`/`False`) are not allowed; write 1 or 0"
            elif isinstance(value, (int, float)):
                message = ""
            elif isinstance(value, complex):
                message = "complex numbers (`1j`) are not allowed in expressions"
            elif isinstance(value, (str, bytes)):
                message = "strings are not allowed in expressions"
            elif value is None:
                message = "`None` is not allowed in expressions"
            elif value is Ellipsis:
                message = "`...` (Ellipsis) is not allowed in expressions"
            else:
                message = f"`{value!r}` is not allowed in expressions"
            if message:
                raise reader.error(message, node.col_offset)
        elif isinstance(node, ast.Name):
            name = node.id
            if name.startswith("_"):
                raise reader.error(
                    f"`{name}`: names starting with `_` are not allowed", node.col_offset
                )
            if name in FUNCTIONS:
                raise reader.error(f"`{name}` is a function; call it as `{name}(...)`", node.col_offset)
            if name not in CONSTANTS:
                occurrences.setdefault(name, node.col_offset)
            else:
                constants.setdefault(name, node.col_offset)
        elif _is_dotted_name(node):  # `mass.x`: one name, a network element's variable
            occurrences.setdefault(f"{node.value.id}.{node.attr}", node.col_offset)
        elif isinstance(node, ast.BinOp):
            if type(node.op) not in _BINARY:
                symbol = _FORBIDDEN_OPERATORS.get(type(node.op), "this operator")
                hint = f"; {_LOGIC_HINT}" if symbol in ("`&`", "`|`") else ""
                raise reader.error(
                    f"operator {symbol} is not allowed; the operators are "
                    f"+ - * / ^ ** < <= > >= == !={hint}",
                    reader.after(node.left.end_col_offset),
                )
            if isinstance(node.op, ast.Pow):
                _check_power(reader, node, carets)
            children = [node.left, node.right]
        elif isinstance(node, ast.UnaryOp):
            if type(node.op) not in _UNARY:
                symbol = "`not`" if isinstance(node.op, ast.Not) else "`~`"
                raise reader.error(f"{symbol} is not allowed; {_LOGIC_HINT}", node.col_offset)
            children = [node.operand]
        elif isinstance(node, ast.Compare):
            left = node.left
            for op, right in zip(node.ops, node.comparators):
                if type(op) not in _COMPARATORS:
                    raise reader.error(
                        "`is` and `in` are not allowed; compare with < <= > >= == !=",
                        reader.after(left.end_col_offset),
                    )
                left = right
            children = [node.left, *node.comparators]
        elif isinstance(node, ast.Call):
            children = _check_call(reader, node)
        else:
            message = _FORBIDDEN_NODES.get(
                type(node), f"`{type(node).__name__}` is not allowed in expressions"
            )
            raise reader.error(message, _forbidden_node_column(reader, node))
        stack.extend(reversed(children))
    return occurrences, constants


def parse_expression(
    text: str | int | float | ParsedExpression,
    *,
    key: str | None = None,
    source: str | None = None,
    names=None,
) -> ParsedExpression:
    """Parse and validate an expression of the language.

    Parameters
    ----------
    text
        The expression, e.g. ``"-k/m*x^3"``; a number (a TOML integer or float) is accepted as
        the constant expression it denotes. A :class:`ParsedExpression` is returned unchanged.
    key
        The TOML key path the text came from (``system.equations.x``), for error messages.
    source
        The file the text came from, for error messages.
    names
        The names bound where the expression is used, if known: the result is
        :meth:`ParsedExpression.binding` of them (a parameter ``e`` shadows the constant).

    Returns
    -------
    ParsedExpression
        The text, its free names and its syntax tree.

    Raises
    ------
    ExpressionError
        If the text is too long, nested too deeply, not valid syntax, or uses anything outside
        the language; the error carries the 0-based column of the offending part.
    """
    if isinstance(text, ParsedExpression):
        return text if names is None else text.binding(names)
    reader = _Reader(_as_text(text, key, source), key, source)
    _check_characters(reader)
    carets = _translate(reader)
    tree = _parse_tree(reader)
    depth = _measure_depth(reader, tree)
    occurrences, constants = _validate(reader, tree, carets)
    parsed = ParsedExpression(
        text=reader.text,
        names=frozenset(occurrences),
        tree=tree,
        key=key,
        source=source,
        _occurrences=tuple(occurrences.items()),
        _columns=tuple(reader.columns),
        _depth=depth,
        constants=frozenset(constants),
        _constant_occurrences=tuple(constants.items()),
    )
    return parsed if names is None else parsed.binding(names)
