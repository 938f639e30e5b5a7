"""MATLAB's mod, rem, square and sawtooth in the expression language: values as MATLAB/Octave
print them, exact complex-step derivatives, and the compiled backend equal to the Python one."""

import math

import numpy as np
import pytest

from odelab.exceptions import ExpressionError
from odelab.expressions import compile_expression


def value(text, **names):
    return compile_expression(text, names=list(names))(**names)


# Octave 8's mod and rem (the same definitions as MATLAB's): mod has the divisor's sign and
# mod(a, 0) = a; rem has the dividend's sign and rem(a, 0) = NaN.
@pytest.mark.parametrize(("a", "m", "mod", "rem"), [
    (-1.5, 2, 0.5, -1.5), (5.5, 2, 1.5, 1.5), (3, 0, 3.0, math.nan), (-7, -3, -1.0, -1.0), (7, -3, -2.0, 1.0),
])
def test_mod_and_rem_are_matlabs(a, m, mod, rem):
    assert value("mod(a, m)", a=float(a), m=float(m)) == mod
    got = value("rem(a, m)", a=float(a), m=float(m))
    assert (math.isnan(got) and math.isnan(rem)) or got == rem


def test_square_and_sawtooth_follow_matlabs_definitions():
    t = np.linspace(0, 4 * np.pi, 9)  # quarter periods
    np.testing.assert_array_equal(value("square(t)", t=t), [1, 1, -1, -1, 1, 1, -1, -1, 1])
    np.testing.assert_array_equal(value("square(t, 25)", t=t), [1, -1, -1, -1, 1, -1, -1, -1, 1])
    np.testing.assert_allclose(value("sawtooth(t)", t=t), [-1, -0.5, 0, 0.5, -1, -0.5, 0, 0.5, -1], atol=4e-16)
    np.testing.assert_allclose(value("sawtooth(t, 0.5)", t=t), [-1, 0, 1, 0, -1, 0, 1, 0, -1], atol=4e-16)


def test_the_arguments_are_counted():
    with pytest.raises(ExpressionError, match="`square` takes 1 or 2 arguments; got 3"):
        compile_expression("square(t, 50, 1)", names=["t"])
    with pytest.raises(ExpressionError, match="`mod` takes 2 arguments; got 1"):
        compile_expression("mod(t)", names=["t"])


def test_complex_step_derivatives_are_the_slopes_between_jumps():
    h = 1e-30
    f = compile_expression("mod(x, 0.7) + rem(2*x, 0.3) + sawtooth(x, 0.25) + square(x)", names=["x"],
                           complex_step=True)
    for x in (0.1, 1.3, 2.9, -0.4):
        slope = 1 + 2 + (1 / (math.pi * 0.25) if x % (2 * math.pi) < 2 * math.pi * 0.25 else -1 / (math.pi * 0.75))
        assert np.imag(f(x=x + 1j * h)) / h == pytest.approx(slope, rel=1e-15)
    g = compile_expression("mod(1.9, m)", names=["m"], complex_step=True)
    assert np.imag(g(m=0.5 + 1j * h)) / h == -3.0  # d/dm (a - floor(a/m) m) = -floor(a/m)


def test_the_compiled_backend_gives_the_python_engines_steps(tmp_path):
    from odelab.experiment.loader import load_experiment
    from odelab.run.runner import run_case

    path = tmp_path / "wave.toml"
    path.write_text('[system]\nstates = ["x"]\n[system.equations]\n'
                    'x = "square(t, 30) + 0.5*sawtooth(3*t, 0.5) - mod(t, 1.5)*x + rem(t, 0.7)"\n'
                    '[initial]\nx = 0\n[time]\nstop = 20\n[reference]\nmethod = "none"\n')
    case = load_experiment(path).cases[0]
    python = run_case(case, backend="python")
    compiled = run_case(case, backend="compiled")
    assert compiled.backend == "compiled" and python.status == compiled.status == "success"
    assert python.stats.nsteps == compiled.stats.nsteps
    # The engines agree to round-off on smooth right-hand sides; here a stage that lands within
    # round-off of a jump may take the other side's value on one engine, and both steps pass the
    # error test: the solutions then agree to the tolerance (rtol 1e-3), not to round-off.
    np.testing.assert_allclose(compiled.x, python.x, rtol=0, atol=1e-3 * np.abs(python.x).max())


def test_the_compiled_helpers_equal_the_python_functions_to_the_bit():
    from odelab.expressions.functions import FUNCTIONS
    from odelab.solvers.compiled.codegen import PRELUDE

    namespace: dict = {}
    exec(compile(PRELUDE.replace("cache=True", "cache=False"), "<prelude>", "exec"), namespace)
    rng = np.random.default_rng(7)
    for a, m in zip(rng.uniform(-20, 20, 300), [*rng.uniform(-3, 3, 290), *([0.0] * 10)]):
        assert namespace["_mod"](a, m) == FUNCTIONS["mod"](a, m)
        got, want = namespace["_rem"](a, m), FUNCTIONS["rem"](a, m)
        assert got == want or (math.isnan(got) and math.isnan(want))
        assert namespace["_square"](a, 37.5) == FUNCTIONS["square"](a, 37.5)
        assert namespace["_sawtooth"](a, 0.3) == FUNCTIONS["sawtooth"](a, 0.3)
        assert namespace["_sawtooth"](a) == FUNCTIONS["sawtooth"](a)
