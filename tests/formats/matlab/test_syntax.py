"""The MATLAB subset's syntax: context-sensitive lexing, the parser's shapes, and its limits."""

import pytest

from odelab.exceptions import ExperimentError
from odelab.formats.matlab import nodes as n
from odelab.formats.matlab.lexer import MAX_BRACKETS, tokenize
from odelab.formats.matlab.parser import parse_text


def _kinds(text):
    return [(t.kind, t.text) for t in tokenize(text, "x.m") if t.kind not in ("nl", "eof")]


def test_white_space_separates_elements_in_brackets_but_not_outside():
    assert _kinds("[1 -2]") == [("op", "["), ("num", "1"), ("op", ","), ("op", "-"), ("num", "2"), ("op", "]")]
    assert _kinds("[1 - 2]") == [("op", "["), ("num", "1"), ("op", "-"), ("num", "2"), ("op", "]")]
    assert _kinds("x = a -b") == [("name", "x"), ("op", "="), ("name", "a"), ("op", "-"), ("name", "b")]
    rows = parse_text("A = [0  1\n -2*k  -3];", "x.m").script[0].value
    assert [len(r) for r in rows.rows] == [2, 2]


def test_quote_is_a_transpose_after_a_value_and_a_string_elsewhere():
    assert _kinds("y = x';")[2:] == [("name", "x"), ("op", "'"), ("op", ";")]
    assert _kinds("s = ['a' 'b'];")[3:6] == [("str", "'a'"), ("op", ","), ("str", "'b'")]
    stmt = parse_text("o = odeset('RelTol', 1e-4);", "x.m").script[0]
    assert isinstance(stmt.value.args[0], n.Str) and stmt.value.args[0].value == "RelTol"


def test_comments_continuations_and_block_comments():
    text = "a = 1 + ... comment\n  2; % trailing\n%{\nb = 3;\n%}\nc = [1 2 % inside\n 3 4];"
    script = parse_text(text, "x.m").script
    assert [s.targets[0].name for s in script] == ["a", "c"]
    assert script[0].line == 1 and script[1].line == 6
    assert [len(r) for r in script[1].value.rows] == [2, 2]


def test_end_inside_an_index_is_the_last_index():
    stmt = parse_text("if true\n z = y(end-1);\nend", "x.m").script[0]
    value = stmt.clauses[0][1][0].value
    assert isinstance(value.args[0].left, n.EndIndex)


def test_command_syntax_and_function_files_with_local_and_nested_functions():
    script = parse_text("hold on\nformat long g\nx = 1;", "x.m").script
    assert isinstance(script[0], n.Command) and script[0].words == ("on",)
    assert script[1].words == ("long", "g")
    src = parse_text("function outer(k)\n  y = 1;\n  function d = inner(t, y)\n    d = k*y;\n  end\nend\n"
                     "function z = helper(a)\n  z = a;\nend\n", "f.m")
    assert [f.name for f in src.functions] == ["outer", "helper"]
    assert src.functions[0].nested[0].name == "inner" and src.functions[0].nested[0].parent is src.functions[0]
    plain = parse_text("function dy = f(t, y)\ndy = -y;\nfunction z = g(a)\nz = a;\n", "f.m")
    assert [f.name for f in plain.functions] == ["f", "g"] and plain.main.outputs == ["dy"]


def test_precedence_is_matlabs():
    def shape(text):
        node = parse_text(f"x = {text};", "x.m").script[0].value

        def walk(e):
            if isinstance(e, n.Binary):
                return f"({walk(e.left)} {e.op} {walk(e.right)})"
            if isinstance(e, n.Unary):
                return f"({e.op}{walk(e.operand)})"
            if isinstance(e, n.Num):
                return e.text
            return e.name if isinstance(e, n.Id) else "?"
        return walk(node)

    assert shape("-2^2") == "(-(2 ^ 2))"
    assert shape("2^3^2") == "((2 ^ 3) ^ 2)"  # MATLAB's power is left-associative
    assert shape("a - b - c") == "((a - b) - c)"
    assert shape("-a*b") == "((-a) * b)"
    assert shape("a < b == c") == "((a < b) == c)"
    assert shape("a | b & c") == "(a | (b & c))"


@pytest.mark.parametrize("text, message", [
    ("x = " + "(" * 10_000 + "1" + ")" * 10_000 + ";", f"brackets nest more than {MAX_BRACKETS} deep"),
    ("x = " + "-" * 10_000 + "1;", "nests more than 64 levels deep"),
    ("x = " + " + ".join(["1"] * 5000) + ";", "more than 120 operations deep"),
    ("x = [1 2;", "a `[` is never closed"),
    ("x = 'abc;", "a string is never closed"),
    ("x = 1 $ 2;", "the character '$' is not MATLAB"),
    ("if x\n y = 1;\n", "an `end` is missing"),
])
def test_malformed_and_hostile_text_is_one_message_with_its_line(text, message):
    with pytest.raises(ExperimentError) as info:
        parse_text(text, "bad.m")
    assert message in str(info.value) and str(info.value).startswith("bad.m: line ")


def test_blocks_nest_a_bounded_depth():
    text = "if 1\n" * 100 + "x = 1;\n" + "end\n" * 100
    with pytest.raises(ExperimentError) as info:
        parse_text(text, "deep.m")
    assert "blocks nest more than 32 deep" in str(info.value)


def test_an_arguments_block_is_read_for_its_defaults():
    src = parse_text("function out = f(tf, opts)\n  arguments\n    tf (1,1) double {mustBePositive} = 5\n"
                     "    opts.gain (1,1) double = 2\n  end\n  out = tf*opts.gain;\nend\n", "f.m")
    block = src.main.body[0]
    assert isinstance(block, n.Arguments) and [e[0].__class__.__name__ for e in block.entries] == ["Id", "Field"]
    assert block.entries[0][1].value == 5 and block.entries[1][1].value == 2
