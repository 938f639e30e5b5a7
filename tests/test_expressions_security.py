"""Expression language security: generated hostile input is never executed, accepted input is bounded.

A sentinel records any import of a module named in the payloads and any file they would
create; generated strings and Python snippets must either be rejected with an
ExpressionError or evaluate to numbers, and the sentinel must stay silent.
"""

import builtins
import time
import tracemalloc

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from odelab.exceptions import ExpressionError, InputError
from odelab.expressions import MAX_LENGTH, compile_expression, parse_expression

SENTINEL_MODULE = "odelab_sentinel_payload"
SENTINEL_FILE = "/tmp/odelab-sentinel-file"

HOSTILE = [
    f"__import__('{SENTINEL_MODULE}')",
    f"__builtins__.__import__('{SENTINEL_MODULE}')",
    f"open('{SENTINEL_FILE}', 'w')",
    "().__class__.__bases__[0].__subclasses__()",
    "x.__class__",
    "sin.__globals__",
    "globals()",
    "eval('1')",
    "exec('1')",
    "getattr(x, 'real')",
    "(lambda: 1)()",
    "[i for i in (1, 2)]",
    "{1: 2}",
    "f'{x}'",
    "(y := 1)",
    "x if x else 1",
    "x[0]",
    "'a' * 3",
    "b'x'",
    "not x",
    "x and 1",
    "*x",
    "sin(x=1)",
    "sin(*x)",
    "sin()()",
    "1j",
    "...",
    "x.real",
    "import os",
    "os.system('true')",
]
SAFE_PIECES = ["x", "t", "1", "2.5", "pi", "sin(x)", "exp(t)", "x^2", "(x + 1)", "abs(t)", "max(x, t)"]
OPERATORS = [" + ", " - ", " * ", " / ", "^", "**", " < ", " == ", ", ", " . ", "[", "]", "(", ")"]


@pytest.fixture()
def sentinel(monkeypatch, tmp_path):
    imported = []
    real_import = builtins.__import__

    def watching_import(name, *args, **kwargs):
        if name == SENTINEL_MODULE:
            imported.append(name)
            raise ImportError("sentinel")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", watching_import)
    import os

    if os.path.exists(SENTINEL_FILE):
        os.remove(SENTINEL_FILE)
    yield imported
    assert not os.path.exists(SENTINEL_FILE), "a payload created the sentinel file"
    assert imported == [], "a payload imported the sentinel module"


def try_everything(text: str) -> None:
    """Parse, compile and evaluate; only an ExpressionError (an InputError) may come out."""
    try:
        fn = compile_expression(text, names=["x", "t"], key="test.expr")
    except InputError:
        return
    value = fn(x=np.linspace(-2, 2, 5), t=np.linspace(0, 1, 5))
    assert np.asarray(value).dtype.kind in "fb"


@pytest.mark.parametrize("payload", HOSTILE)
def test_hostile_snippets_are_rejected(payload, sentinel):
    with pytest.raises(ExpressionError):
        compile_expression(payload, names=["x", "t"])


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.lists(st.sampled_from(HOSTILE + SAFE_PIECES + OPERATORS), min_size=1, max_size=12).map("".join))
def test_generated_snippets_never_execute(text, sentinel):
    try_everything(text)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(max_size=80))
def test_random_text_is_rejected_or_evaluates(text, sentinel):
    try_everything(text)


def worst_case_accepted():
    """Expressions near the length limit that the language accepts."""
    power = "9**" * 120 + "9"  # 121 levels deep: inside the depth limit
    sums = "+".join(["sin(x)*exp(t)"] * 140)
    return [power, sums[: MAX_LENGTH - 20].rsplit("+", 1)[0]]


@pytest.mark.parametrize("text", worst_case_accepted(), ids=["power-tower", "long-sum"])
def test_accepted_expressions_are_bounded_in_time_and_memory(text):
    parse_expression(text)  # accepted
    t = np.linspace(0, 1, 10_000)
    tracemalloc.start()
    start = time.perf_counter()
    fn = compile_expression(text, names=["x", "t"])
    value = fn(x=t, t=t)
    elapsed = time.perf_counter() - start
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert np.shape(value) in ((), (10_000,))
    # Generous bounds (a bound, not a benchmark): linear in length x points.
    assert elapsed < 5.0 and peak < 200e6


def test_the_sentinel_is_live(sentinel):
    # Plain Python runs the first payload, and the sentinel sees it: the tests above can fail.
    with pytest.raises(ImportError):
        eval(HOSTILE[0])
    assert sentinel == [SENTINEL_MODULE]
    sentinel.clear()
