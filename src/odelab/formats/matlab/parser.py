"""MATLAB tokens to a syntax tree (:mod:`.nodes`): scripts, function files, local and nested functions.

A recursive-descent parser with precedence climbing (MATLAB's operator precedence, lowest
first: ``||``, ``&&``, ``|``, ``&``, comparisons, ``:``, ``+ -``, ``* / \\ .* ./ .\\``, unary
``- + ~``, ``^ .^`` and the transposes). It recurses only into brackets, unary operators,
anonymous functions and blocks, each counted against a limit the lexer and this parser check
before Python's own stack could be reached; every tree it builds is at most
:data:`~.nodes.MAX_DEPTH` deep.
"""

from __future__ import annotations

from odelab.exceptions import ExperimentError
from odelab.formats.matlab import nodes as n
from odelab.formats.matlab.lexer import Token, tokenize

__all__ = ["parse", "parse_text", "MAX_BLOCKS"]

MAX_BLOCKS = 32
"""Blocks (if, for, while, switch, try, nested functions) nest at most 32 deep."""

MAX_NESTING = 64
"""Brackets, unary operators and anonymous functions nest at most 64 deep in one expression."""

_BINARY = {"||": 1, "&&": 2, "|": 3, "&": 4, "==": 5, "~=": 5, "<": 5, "<=": 5, ">": 5, ">=": 5, ":": 6,
           "+": 7, "-": 7, "*": 8, "/": 8, "\\": 8, ".*": 8, "./": 8, ".\\": 8, "^": 10, ".^": 10}
_UNARY_PREC = 9
_OPENERS = frozenset({"if", "for", "parfor", "while", "switch", "try", "unwind_protect", "arguments"})
_STATEMENT_END = frozenset({";", ","})


def _depth(*children) -> int:
    return 1 + max((c.depth for c in children if c is not None), default=0)


class _Parser:
    def __init__(self, tokens: list[Token], src: str, lines: list[str]):
        self.toks = tokens
        self.i = 0
        self.src = src
        self.lines = lines
        self.blocks = 0
        self.nesting = 0
        self.ended_functions = self._functions_use_end()

    # --- tokens ----------------------------------------------------------------------------
    @property
    def tok(self) -> Token:
        return self.toks[self.i]

    def peek(self, k: int = 1) -> Token:
        return self.toks[min(self.i + k, len(self.toks) - 1)]

    def advance(self) -> Token:
        tok = self.toks[self.i]
        if tok.kind != "eof":
            self.i += 1
        return tok

    def is_op(self, text: str, tok: Token | None = None) -> bool:
        tok = tok or self.tok
        return tok.kind == "op" and tok.text == text

    def is_kw(self, *words: str) -> bool:
        return self.tok.kind == "kw" and self.tok.text in words

    def error(self, message: str, tok: Token | None = None) -> ExperimentError:
        tok = tok or self.tok
        return ExperimentError(f"line {tok.line}: {message}", source=self.src)

    def expect_op(self, text: str, what: str) -> Token:
        if not self.is_op(text):
            raise self.error(f"expected `{text}` {what}; found {self._shown(self.tok)}.")
        return self.advance()

    @staticmethod
    def _shown(tok: Token) -> str:
        if tok.kind == "eof":
            return "the end of the file"
        if tok.kind == "nl":
            return "the end of the line"
        return f"`{tok.text}`"

    def text_of(self, line: int) -> str:
        text = self.lines[line - 1].strip() if 0 < line <= len(self.lines) else ""
        return text if len(text) <= 72 else text[:69] + "..."

    def _functions_use_end(self) -> bool:
        """Whether this file's functions end with `end` (then functions may nest) or run to the next `function`."""
        functions = sum(1 for t in self.toks if t.kind == "kw" and t.text == "function")
        if not functions:
            return False
        ends = sum(1 for t in self.toks if t.kind == "kw" and t.text == "end")
        openers = sum(1 for t in self.toks if t.kind == "kw" and t.text in _OPENERS)
        extra = ends - openers
        if extra == 0:
            return False
        if extra >= functions:
            return True
        raise ExperimentError(f"its {openers} blocks and {functions} functions do not match its {ends} `end`s: "
                              "either every function ends with `end` or none does; check the blocks' `end`s.",
                              source=self.src)

    def skip_separators(self) -> None:
        while self.tok.kind == "nl" or (self.tok.kind == "op" and self.tok.text in _STATEMENT_END):
            self.advance()

    # --- files and functions ---------------------------------------------------------------
    def parse_file(self) -> n.SourceFile:
        self.skip_separators()
        functions: list[n.Function] = []
        script = None
        if not self.is_kw("function"):
            script = self.parse_block(("function",), top=True)
        while self.is_kw("function") or (script is not None and self.tok.kind != "eof"):
            if self.is_kw("function"):
                functions.append(self.parse_function(None))
            else:  # Octave: a script's statements may follow the functions it defines
                script.extend(self.parse_block(("function",), top=True))
            self.skip_separators()
        if self.tok.kind != "eof":
            raise self.error(f"{self._shown(self.tok)} after the last function; a function file holds only "
                             "functions.")
        return n.SourceFile(path=self.src, script=script, functions=functions, lines=self.lines)

    def parse_function(self, parent: n.Function | None) -> n.Function:
        start = self.advance()  # function
        outputs: list[str] = []
        if self.is_op("["):
            self.advance()
            while not self.is_op("]"):
                if self.tok.kind == "name":
                    outputs.append(self.advance().text)
                elif self.is_op(","):
                    self.advance()
                else:
                    raise self.error(f"expected the function's output names; found {self._shown(self.tok)}.")
            self.advance()
            self.expect_op("=", "after the function's outputs")
            name_tok = self.advance()
        else:
            name_tok = self.advance()
            if self.is_op("="):
                outputs = [name_tok.text]
                self.advance()
                name_tok = self.advance()
        if name_tok.kind != "name":
            raise self.error(f"expected the function's name; found {self._shown(name_tok)}.", name_tok)
        name = name_tok.text
        while self.is_op("."):  # set.prop / get.prop methods: the name as written
            self.advance()
            name += "." + self.advance().text
        inputs: list[str] = []
        if self.is_op("("):
            self.advance()
            while not self.is_op(")"):
                if self.tok.kind == "name":
                    inputs.append(self.advance().text)
                elif self.is_op("~"):
                    self.advance()
                    inputs.append("~")
                elif self.is_op(","):
                    self.advance()
                else:
                    raise self.error(f"expected the function's input names; found {self._shown(self.tok)}.")
            self.advance()
        fn = n.Function(name=name, inputs=inputs, outputs=outputs, body=[], line=start.line, parent=parent,
                        file=self.src)
        self.enter_block()
        fn.body = self.parse_block(("end", "function"), function=fn)
        if self.ended_functions:
            if not self.is_kw("end"):
                raise self.error(f"function `{name}` (line {start.line}) has no `end`; the file's other functions "
                                 "end with one.")
            self.advance()
        self.blocks -= 1
        return fn

    def enter_block(self) -> None:
        self.blocks += 1
        if self.blocks > MAX_BLOCKS:
            raise self.error(f"blocks nest more than {MAX_BLOCKS} deep; ODE code nests a few.")

    # --- statements --------------------------------------------------------------------------
    def parse_block(self, terminators: tuple[str, ...], top: bool = False,
                    function: n.Function | None = None) -> list[n.Stmt]:
        body: list[n.Stmt] = []
        while True:
            self.skip_separators()
            tok = self.tok
            if tok.kind == "eof":
                if top or (function is not None and not self.ended_functions):
                    return body
                raise self.error("the file ends inside a block: an `end` is missing.")
            if tok.kind == "kw" and tok.text == "function":
                if function is not None and self.ended_functions:
                    function.nested.append(self.parse_function(function))
                    continue
                if "function" in terminators:
                    return body
                raise self.error("a function cannot be defined inside a block.")
            if tok.kind == "kw" and tok.text in terminators:
                return body
            body.append(self.parse_statement())

    def parse_statement(self) -> n.Stmt:
        tok = self.tok
        text = self.text_of(tok.line)
        if tok.kind == "cmd":
            self.advance()
            return n.Command(tok.line, tok.text, tuple(tok.value), text=text)
        if tok.kind == "kw":
            handler = getattr(self, f"stmt_{tok.text}", None)
            if handler is None:
                raise self.error(f"`{tok.text}` is out of place here.")
            stmt = handler()
            stmt.text = text
            return stmt
        stmt = self.assignment_or_expression()
        stmt.text = text
        self.end_statement()
        return stmt

    def end_statement(self) -> None:
        if self.tok.kind in ("nl", "eof") or self.tok.kind == "kw" or (
                self.tok.kind == "op" and self.tok.text in _STATEMENT_END):
            return
        raise self.error(f"expected the end of the statement; found {self._shown(self.tok)}.")

    def assignment_or_expression(self) -> n.Stmt:
        line = self.tok.line
        if self.is_op("[") and self._multi_assignment():
            targets = self.parse_targets()
            self.expect_op("=", "after the outputs")
            value = self.parse_expr()
            return n.Assign(line, targets, value, multi=True)
        expr = self.parse_expr()
        if self.is_op("="):
            self.advance()
            self.check_target(expr)
            return n.Assign(line, [expr], self.parse_expr())
        for op in ("+=", "-=", "*=", "/="):
            if self.is_op(op):
                self.advance()
                self.check_target(expr)
                right = self.parse_expr()
                return n.Assign(line, [expr], n.Binary(line, op[0], expr, right, depth=_depth(expr, right)))
        return n.ExprStmt(line, expr)

    def _multi_assignment(self) -> bool:
        """`[a, b] = ...`: the bracket's match is followed by `=`."""
        depth = 0
        for k in range(self.i, len(self.toks)):
            tok = self.toks[k]
            if tok.kind == "op" and tok.text in "([{":
                depth += 1
            elif tok.kind == "op" and tok.text in ")]}":
                depth -= 1
                if depth == 0:
                    nxt = self.toks[k + 1] if k + 1 < len(self.toks) else tok
                    return nxt.kind == "op" and nxt.text == "="
            elif tok.kind in ("nl", "eof"):
                return False
        return False

    def parse_targets(self) -> list[n.Expr]:
        self.advance()  # [
        targets: list[n.Expr] = []
        while not self.is_op("]"):
            if self.is_op(","):
                self.advance()
                continue
            if self.is_op("~"):
                targets.append(n.Tilde(self.advance().line))
                continue
            target = self.parse_postfix()
            self.check_target(target)
            targets.append(target)
        self.advance()
        return targets

    def check_target(self, expr: n.Expr) -> None:
        node = expr
        while isinstance(node, (n.Index, n.Field, n.DynField)):
            node = node.target
        if not isinstance(node, n.Id):
            raise self.error("the left side of `=` must be a variable (`x`, `x(2)`, `s.k`).")

    def stmt_if(self) -> n.If:
        line = self.advance().line
        self.enter_block()
        clauses = []
        cond = self.parse_expr()
        body = self.parse_block(("elseif", "else", "end"))
        clauses.append((cond, body))
        orelse = None
        while True:
            if self.is_kw("elseif"):
                self.advance()
                cond = self.parse_expr()
                clauses.append((cond, self.parse_block(("elseif", "else", "end"))))
            elif self.is_kw("else"):
                self.advance()
                orelse = self.parse_block(("end",))
            else:
                break
        self.close_block("if", line)
        return n.If(line, clauses, orelse)

    def close_block(self, what: str, line: int) -> None:
        if not self.is_kw("end"):
            raise self.error(f"the `{what}` of line {line} has no `end`.")
        self.advance()
        self.blocks -= 1

    def stmt_for(self) -> n.For:
        line = self.advance().line
        self.enter_block()
        paren = self.is_op("(") and self._for_in_parentheses()
        if paren:
            self.advance()
        var_tok = self.advance()
        if var_tok.kind != "name":
            raise self.error(f"expected the loop variable after `for`; found {self._shown(var_tok)}.", var_tok)
        self.expect_op("=", "after the loop variable")
        iterable = self.parse_expr()
        if paren:
            self.expect_op(")", "closing the `for`")
        body = self.parse_block(("end",))
        self.close_block("for", line)
        return n.For(line, n.Id(var_tok.line, var_tok.text), iterable, body)

    stmt_parfor = stmt_for

    def _for_in_parentheses(self) -> bool:
        """`for (k = 1:3)`: the parenthesis holds the whole header."""
        return self.peek().kind == "name" and self.is_op("=", self.peek(2))

    def stmt_while(self) -> n.While:
        line = self.advance().line
        self.enter_block()
        cond = self.parse_expr()
        body = self.parse_block(("end",))
        self.close_block("while", line)
        return n.While(line, cond, body)

    def stmt_switch(self) -> n.Switch:
        line = self.advance().line
        self.enter_block()
        subject = self.parse_expr()
        self.skip_separators()
        cases = []
        otherwise = None
        while True:
            if self.is_kw("case"):
                self.advance()
                value = self.parse_expr()
                cases.append((value, self.parse_block(("case", "otherwise", "end"))))
            elif self.is_kw("otherwise"):
                self.advance()
                otherwise = self.parse_block(("case", "otherwise", "end"))
            else:
                break
        self.close_block("switch", line)
        return n.Switch(line, subject, cases, otherwise)

    def stmt_try(self) -> n.TryCatch:
        line = self.advance().line
        self.enter_block()
        body = self.parse_block(("catch", "end"))
        handler: list[n.Stmt] = []
        if self.is_kw("catch"):
            catch_line = self.advance().line
            if self.tok.kind == "name" and self.tok.line == catch_line:
                self.advance()  # catch ME
            handler = self.parse_block(("end",))
        self.close_block("try", line)
        return n.TryCatch(line, body, handler)

    def stmt_arguments(self) -> n.Arguments:
        """``arguments`` ... ``end``: each line ``name (dims) class {validators} = default``; only the names and
        the defaults matter here (the validators are MATLAB's checks of its caller)."""
        line = self.advance().line
        self.enter_block()
        if self.is_op("("):  # arguments (Repeating), (Output)
            while not self.is_op(")") and self.tok.kind != "eof":
                self.advance()
            self.advance()
        entries: list = []
        while True:
            self.skip_separators()
            if self.is_kw("end") or self.tok.kind == "eof":
                break
            name_tok = self.advance()
            if name_tok.kind != "name":
                raise self.error(f"expected an argument's name in the arguments block; found {self._shown(name_tok)}.",
                                 name_tok)
            target: n.Expr = n.Id(name_tok.line, name_tok.text)
            while self.is_op(".") and self.peek().kind == "name":  # opts.gain: a name-value argument
                self.advance()
                target = n.Field(name_tok.line, target, self.advance().text, depth=target.depth + 1)
            default = None
            while self.tok.kind not in ("nl", "eof") and not self.is_op("=") and not self.is_op(";"):
                self.advance()
            if self.is_op("="):
                self.advance()
                default = self.parse_expr()
            entries.append((target, default))
            while self.tok.kind not in ("nl", "eof") and not self.is_kw("end"):
                self.advance()
        self.close_block("arguments", line)
        return n.Arguments(line, entries)

    def stmt_break(self) -> n.Break:
        return n.Break(self.advance().line)

    def stmt_continue(self) -> n.Continue:
        return n.Continue(self.advance().line)

    def stmt_return(self) -> n.Return:
        return n.Return(self.advance().line)

    def stmt_global(self) -> n.Global:
        tok = self.advance()
        names = []
        while self.tok.kind == "name":
            names.append(self.advance().text)
        if not names:
            raise self.error(f"`{tok.text}` names no variable.")
        return n.Global(tok.line, names, persistent=tok.text == "persistent")

    stmt_persistent = stmt_global

    # --- expressions ---------------------------------------------------------------------------
    def nest(self, tok: Token) -> None:
        self.nesting += 1
        if self.nesting > MAX_NESTING:
            raise self.error(f"the expression nests more than {MAX_NESTING} levels deep (brackets, signs, "
                             "anonymous functions); split it with intermediate variables.", tok)

    def checked(self, node: n.Expr) -> n.Expr:
        if node.depth > n.MAX_DEPTH:
            raise self.error(f"an expression is more than {n.MAX_DEPTH} operations deep (a chain of that many "
                             "terms); split it with intermediate variables.")
        return node

    def parse_expr(self) -> n.Expr:
        return self.parse_binary(1)

    def parse_binary(self, min_prec: int) -> n.Expr:
        left = self.parse_unary()
        while True:
            tok = self.tok
            if tok.kind != "op" or tok.text not in _BINARY:
                return left
            prec = _BINARY[tok.text]
            if prec < min_prec:
                return left
            self.advance()
            if tok.text == ":":
                mid = self.parse_binary(7)
                if self.is_op(":"):
                    self.advance()
                    stop = self.parse_binary(7)
                    left = self.checked(n.Range(tok.line, left, mid, stop, depth=_depth(left, mid, stop)))
                else:
                    left = self.checked(n.Range(tok.line, left, None, mid, depth=_depth(left, mid)))
                continue
            right = self.parse_binary(prec + 1)
            left = self.checked(n.Binary(tok.line, tok.text, left, right, depth=_depth(left, right)))

    def parse_unary(self) -> n.Expr:
        tok = self.tok
        if tok.kind == "op" and tok.text in ("-", "+", "~"):
            self.advance()
            self.nest(tok)
            operand = self.parse_binary(_UNARY_PREC + 1)
            self.nesting -= 1
            return self.checked(n.Unary(tok.line, tok.text, operand, depth=_depth(operand)))
        return self.parse_postfix()

    def parse_postfix(self) -> n.Expr:
        node = self.parse_primary()
        while True:
            tok = self.tok
            if tok.kind != "op":
                return node
            if tok.text == "(" and not tok.space or (tok.text == "(" and not self._in_matrix_space(tok)):
                self.advance()
                args = self.parse_args(")")
                node = n.Index(tok.line, node, args, depth=_depth(node, *args))
            elif tok.text == "{":
                self.advance()
                args = self.parse_args("}")
                node = n.Index(tok.line, node, args, brace=True, depth=_depth(node, *args))
            elif tok.text == "." and self.peek().kind in ("name", "kw", "end"):
                self.advance()
                node = n.Field(tok.line, node, self.advance().text, depth=_depth(node))
            elif tok.text == "." and self.is_op("(", self.peek()):
                self.advance()
                self.advance()
                self.nest(tok)
                name = self.parse_expr()
                self.nesting -= 1
                self.expect_op(")", "closing the dynamic field name")
                node = n.DynField(tok.line, node, name, depth=_depth(node, name))
            elif tok.text in ("'", ".'"):
                self.advance()
                node = n.Postfix(tok.line, tok.text, node, depth=_depth(node))
            else:
                return node
            self.checked(node)

    @staticmethod
    def _in_matrix_space(tok: Token) -> bool:
        return False  # the lexer inserts the comma that `[a (1)]` implies

    def parse_args(self, close: str) -> list[n.Expr]:
        self.nest(self.tok)
        args: list[n.Expr] = []
        while not self.is_op(close):
            if self.is_op(":") and (self.is_op(",", self.peek()) or self.is_op(close, self.peek())):
                args.append(n.Colon(self.advance().line))
            else:
                args.append(self.parse_expr())
            if self.is_op(","):
                self.advance()
                if self.is_op(close):
                    raise self.error(f"an argument is missing before `{close}`.")
            elif not self.is_op(close):
                raise self.error(f"expected `,` or `{close}` in the arguments; found {self._shown(self.tok)}.")
        self.advance()
        self.nesting -= 1
        return args

    def parse_primary(self) -> n.Expr:
        tok = self.tok
        if tok.kind == "num":
            self.advance()
            value, imaginary = tok.value
            return n.Num(tok.line, value, tok.text, imaginary)
        if tok.kind == "str":
            self.advance()
            return n.Str(tok.line, tok.value, double=tok.text.startswith('"'))
        if tok.kind == "name":
            self.advance()
            return n.Id(tok.line, tok.text)
        if tok.kind == "end":
            self.advance()
            return n.EndIndex(tok.line)
        if tok.kind == "op":
            if tok.text == "(":
                self.advance()
                self.nest(tok)
                inner = self.parse_expr()
                self.nesting -= 1
                self.expect_op(")", "closing the parenthesis")
                return inner
            if tok.text in ("[", "{"):
                return self.parse_matrix()
            if tok.text == "@":
                return self.parse_handle()
            if tok.text == ":":
                self.advance()
                return n.Colon(tok.line)
        raise self.error(f"expected a value; found {self._shown(tok)}.")

    def parse_matrix(self) -> n.Expr:
        open_tok = self.advance()
        close = "]" if open_tok.text == "[" else "}"
        self.nest(open_tok)
        rows: list[list[n.Expr]] = [[]]
        while not self.is_op(close):
            if self.is_op(";"):
                self.advance()
                rows.append([])
                continue
            if self.is_op(","):
                self.advance()
                continue
            rows[-1].append(self.parse_expr())
        self.advance()
        self.nesting -= 1
        rows = [r for r in rows if r]
        children = [e for r in rows for e in r]
        return self.checked(n.Matrix(open_tok.line, rows, cell=close == "}", depth=_depth(*children)))

    def parse_handle(self) -> n.Expr:
        at = self.advance()
        if self.tok.kind == "name":
            name = self.advance().text
            while self.is_op(".") and self.peek().kind == "name":  # @pkg.fun
                self.advance()
                name += "." + self.advance().text
            return n.FuncHandle(at.line, name)
        if not self.is_op("("):
            raise self.error("expected a function name or `(` after `@`.")
        self.advance()
        params: list[str] = []
        while not self.is_op(")"):
            if self.tok.kind == "name":
                params.append(self.advance().text)
            elif self.is_op("~"):
                self.advance()
                params.append("~")
            elif self.is_op(","):
                self.advance()
            else:
                raise self.error(f"expected the anonymous function's argument names; found {self._shown(self.tok)}.")
        self.advance()
        self.nest(at)
        body = self.parse_expr()
        self.nesting -= 1
        return self.checked(n.AnonFn(at.line, params, body, depth=_depth(body)))


def parse_text(text: str, src: str) -> n.SourceFile:
    """Parse MATLAB source ``text`` (from the file ``src``, named in messages)."""
    tokens = tokenize(text, src)
    return _Parser(tokens, src, text.splitlines()).parse_file()


def parse(path, raw: bytes) -> n.SourceFile:
    """Parse a ``.m`` file's bytes (decoded by :func:`odelab.formats.matlab.source.decode`)."""
    from odelab.formats.matlab.source import decode

    return parse_text(decode(raw, str(path)), str(path))
