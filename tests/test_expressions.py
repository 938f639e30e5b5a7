"""Tests of odelab.expressions: values, precedence, errors with carets, hostile input, speed path."""

from __future__ import annotations

import math
import operator
import os
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from odelab.exceptions import ExpressionError, InputError
from odelab.expressions import (CONSTANTS, FUNCTIONS, MAX_LENGTH, RESERVED, check_identifier,
                                compile_expression, compile_vector, evaluate_constant,
                                evaluate_parameters, parse_expression)  # fmt: skip


def value(text, **values):
    return compile_expression(text, names=values)(**values)


def error(text, names=("x", "y", "t")):
    with pytest.raises(ExpressionError) as info:
        compile_expression(text, names=names)
    assert info.value.expression == text
    return info.value


# --- values ----------------------------------------------------------------------------------

X = 0.3
FUNCTION_VALUES = [
    ("sin(x)", math.sin(X)), ("cos(x)", math.cos(X)), ("tan(x)", math.tan(X)),
    ("asin(x)", math.asin(X)), ("acos(x)", math.acos(X)), ("atan(x)", math.atan(X)),
    ("atan2(x, -1)", math.atan2(X, -1)), ("sinh(x)", math.sinh(X)), ("cosh(x)", math.cosh(X)),
    ("tanh(x)", math.tanh(X)), ("exp(x)", math.exp(X)), ("log(x)", math.log(X)),
    ("log10(x)", math.log10(X)), ("sqrt(x)", math.sqrt(X)), ("abs(-x)", X), ("sign(-x)", -1.0),
    ("min(x, 2, -1)", -1.0), ("max(x, 0.1)", X), ("max(x, 2, 7, -1)", 7.0), ("floor(-x)", -1.0),
    ("ceil(x)", 1.0), ("heaviside(x)", 1.0), ("step(-x)", 0.0), ("where(x - 1, 5, 6)", 5.0),
    ("where(x > 1, 5, 6)", 6.0), ("pi", math.pi), ("e", math.e), ("2*pi*x", 2 * math.pi * X),
]


def test_the_language_lists():
    assert " ".join(FUNCTIONS) == (
        "sin cos tan asin acos atan atan2 sinh cosh tanh exp log log10 sqrt abs sign min max "
        "floor ceil heaviside step where mod rem square sawtooth")  # fmt: skip
    assert dict(CONSTANTS) == {"pi": math.pi, "e": math.e}
    assert RESERVED == set(FUNCTIONS) | {"pi", "e", "t"}


@pytest.mark.parametrize("text, expected", FUNCTION_VALUES)
def test_function_values(text, expected):
    result = value(text, x=X)
    assert isinstance(result, np.float64)
    assert result == pytest.approx(expected, rel=1e-15)


def test_heaviside_is_matlab_and_step_switches_at_zero():
    x = np.array([-1.0, 0.0, 2.0])
    np.testing.assert_array_equal(value("heaviside(x)", x=x), [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(value("step(x) + 2*sign(x)", x=x), [-2.0, 1.0, 3.0])


@pytest.mark.parametrize(
    "text, expected",
    [("2*x^2", 18.0), ("-x^2", -9.0), ("x^3+1", 28.0), ("2^-1", 0.5), ("(2^3)^2", 64.0),
     ("2^(3^2)", 512.0), ("2**3**2", 512.0), ("x ^ 2 / 3", 3.0), ("-x**2", -9.0), ("1e2^0.5", 10.0),
     ("2.^x", 8.0), ("2.*x", 6.0)],
)  # fmt: skip
def test_power_precedence_is_matlabs(text, expected):
    assert value(text, x=3.0) == expected


@pytest.mark.parametrize(
    "text, column", [("a^b^c", 1), ("9^9^9", 1), ("a^-b^c", 1), ("a**b^c", 4), ("a^(b)^c", 1)]
)
def test_chained_power_with_caret_is_rejected(text, column):
    err = error(text, names="abc")
    assert "`(a^b)^c` or `a^(b^c)`" in err.message
    assert err.column == column


def test_floating_point_errors_give_inf_and_nan_quietly(recwarn):
    start = time.perf_counter()
    assert value("9**9**9") == math.inf and time.perf_counter() - start < 1.0
    assert value("1/0") == math.inf and value("1/x", x=0) == math.inf
    assert math.isnan(value("(-8)^(1/3)")) and math.isnan(value("log(x)", x=-1))
    assert value("1e400") == math.inf and value("1" + "0" * 400) == math.inf
    assert len(recwarn) == 0


def test_comparisons_are_floats_and_chains_mean_and():
    t = np.array([-1.0, 0.0, 0.5, 1.0, 2.0])
    assert value("0 < t < 1", t=t).dtype == np.float64
    np.testing.assert_array_equal(value("0 < t < 1", t=t), [0, 0, 1, 0, 0])
    np.testing.assert_array_equal(value("0 <= t <= 1 != 2", t=t), [0, 1, 1, 1, 0])
    np.testing.assert_array_equal(value("-(t >= 1)*3", t=t), [0, 0, 0, -3, -3])
    assert value("t == 2", t=2) == 1.0 and value("t != 2", t=2) == 0.0
    np.testing.assert_array_equal(value("where(t > 0, t, -t)", t=t), np.abs(t))
    assert type(value("where(t > 0, 1, 2)", t=3.0)) is np.float64  # 0-d results are unwrapped
    assert value("T*t", t=2.0, T=5.0) == 10.0  # names are case-sensitive


def test_broadcasting_and_constant_expressions():
    x = np.linspace(0, 1, 4)
    np.testing.assert_allclose(value("x*y", x=x, y=2.0), 2 * x)
    assert value("x + y", x=x[:, None], y=x).shape == (4, 4)
    constant = value("2*pi", x=x)
    assert np.broadcast_to(constant, x.shape).shape == (4,) and constant == 2 * math.pi


def test_parsed_expression_names_and_numbers():
    parsed = parse_expression("-k/m*x^3 + sin(omega*t) + pi*e")
    assert parsed.names == {"k", "m", "x", "omega", "t"}
    assert parse_expression(3).text == "3" and parse_expression(2.5).text == "2.5"
    assert evaluate_constant(7) == 7.0 and evaluate_constant(1e-3) == 1e-3
    compiled = compile_expression("omega*t", names=["t", "omega", "unused"])
    assert compiled.names == {"omega", "t"} and compiled.text == "omega*t"


# --- compile_vector ----------------------------------------------------------------------------

RIGID = ["y2*y3", "-y1*y3", "a*y1*y2"]


def test_vector_rigid_body_values_and_shapes():
    F = compile_vector(RIGID, args=["t", "y1", "y2", "y3"], constants={"a": -0.51})
    out = F(0.0, *np.array([1.0, 2.0, 3.0]))
    assert out.shape == (3,) and out.dtype == np.float64
    np.testing.assert_array_equal(out, [6.0, -3.0, -0.51 * 2.0])
    np.testing.assert_array_equal(F(0, 1, 2, 3), out)  # ints are numbers too
    assert F(0.0, np.ones(5), 2.0, 3.0).shape == (3, 5)
    assert F(np.zeros(7), 1.0, 2.0, 3.0).shape == (3, 7)  # t is unused but sets the shape
    assert F(0.0, np.ones((2, 1)), np.ones(4), 3.0).shape == (3, 2, 4)


def test_vector_constant_rows_broadcast():
    F = compile_vector(["1", "x", 2.5], args=["x"], keys=["a", "b", "c"])
    np.testing.assert_array_equal(F(4.0), [1.0, 4.0, 2.5])
    np.testing.assert_array_equal(F(np.arange(3.0)), [[1, 1, 1], [0, 1, 2], [2.5, 2.5, 2.5]])
    assert compile_vector(["1"], args=["x"])(np.ones((2, 3))).shape == (1, 2, 3)
    assert compile_vector([], args=["x"])(1.0).shape == (0,)


def test_vector_errors_name_the_key():
    with pytest.raises(ExpressionError) as info:
        compile_vector(["x", "-k*x + q"], args=["t", "x"], constants={"k": 1.0},
                       keys=["system.equations.v", "system.equations.x"], source="spring.toml")  # fmt: skip
    err = info.value
    assert (err.key, err.source, err.column) == ("system.equations.x", "spring.toml", 7)
    assert str(err).startswith("spring.toml: `system.equations.x`: unknown name `q`")
    assert err.message.endswith("unknown name `q`; known names: t, x, k, pi, e")
    for args, constants in [(["x", "x"], {}), (["x"], {"x": 1}), (["pi"], {}), (["_array"], {})]:
        with pytest.raises(InputError):
            compile_vector(["x"], args=args, constants=constants)


def test_generated_code_reaches_only_helpers():
    F = compile_vector(RIGID, args=["t", "y1", "y2", "y3"], constants={"a": 2.0})
    assert F.__globals__["__builtins__"] == {}
    assert {n for n in F.__globals__ if not n.startswith("_")} == {"a"}
    assert "_rows = ((y2 * y3), ((-y1) * y3), ((a * y1) * y2), )" in F.source  # one function


# --- errors and hostile input ---------------------------------------------------------------------

HOSTILE = [  # (text, part of the message, column of the caret)
    ("__import__('os')", "`__import__` is not an allowed function; allowed: sin, cos", 0),
    ("system('ls')", "`system` is not an allowed function; allowed: sin, cos, tan", 0),
    ("open('f')", "`open` is not an allowed function", 0),
    ("eval('1')", "`eval` is not an allowed function", 0),
    ("getattr(x,'y')", "`getattr` is not an allowed function", 0),
    ("sinn(x)", "`sinn` is not an allowed function; did you mean `sin`?", 0),
    ("().__class__", "attribute access (`.`) is not allowed", 2),
    ("x.__class__", "attribute access (`.`) is not allowed", 1),
    ("sin.__self__", "attribute access (`.`) is not allowed", 3),
    ("[1][0]", "indexing (`[...]`) is not allowed", 3), ("x[0]", "indexing", 1),
    ("lambda: 1", "lambda functions are not allowed", 0),
    ('"a"', "strings are not allowed", 0), ("b'a'", "strings are not allowed", 0),
    ("f'{x}'", "f-strings are not allowed", 0), ("sin(x)(y)", "calling the result of a call", 6),
    ("2(x + 1)", "to multiply, write `*`", 1),
    ("sin(x=1)", "keyword arguments (`x=`) are not allowed", 4),
    ("max(*x, 1)", "starred arguments (`*`) are not allowed", 4),
    ("atan2(x)", "`atan2` takes 2 arguments; got 1", 0),
    ("sin(x, y)", "`sin` takes 1 argument; got 2", 0),
    ("max(x)", "`max` takes 2 or more arguments; got 1", 0),
    ("x + sin", "`sin` is a function; call it as `sin(...)`", 4),
    ("[x for x in y]", "comprehensions", 0), ("{1: 2}", "dicts", 0),
    ("1, 2", "tuples (`,`) are not allowed", 1),
    ("x and y", "`and`/`or` are not allowed; combine conditions with a chained comparison", 2),
    ("not x", "`not` is not allowed", 0), ("x if y else t", "write `where(c, a, b)`", 2),
    ("(x := 1)", "assignments (`:=`) are not allowed", 1),
    ("1j", "complex numbers (`1j`) are not allowed", 0),
    ("...", "`...` (Ellipsis) is not allowed", 0),
    ("True", "booleans (`True`/`False`) are not allowed", 0), ("None", "`None` is not", 0),
    ("x % 2", "operator `%` is not allowed", 2), ("x & y", "operator `&` is not allowed", 2),
    ("x is y", "`is` and `in` are not allowed", 2),
    ("_secret", "names starting with `_` are not allowed", 0),
    ("__builtins__", "names starting with `_` are not allowed", 0),
    ("x # comment", "comments (`#`) are not allowed", 2),
    ("x ~= 1", "`~=` is MATLAB's not-equal; write `!=`", 2),
    ("x.^2 + 1", "`.^` is MATLAB's elementwise operator; write `^`", 1),
    ("t > 1 && x", "`&&` is not supported", 6),
    ("x \u2212 1", "character `\u2212` (U+2212) is not allowed; expressions are ASCII; write `-`", 2),
    ("x\x00", "control character U+0000", 1), ("   ", "empty expression", 0),
    ("x +", "syntax error: an operator or an operand is missing or out of place here", 3),
    ("sin(x", "syntax error: a bracket is opened here and never closed: add the closing bracket", 3),
    ("x^2 +* 3", "syntax error", 5),  # the column is mapped back through `^` -> `**`
    ("  x^2^3", "chained powers", 3), ("x\n+ y^2 $", "syntax error", 8),
    ("omgea", "unknown name `omgea`; did you mean `omega`? Known names: t, x, v, omega, pi, e", 0),
    ("2*T", "unknown name `T`; did you mean `t`? (names are case-sensitive)", 2),
    ("x + zz", "unknown name `zz`; known names: t, x, v, omega, pi, e", 4),
]


@pytest.mark.parametrize("text, message, column", HOSTILE)
def test_rejected_with_message_and_caret(text, message, column):
    err = error(text, names=["t", "x", "v", "omega"])
    assert isinstance(err, InputError) and isinstance(err, ValueError)
    assert message in err.message
    assert err.column == column
    line_start = text.rfind("\n", 0, column) + 1  # the caret sits under the line holding the column
    assert str(err).splitlines()[-1] == "    " + " " * (column - line_start) + "^"


def test_errors_carry_key_and_source():
    with pytest.raises(ExpressionError) as info:
        parse_expression("x^", key="system.equations.x", source="lab.toml")
    err = info.value
    assert (err.key, err.source, err.expression, err.column) == ("system.equations.x", "lab.toml", "x^", 2)
    assert str(err) == ("lab.toml: `system.equations.x`: syntax error: an operator or an operand is missing or out of "
                        "place here\n    x^\n      ^")


def test_huge_and_deep_expressions_are_rejected_cleanly():
    err = error("x+" * 51_200 + "x")  # 100 kB
    assert err.message.startswith("expression is 102401 characters long; the limit is 2000")
    assert err.column == MAX_LENGTH
    assert "characters long" in error("(" * 10_000 + "x" + ")" * 10_000).message
    assert (error("(" * 150 + "x" + ")" * 150).column, error("-" * 1990 + "x").column) == (100, 200)
    assert "brackets are nested more than 100 deep" in error("(" * 150 + "x" + ")" * 150).message
    assert "nested too deeply (more than 200 levels" in error("-" * 1990 + "x").message
    assert "nested too deeply" in error("+".join(["x"] * 300)).message
    assert value("+".join(["x"] * 150), x=1.0) == 150.0
    assert value("sin(" * 99 + "x" + ")" * 99, x=0.0) == 0.0


def test_non_text_values():
    for bad, message in [(True, "booleans are not numbers"), (math.inf, "must be finite"),
                         (None, "must be a string or a number"), ([1], "must be a string")]:  # fmt: skip
        with pytest.raises(ExpressionError, match=message):
            parse_expression(bad, key="k")


PAYLOADS = [
    "__import__('os').environ.setdefault('ODELAB_SENTINEL', 'pwned')",
    "getattr(__import__('os'), 'environ').setdefault('ODELAB_SENTINEL', 'pwned')",
    "(lambda: __import__('os').environ.setdefault('ODELAB_SENTINEL', 'pwned'))()",
    "exec(\"import os; os.environ['ODELAB_SENTINEL'] = 'pwned'\")",
    "[c for c in ().__class__.__base__.__subclasses__() if c.__name__ == 'Popen']",
    "sin.__globals__", "x.__class__.__init__.__globals__",
]


def test_sentinel_nothing_executes(monkeypatch):
    monkeypatch.delenv("ODELAB_SENTINEL", raising=False)
    eval(PAYLOADS[0])  # the sentinel is live: plain Python would run the payload
    assert os.environ.pop("ODELAB_SENTINEL") == "pwned"
    for payload in PAYLOADS:
        for attempt in (lambda: compile_expression(payload, names=["x"]),
                        lambda: compile_vector([payload], args=["x"]),
                        lambda: evaluate_parameters({"a": payload})):  # fmt: skip
            with pytest.raises(ExpressionError):
                attempt()
    assert "ODELAB_SENTINEL" not in os.environ


# --- names, constants and parameters ----------------------------------------------------------------


@pytest.mark.parametrize(
    "name, message",
    [("e", "`states.e`: `e` is a constant (2.718281828459045); choose another name for this state"),
     ("pi", "`pi` is a constant"), ("t", "`t` is the time variable"),
     ("sin", "`sin` is a function"), ("_x", "`_x` starts with `_`"),
     ("lambda", "`lambda` is a Python keyword"), ("x y", "`x y` is not a valid state name"),
     ("\u03c9", "is not a valid state name"), ("", "must not be empty"), (3, "must be a string")],
)  # fmt: skip
def test_check_identifier_rejects(name, message):
    with pytest.raises(InputError) as info:
        check_identifier(name, key=f"states.{name}", source="f.toml", what="state")
    assert message in info.value.message
    assert (info.value.key, info.value.source) == (f"states.{name}", "f.toml")
    for good in ["x", "x1", "Omega", "T", "theta_dot", "match"]:
        assert check_identifier(good) == good


def test_evaluate_constant():
    assert evaluate_constant("2*pi") == 2 * math.pi
    assert type(evaluate_constant("stop/2", values={"stop": 3})) is float
    with pytest.raises(ExpressionError) as info:
        evaluate_constant("1/(t0 - 1)", values={"t0": 1.0}, key="time.stop", source="f.toml")
    assert str(info.value) == (
        "f.toml: `time.stop` = `1/(t0 - 1)` evaluates to inf; it must be a finite number "
        "(check for a division by zero, an overflow, or a log or square root of a negative number)"
    )
    with pytest.raises(InputError, match="evaluates to nan"):
        evaluate_constant("sqrt(-1)")
    with pytest.raises(ExpressionError, match="no names are available here"):
        evaluate_constant("T")


def test_evaluate_parameters_in_dependency_order():
    params = {"k": "m*w^2", "z": "k/m + offset", "m": 2, "w": 3.0, "offset": "-1"}
    result = evaluate_parameters(params)
    assert result == {"k": 18.0, "z": 8.0, "m": 2.0, "w": 3.0, "offset": -1.0}
    assert list(result) == list(params) and all(type(v) is float for v in result.values())


@pytest.mark.parametrize(
    "params, message, key",
    [({"a": "b + 1", "b": "2*a"}, "`parameters.a` and `parameters.b` depend on each other", "a"),
     ({"a": "a + 1"}, "`parameters.a` depends on itself; give it a number", "a"),
     ({"d": 1, "a": "b", "b": "c", "c": "a*d"},
      "`parameters.a`, `parameters.b` and `parameters.c` depend on each other in a cycle "
      "(a -> b -> c -> a)", "a"),
     ({"m": 0, "k": "1/m"}, "`parameters.k` = `1/m` evaluates to inf", "k"),
     ({"m": True}, "`parameters.m` must be a number or an expression string; got bool", "m"),
     ({"m": [1]}, "must be a number or an expression string; got list", "m"),
     ({"sin": 1.0}, "`sin` is a function of the expression language", "sin"),
     ({"mass": 1, "k": "2*mas"}, "unknown name `mas`; did you mean `mass`?", "k")],
)  # fmt: skip
def test_evaluate_parameters_errors(params, message, key):
    with pytest.raises(InputError) as info:
        evaluate_parameters(params, source="f.toml")
    assert message in info.value.message
    assert (info.value.key, info.value.source) == (f"parameters.{key}", "f.toml")


# --- complex step ----------------------------------------------------------------------------------

H = 1e-20
DERIVATIVES = [  # (expression, x, analytic derivative at x)
    ("abs(x)*x", -1.5, 3.0), ("abs(x)*x", 1.5, 3.0), ("max(x, 2*x)", 1.3, 2.0), ("x^3", 2.0, 12.0),
    ("max(x, 2*x)", -1.3, 1.0), ("min(x, 2*x, 5)", 1.3, 1.0), ("x^3", -2.0, 12.0),
    ("sin(x)*exp(x)", 0.7, math.exp(0.7) * (math.sin(0.7) + math.cos(0.7))),
    ("2^x", 1.5, 2**1.5 * math.log(2)), ("x^x", 2.0, 4 * (math.log(2) + 1)),
    ("x/(1 + x^2)", 0.5, (1 - 0.25) / 1.25**2), ("sqrt(x)*log(x)", 4.0, (math.log(4) + 2) / 4),
    ("tan(x) + asin(x) + acos(2*x)", 0.3, 1 / math.cos(0.3) ** 2 + 1 / math.sqrt(0.91) - 2 / math.sqrt(0.64)),
    ("atan(x) + atan2(x, 2)", 1.0, 0.5 + 0.4), ("sinh(x)*cosh(x)", 0.4, math.cosh(0.8)),
    ("tanh(x) + log10(x)", 0.3, 1 / math.cosh(0.3) ** 2 + 1 / (0.3 * math.log(10))),
    ("where(x > 0, x^2, -x)", 3.0, 6.0), ("where(x > 0, x^2, -x)", -3.0, -1.0),
    ("(x < 1)*x + heaviside(x)*x^2 + step(x)", 2.0, 4.0),
    ("sign(x)*x + floor(x)*x + ceil(x)", -1.5, -1.0 - 2.0), ("-x^2 + e^x", 1.0, -2 + math.e),
]  # fmt: skip


@pytest.mark.parametrize("text, x, derivative", DERIVATIVES)
def test_complex_step_derivatives(text, x, derivative):
    result = compile_expression(text, names=["x"], complex_step=True)(x=x + 1j * H)
    assert abs(result.imag / H - derivative) <= 1e-14 * abs(derivative)
    assert result.real == pytest.approx(value(text, x=x), rel=1e-15)


def test_complex_step_keeps_real_domain_and_vector_jacobian():
    f = compile_expression("log(x) + sqrt(x)", names=["x"], complex_step=True)
    assert math.isnan(f(x=-1 + 1j * H).real)  # NaN like the real variant, not a branch value
    F = compile_vector(RIGID, args=["t", "y1", "y2", "y3"], constants={"a": -0.51}, complex_step=True)
    y = np.array([0.3, 1.0, 0.5])
    J = np.column_stack([F(0.0, *(y + 1j * H * np.eye(3)[j])).imag / H for j in range(3)])
    expected = [[0, y[2], y[1]], [-y[2], 0, -y[0]], [-0.51 * y[1], -0.51 * y[0], 0]]
    np.testing.assert_allclose(J, expected, rtol=1e-15)


# --- property: random arithmetic trees match a reference evaluator -------------------------------

# numpy's scalar `**` and the np.power ufunc may differ in the last bit: use the operator
UFUNCS = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "^": operator.pow,
          "**": operator.pow, "sin": np.sin, "exp": np.exp, "sqrt": np.sqrt, "abs": np.abs,
          "log": np.log, "min": np.minimum, "max": np.maximum, "atan2": np.arctan2}  # fmt: skip
BINARY = ["+", "-", "*", "/", "^", "**"]
LEAVES = st.sampled_from(["x", "y", "pi", "e", "0", "2", "3", "0.5", "1e-3", "7.25"])
TREES = st.recursive(
    LEAVES,
    lambda sub: st.one_of(
        st.tuples(st.sampled_from(BINARY), sub, sub),
        st.tuples(st.just("neg"), sub),
        st.tuples(st.sampled_from(["sin", "exp", "sqrt", "abs", "log"]), sub),
        st.tuples(st.sampled_from(["min", "max", "atan2"]), sub, sub),
    ),
    max_leaves=12,
)


def render(tree):
    if isinstance(tree, str):
        return tree
    op, *parts = [tree[0], *map(render, tree[1:])]
    if op == "neg":
        return f"(-{parts[0]})"
    return f"({op.join(parts)})" if op in BINARY else f"{op}({', '.join(parts)})"


def reference(tree, env):
    if isinstance(tree, str):
        return env[tree] if tree in env else np.float64(CONSTANTS.get(tree) or float(tree))
    op, *args = tree
    values = [reference(a, env) for a in args]
    return np.negative(values[0]) if op == "neg" else UFUNCS[op](*values)


@settings(max_examples=150, deadline=None)
@given(TREES, st.floats(-5, 5), st.floats(-5, 5))
def test_random_trees_match_reference(tree, x, y):
    env = {"x": np.array([x, -y, 0.5]), "y": np.float64(y)}
    with np.errstate(all="ignore"):
        expected = reference(tree, env)
    result = compile_expression(render(tree), names=["x", "y"])(**env)
    np.testing.assert_array_equal(result, expected)  # same operations, same bits


def test_a_sweep_compiles_each_text_once():
    from odelab.expressions import compile_expression
    from odelab.expressions.constants import evaluate_parameters

    a = compile_expression("k/m + t", names=["k", "m", "t"])
    assert compile_expression("k/m + t", names=["k", "m", "t"]) is a
    assert compile_expression("k/m + t", names=["k", "m", "t", "b"]) is not a  # other names: its own entry
    assert a(k=6.0, m=2.0, t=1.0) == 4.0
    first = evaluate_parameters({"m": 2, "k": "m*3"})
    first["k"] = -1.0  # the caller's copy: the next case gets the true values
    assert evaluate_parameters({"m": 2, "k": "m*3"}) == {"m": 2.0, "k": 6.0}
    assert evaluate_parameters({"m": 2.5, "k": "m*3"}) == {"m": 2.5, "k": 7.5}
