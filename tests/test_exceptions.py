"""Exceptions: the builtin bases, location, and the caret under an expression's error."""

import pytest

from odelab.exceptions import ExperimentError, ExpressionError, InputError, OdelabError


def test_hierarchy():
    for cls in (InputError, ExperimentError, ExpressionError):
        assert issubclass(cls, OdelabError) and issubclass(cls, ValueError)


def test_located_fills_only_what_is_missing():
    exc = InputError("bad", key="solver.rtol").located(source="a.toml", key="other")
    assert (exc.source, exc.key) == ("a.toml", "solver.rtol")
    assert str(exc) == "a.toml: bad"


@pytest.mark.parametrize(
    "expression, column, shown",
    [
        ("cos(t) +* 2", 8, "    cos(t) +* 2\n            ^"),
        ("x +\n  foo(1)", 6, "      foo(1)\n      ^"),  # the line holding the column, not the whole text
        ("a" * 300 + "?", 300, None),  # a long line is windowed around the column
    ],
)
def test_caret(expression, column, shown):
    exc = ExpressionError("msg", expression=expression, column=column, key="k")
    text = exc.caret()
    line, caret = text.split("\n")
    assert caret.index("^") - 4 < len(line) - 4 + 1
    assert line[caret.index("^")] == expression[column]
    if shown is not None:
        assert text == shown
    assert str(exc).startswith("`k`: msg\n")


def test_key_is_not_duplicated_or_confused_with_a_word():
    assert str(ExpressionError("unknown name `bad`; known names", expression="bad", key="k")).startswith("`k`: ")
    assert str(ExpressionError("`k`: already there", expression="x", key="k")).count("`k`") == 1
