"""MATLAB source text to tokens: the context-sensitive parts of MATLAB's syntax, never executing anything.

What makes MATLAB's lexing context-sensitive, all handled here so the parser sees plain tokens:

- ``'`` is a transpose after a value (``x'``, ``y(1)'``) and starts a string elsewhere;
- inside ``[ ]`` and ``{ }`` white space separates elements (``[1 -2]`` is two numbers,
  ``[1 - 2]`` one) and a line break separates rows: the lexer inserts the commas and
  semicolons it implies;
- ``end`` inside an index (``y(end)``) is the last index, elsewhere it closes a block;
- ``...`` continues a line; ``%`` and ``#`` (Octave) start comments, ``%{``/``%}`` lines
  enclose block comments;
- a statement such as ``hold on`` or ``format long`` is command syntax: a name and words.

Every limit is checked as the text is read, before anything recursive sees it: the number of
tokens and how deeply brackets nest (10,000 nested parentheses stop here, at the first one over
the limit, with the line).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from odelab.exceptions import ExperimentError

__all__ = ["Token", "tokenize", "KEYWORDS", "MAX_TOKENS", "MAX_BRACKETS"]

MAX_TOKENS = 400_000
"""A MATLAB file of at most 1 MB holds fewer tokens than this."""

MAX_BRACKETS = 48
"""Brackets nest at most 48 deep (ODE code nests a handful): the parser's recursion stays shallow."""

KEYWORDS = frozenset({
    "function", "end", "if", "elseif", "else", "for", "parfor", "while", "switch", "case", "otherwise",
    "break", "continue", "return", "global", "persistent", "try", "catch", "do", "until",
    "endfunction", "endif", "endfor", "endwhile", "endswitch", "end_try_catch", "unwind_protect",
    "unwind_protect_cleanup", "end_unwind_protect",
})
_PAREN_COMMANDS = frozenset({"syms", "pkg"})  # command syntax whose words hold parentheses: `syms y(t)`
_OCTAVE_ENDS = frozenset({"endfunction", "endif", "endfor", "endwhile", "endswitch", "end_try_catch",
                          "end_unwind_protect"})

# Statement-level words that MATLAB's command syntax uses in ODE scripts (`hold on`, `format long`)
_OPERATORS = sorted([
    "==", "~=", "!=", "<=", ">=", "&&", "||", ".*", "./", ".\\", ".^", ".'", "+=", "-=", "*=", "/=",
    "+", "-", "*", "/", "\\", "^", "<", ">", "&", "|", "~", "!", "=", "(", ")", "[", "]", "{", "}", ",", ";",
    ":", ".", "@", "'",
], key=len, reverse=True)
_NUMBER = re.compile(r"(?:0[xX][0-9A-Fa-f]+|0[bB][01]+|(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?)([ij](?![A-Za-z0-9_]))?")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_SPACE = re.compile(r"[ \t\f\v]+")
_VALUE_END = frozenset({")", "]", "}", "'", ".'"})  # tokens after which ' is a transpose and space may separate
_BLOCK_OPEN = re.compile(r"^[ \t]*[%#]\{[ \t]*$")
_BLOCK_CLOSE = re.compile(r"^[ \t]*[%#]\}[ \t]*$")


@dataclass(frozen=True, slots=True)
class Token:
    """One token: ``kind`` is num, str, name, kw, op, end (the last index), nl (a statement's end), cmd, eof."""

    kind: str
    text: str
    line: int
    col: int
    value: object = None  # a number's value, a string's characters, a command's words
    space: bool = False  # white space before it


def _error(message: str, line: int, src: str) -> ExperimentError:
    return ExperimentError(f"line {line}: {message}", source=src)


class _Lexer:
    def __init__(self, text: str, src: str):
        self.text = text
        self.src = src
        self.pos = 0
        self.line = 1
        self.line_start = 0
        self.tokens: list[Token] = []
        self.stack: list[str] = []  # open brackets: ( [ {
        self.index_depth = 0  # ( or { opened right after a value: `end` inside is an index
        self.opened_as_index: list[bool] = []
        self.at_statement_start = True
        self.block_comment = 0

    # --- helpers ---------------------------------------------------------------------------
    def emit(self, kind: str, text: str, value=None, space: bool = False) -> None:
        if len(self.tokens) >= MAX_TOKENS:
            raise _error(f"the file holds more than {MAX_TOKENS:,} tokens; ODE files are far smaller. Split it or "
                         "write the experiment file by hand.", self.line, self.src)
        col = self.pos - self.line_start + 1
        self.tokens.append(Token(kind, text, self.line, col, value, space))
        if kind != "nl":
            self.at_statement_start = False

    def prev(self) -> Token | None:
        return self.tokens[-1] if self.tokens else None

    def prev_is_value(self) -> bool:
        p = self.prev()
        if p is None:
            return False
        if p.kind in ("num", "str", "end"):
            return True
        if p.kind == "name":
            return True
        if p.kind == "kw":
            return False
        return p.kind == "op" and p.text in _VALUE_END

    def in_matrix(self) -> bool:
        return bool(self.stack) and self.stack[-1] in "[{"

    def newline(self) -> None:
        self.line += 1
        self.line_start = self.pos

    # --- the main loop ---------------------------------------------------------------------
    def run(self) -> list[Token]:
        text = self.text
        n = len(text)
        while self.pos < n:
            if self.at_line_start() and self.block_comment_line():
                continue
            ch = text[self.pos]
            space = False
            m = _SPACE.match(text, self.pos)
            if m:
                self.pos = m.end()
                space = True
                if self.pos >= n:
                    break
                ch = text[self.pos]
            if ch in "\r\n":
                self.line_break()
                continue
            if ch in "%#":
                self.skip_comment()
                continue
            if text.startswith("...", self.pos):
                self.continuation()
                continue
            if self.at_statement_start and not self.stack and ch == "!" and not text.startswith("!=", self.pos):
                raise _error("`!` runs a shell command; odelab never runs commands from a MATLAB file. Remove the "
                             "line.", self.line, self.src)
            if self.in_matrix() and space and self.prev_is_value() and self.starts_element(ch):
                self.emit("op", ",")
            if self.at_statement_start and not self.stack and self.command_syntax():
                continue
            self.token(ch, space)
        if self.block_comment:
            raise _error("a block comment (%{) is never closed with %}.", self.line, self.src)
        if self.stack:
            raise _error(f"a `{self.stack[-1]}` is never closed.", self.line, self.src)
        self.emit("nl", "")
        self.emit("eof", "")
        return self.tokens

    def at_line_start(self) -> bool:
        return self.pos == self.line_start

    def block_comment_line(self) -> bool:
        """%{ and %} alone on their lines open and close (nested) block comments."""
        end = self.text.find("\n", self.pos)
        end = len(self.text) if end < 0 else end
        line = self.text[self.pos:end]
        if _BLOCK_OPEN.match(line):
            self.block_comment += 1
        elif self.block_comment and _BLOCK_CLOSE.match(line):
            self.block_comment -= 1
        elif not self.block_comment:
            return False
        self.pos = end
        if self.pos < len(self.text):
            self.pos += 1
            self.newline()
        return True

    def line_break(self) -> None:
        if self.text.startswith("\r\n", self.pos):
            self.pos += 2
        else:
            self.pos += 1
        if self.in_matrix():
            p = self.prev()
            if p is not None and p.kind == "op" and p.text == ",":
                self.tokens.pop()
                p = self.prev()
            if p is not None and not (p.kind == "op" and p.text in ("[", "{", ";")):
                self.emit("op", ";")
        elif not self.stack:
            self.emit_nl()
        self.newline()

    def emit_nl(self) -> None:
        p = self.prev()
        if p is not None and p.kind != "nl":
            self.emit("nl", "\n")
        self.at_statement_start = True

    def skip_comment(self) -> None:
        end = self.text.find("\n", self.pos)
        self.pos = len(self.text) if end < 0 else end

    def continuation(self) -> None:
        end = self.text.find("\n", self.pos)
        if end < 0:
            self.pos = len(self.text)
            return
        self.pos = end + 1
        self.newline()

    def starts_element(self, ch: str) -> bool:
        """In [ ] after a value and white space: does this character start a new element?"""
        text = self.text
        nxt = text[self.pos + 1] if self.pos + 1 < len(text) else ""
        if ch in "+-":
            return nxt not in " \t=" and not text.startswith(ch * 2, self.pos)
        if ch == "'" or ch == '"':
            return True
        if ch in "([{@":
            return True
        if ch in "~!":
            return nxt != "="
        if ch == ".":
            return nxt.isdigit()
        return ch.isalnum() or ch == "_"

    def command_syntax(self) -> bool:
        """``hold on``, ``format long``, ``global a b``: a name, white space, then words (no operator, no =).
        ``arguments`` alone on its line opens a function's argument-validation block (R2019b)."""
        m = _NAME.match(self.text, self.pos)
        if m and m.group() == "arguments" and re.match(r"[ \t]*(?:\([^)\n]*\))?[ \t]*(?:[%#].*)?(?:\r?\n|$)",
                                                        self.text[m.end():]):
            self.pos = m.end()
            self.emit("kw", "arguments")
            self.pos_fix(m.start())
            return True
        if not m or m.group() in KEYWORDS:
            return False
        after = m.end()
        space = _SPACE.match(self.text, after)
        if not space:
            return False
        rest_start = space.end()
        end = self.text.find("\n", rest_start)
        end = len(self.text) if end < 0 else end
        rest = self.text[rest_start:end]
        if not rest or rest[0] in "%#\r\n;,":
            return False
        first = rest[0]
        if not (first.isalnum() or first in "_-'"):
            return False
        if first == "-" and (len(rest) < 2 or not rest[1].isalpha()):
            return False  # `x -1` is arithmetic in ODE code
        code = re.match(r"(?:'(?:[^']|'')*'|[^%#;,'])*", rest).group()
        bare = re.sub(r"'(?:[^']|'')*'", "", code)  # what is not quoted decides
        if "=" in bare.replace("==", "") or ("(" in bare and m.group() not in _PAREN_COMMANDS):
            return False
        first_name = _NAME.match(rest)
        if first.isdigit() or (first_name and first_name.end() < len(rest) and rest[first_name.end()] in "+-*/^.(=<>&|:"
                               and m.group() not in _PAREN_COMMANDS):
            return False
        words = []
        for part in re.finditer(r"'((?:[^']|'')*)'|(\S+)", code.rstrip(";, \t\r")):
            words.append(part.group(1).replace("''", "'") if part.group(1) is not None else part.group(2))
        self.emit("cmd", m.group(), value=tuple(words))
        self.pos = rest_start + len(code)
        return True

    def token(self, ch: str, space: bool) -> None:
        text = self.text
        if ch == "'" and not (self.prev_is_value() and not (space and self.in_matrix())):
            self.string("'")
            return
        if ch == '"':
            self.string('"')
            return
        if ch.isdigit() or (ch == "." and self.pos + 1 < len(text) and text[self.pos + 1].isdigit()):
            self.number(space)
            return
        m = _NAME.match(text, self.pos)
        if m:
            self.name(m.group(), space)
            return
        for op in _OPERATORS:
            if text.startswith(op, self.pos):
                self.operator(op, space)
                return
        shown = ch if ch.isprintable() else f"\\x{ord(ch):02x}"
        raise _error(f"the character {shown!r} is not MATLAB; is this a MATLAB file?", self.line, self.src)

    def string(self, quote: str) -> None:
        text = self.text
        start = self.pos
        i = self.pos + 1
        chars = []
        while True:
            if i >= len(text) or text[i] in "\r\n":
                raise _error("a string is never closed (a missing quote).", self.line, self.src)
            if text[i] == quote:
                if i + 1 < len(text) and text[i + 1] == quote:
                    chars.append(quote)
                    i += 2
                    continue
                break
            chars.append(text[i])
            i += 1
        self.pos = i + 1
        self.emit("str", text[start:self.pos], value="".join(chars))
        self.pos_fix(start)

    def pos_fix(self, start: int) -> None:
        """Tokens record the column where they start."""
        tok = self.tokens[-1]
        self.tokens[-1] = Token(tok.kind, tok.text, tok.line, start - self.line_start + 1, tok.value, tok.space)

    def number(self, space: bool) -> None:
        text = self.text
        start = self.pos
        m = _NUMBER.match(text, self.pos)
        body = m.group()
        # `1./x` and `2.^y`: the dot belongs to the operator
        if body.endswith(".") and m.end() < len(text) and text[m.end()] in "*/^\\'":
            body = body[:-1]
        end = start + len(body)
        imaginary = m.group(1) if len(body) == len(m.group()) else None
        digits = body[:-1] if imaginary else body
        if digits[:2].lower() == "0x":
            value = float(int(digits[2:], 16))
        elif digits[:2].lower() == "0b":
            value = float(int(digits[2:], 2))
        else:
            value = float(digits.replace("d", "e").replace("D", "e"))
        self.pos = end
        self.emit("num", body, value=(value, bool(imaginary)), space=space)
        self.pos_fix(start)

    def name(self, word: str, space: bool) -> None:
        start = self.pos
        self.pos += len(word)
        if word == "end" and self.index_depth > 0:
            self.emit("end", word, space=space)
        elif word in _OCTAVE_ENDS:
            self.emit("kw", "end", space=space)
        elif word in KEYWORDS:
            self.emit("kw", word, space=space)
        else:
            self.emit("name", word, space=space)
        self.pos_fix(start)

    def operator(self, op: str, space: bool) -> None:
        start = self.pos
        if op in ("(", "[", "{"):
            if len(self.stack) >= MAX_BRACKETS:
                raise _error(f"brackets nest more than {MAX_BRACKETS} deep; odelab reads ODE code, which nests a "
                             "handful. Split the expression with intermediate variables.", self.line, self.src)
            is_index = op != "[" and self.prev_is_value()
            self.stack.append(op)
            self.opened_as_index.append(is_index)
            if is_index:
                self.index_depth += 1
        elif op in (")", "]", "}"):
            want = {")": "(", "]": "[", "}": "{"}[op]
            if not self.stack or self.stack[-1] != want:
                raise _error(f"a `{op}` closes nothing (brackets do not match).", self.line, self.src)
            if self.in_matrix():  # `[1 2 ;]`, `[a, ]`: a trailing separator is no element
                p = self.prev()
                if p is not None and p.kind == "op" and p.text in (",", ";") and p.text != want:
                    self.tokens.pop()
            self.stack.pop()
            if self.opened_as_index.pop():
                self.index_depth -= 1
        if op in (";", ",") and not self.stack:
            self.pos += 1
            self.emit("op", op)
            self.pos_fix(start)
            self.at_statement_start = True
            return
        length = len(op)
        op = {"!=": "~=", "!": "~"}.get(op, op)
        self.pos = start + length
        self.emit("op", op, space=space)
        self.pos_fix(start)


def tokenize(text: str, src: str) -> list[Token]:
    """The tokens of MATLAB source ``text`` (from the file ``src``, for messages)."""
    return _Lexer(text, src).run()
