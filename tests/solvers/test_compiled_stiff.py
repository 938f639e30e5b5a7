"""The compiled ode23s and ode15s take the Python path's steps, with its statistics and values.

The Python path is what an experiment's stiff case runs: :func:`odelab.solve` with the exact
Jacobian of the equations (``complex_step_jacobian``); the compiled path generates the same
Jacobian and calls the same LAPACK routines. Problems: Robertson, HIRES (Hairer & Wanner's
test set), van der Pol with mu = 1000 and a chain of masses with stiff springs and dampers.
"""

import numpy as np
import pytest

import odelab
from odelab.exceptions import InputError
from odelab.expressions import compile_vector
from odelab.solvers.compiled import CompiledSystem, solve_compiled
from odelab.solvers.compiled.stiff import STIFF_METHODS, why_not_stiff
from odelab.systems.jacobian import complex_step_jacobian

EPS = np.finfo(float).eps


def _chain(n):
    """n masses between a wall and a free end, springs k and dampers c, a unit force on the last."""
    states = [f"x{i}" for i in range(n)] + [f"v{i}" for i in range(n)]
    equations = [f"v{i}" for i in range(n)]
    for i in range(n):
        left_x, right_x = (f"x{i - 1}" if i else "0"), (f"x{i + 1}" if i < n - 1 else f"x{i}")
        left_v, right_v = (f"v{i - 1}" if i else "0"), (f"v{i + 1}" if i < n - 1 else f"v{i}")
        equations.append(f"k*({left_x} - 2*x{i} + {right_x}) + c*({left_v} - 2*v{i} + {right_v})"
                         + (" + 1" if i == n - 1 else ""))
    return states, equations


CHAIN = _chain(10)
PROBLEMS = {
    "robertson": (["y1", "y2", "y3"], ["-0.04*y1 + 1e4*y2*y3", "0.04*y1 - 1e4*y2*y3 - 3e7*y2^2", "3e7*y2^2"], {},
                  [0, 0.4, 4, 40, 400, 4e3, 4e4, 4e5, 4e6, 4e8, 4e10], [1, 0, 0],
                  dict(rtol=1e-4, atol=[1e-8, 1e-14, 1e-8])),
    "hires": ([f"y{i}" for i in range(1, 9)],
              ["-1.71*y1 + 0.43*y2 + 8.32*y3 + 0.0007", "1.71*y1 - 8.75*y2", "-10.03*y3 + 0.43*y4 + 0.035*y5",
               "8.32*y2 + 1.71*y3 - 1.12*y4", "-1.745*y5 + 0.43*y6 + 0.43*y7",
               "-280*y6*y8 + 0.69*y4 + 1.71*y5 - 0.43*y6 + 0.69*y7", "280*y6*y8 - 1.81*y7", "-280*y6*y8 + 1.81*y7"],
              {}, [0, 321.8122], [1, 0, 0, 0, 0, 0, 0, 0.0057], dict(rtol=1e-4, atol=1e-7)),
    "vdp": (["x", "v"], ["v", "mu*(1 - x^2)*v - x"], {"mu": 1000.0}, [0, 3000], [2, 0], {}),
    "chain": (*CHAIN, {"k": 1e4, "c": 1e3}, list(np.linspace(0, 10, 101)), [0.0] * 20, dict(rtol=1e-4, atol=1e-7)),
}


def _both(name, method, **extra):
    states, equations, parameters, tspan, y0, options = PROBLEMS[name]
    options = {**options, **extra}
    system = CompiledSystem.from_equations(states, equations, parameters)
    F = compile_vector(equations, args=["t", *states], constants=parameters)
    jacobian = complex_step_jacobian(equations, states, parameters)
    python = odelab.solve(lambda t, x: F(t, *x), tspan, y0, method=method, jacobian=jacobian, **options)
    compiled = solve_compiled(system, tspan, y0, method, jacobian=jacobian, **options)
    return python, compiled


def assert_same(python, compiled, ulps):
    """Same steps and counters (every field of MATLAB's Stats), same output times, values within
    ``ulps`` spacings of the solution's scale."""
    assert compiled.stats == python.stats
    assert (compiled.status, compiled.message) == (python.status, python.message)
    assert compiled.t.shape == python.t.shape and compiled.y.shape == python.y.shape
    np.testing.assert_array_equal(compiled.t, python.t)
    scale = np.max(np.abs(python.y), axis=0)
    assert np.all(np.abs(compiled.y - python.y) <= ulps * EPS * scale)


@pytest.mark.parametrize("name", list(PROBLEMS))
def test_ode23s_takes_the_python_steps(name):
    python, compiled = _both(name, "ode23s")
    assert python.stats.nsteps > 100 and python.stats.npds == python.stats.nsteps  # a Jacobian a step
    assert_same(python, compiled, 4)  # the same operations in the same order: equal to the bit here


@pytest.mark.parametrize("name", list(PROBLEMS))
def test_ode15s_takes_the_python_steps(name):
    python, compiled = _both(name, "ode15s")
    assert python.stats.nsteps > 100 and python.stats.npds < python.stats.nsteps / 5  # Jacobians kept
    assert python.stats.nfailed > 0  # failed steps and Newton failures are taken the same way
    assert_same(python, compiled, 4)  # numpy's BLAS calls made with its arguments: equal to the bit here


@pytest.mark.parametrize("options", [{"refine": 4}, {"max_order": 2}, {"bdf": True}, {"initial_step": 1e-6},
                                     {"max_step": 20.0, "atol": [1e-7, 1e-5]}])
def test_ode15s_options_match(options):
    python, compiled = _both("vdp", "ode15s", **options)
    assert_same(python, compiled, 4)


def test_ode15s_interpolates_the_tspan_grid_as_on_python():
    states, equations, parameters, *_ = PROBLEMS["hires"]
    tspan = list(np.linspace(0, 321.8122, 400))  # several output times inside one step
    system = CompiledSystem.from_equations(states, equations, parameters)
    F = compile_vector(equations, args=["t", *states], constants=parameters)
    J = complex_step_jacobian(equations, states, parameters)
    y0, options = PROBLEMS["hires"][4], PROBLEMS["hires"][5]
    python = odelab.solve(lambda t, x: F(t, *x), tspan, y0, method="ode15s", jacobian=J, **options)
    compiled = solve_compiled(system, tspan, y0, "ode15s", jacobian=J, **options)
    assert python.t.size == 400 and python.stats.nsteps < 400
    assert_same(python, compiled, 4)


def test_the_compiled_products_sum_as_the_python_path_does_bit_for_bit():
    """The compiled loops' products are odelab.solvers.ordered's sums, no BLAS on either path."""
    from odelab.solvers.compiled.cache import load_kernels
    from odelab.solvers.ordered import backwards, combine, matmul, matvec

    kernels = load_kernels()
    rng = np.random.default_rng(3)
    for k, n in [(1, 3), (3, 5), (5, 200), (6, 8)]:
        A = rng.standard_normal((n, k)) * 10.0 ** rng.integers(-4, 4, (n, k))
        B = rng.standard_normal((k, n)) * 10.0 ** rng.integers(-4, 4, (k, n))
        g, x = rng.standard_normal(k), rng.standard_normal(k)
        out = np.empty(n)
        kernels._vecmat(g, B, out)
        assert np.array_equal(out, backwards(g).dot(B[None])[0]) and np.array_equal(out, combine(g, B))
        kernels._matvec(A, x, out)
        assert np.array_equal(out, matvec(A, x))
        C = np.empty((n, n))
        kernels._matmul(A, B, C)
        assert np.array_equal(C, matmul(A, B))
        R = rng.standard_normal((k, k))
        T = np.empty((k, n))
        kernels._matmul(R, B, T, True)
        assert np.array_equal(T, matmul(R.T, B))


@pytest.mark.parametrize("options", [{"refine": 4}, {"initial_step": 1e-6, "max_step": 50.0},
                                     {"atol": [1e-7, 1e-5]}])
def test_ode23s_options_match(options):
    python, compiled = _both("vdp", "ode23s", **options)
    assert_same(python, compiled, 4)


def test_ode23s_step_limit_fails_as_on_python():
    with pytest.warns(odelab.SolverWarning, match="max_steps = 60"):
        python, compiled = _both("vdp", "ode23s", max_steps=60)
    assert_same(python, compiled, 4)
    assert compiled.status == "failed" and compiled.stats.nsteps == 60


@pytest.mark.parametrize("tspan", [[0.0, 5.0], list(np.linspace(0, 5, 23))])
def test_ode23s_on_a_tspan_grid(tspan):
    states, equations, parameters, *_ = PROBLEMS["hires"]
    system = CompiledSystem.from_equations(states, equations, parameters)
    F = compile_vector(equations, args=["t", *states], constants=parameters)
    J = complex_step_jacobian(equations, states, parameters)
    y1 = [0.7, 0.1, 0.05, 0.1, 0.01, 0.3, 0.001, 0.005]
    python = odelab.solve(lambda t, x: F(t, *x), tspan, y1, method="ode23s", jacobian=J, rtol=1e-5)
    compiled = solve_compiled(system, tspan, y1, "ode23s", jacobian=J, rtol=1e-5)
    assert_same(python, compiled, 4)


def test_ode23s_backwards():
    """Stiff backwards in time (the damping has the sign that decays towards t = 0)."""
    system = CompiledSystem.from_equations(["x", "y"], ["-w*y", "w*x + 50*(y - sin(t))"], {"w": 2.0})
    F = compile_vector(["-2*y", "2*x + 50*(y - sin(t))"], args=["t", "x", "y"])
    J = complex_step_jacobian(["-w*y", "w*x + 50*(y - sin(t))"], ["x", "y"], {"w": 2.0})
    python = odelab.solve(lambda t, x: F(t, *x), [6.0, 0.0], [1.0, 0.0], method="ode23s", jacobian=J, refine=3)
    compiled = solve_compiled(system, [6.0, 0.0], [1.0, 0.0], "ode23s", jacobian=J, refine=3)
    assert python.t[-1] == 0.0 and python.stats.nsteps > 20
    assert compiled.stats == python.stats
    scale = np.max(np.abs(python.y))
    assert np.max(np.abs(compiled.y - python.y)) <= 1e3 * EPS * scale  # sin: numpy's and the C library's


def test_linear_systems_use_their_matrix():
    A = np.array([[-1000.0, 1.0], [0.0, -0.5]])
    system = CompiledSystem.linear(A, ["a", "b"])
    def fun(t, x):  # A x summed in index order, as the generated rhs sums it (A @ x is BLAS's order)
        return np.array([A[0, 0] * x[0] + A[0, 1] * x[1], A[1, 0] * x[0] + A[1, 1] * x[1]])

    python = odelab.solve(fun, [0, 10], [1.0, 1.0], method="ode23s", jacobian=A)
    compiled = solve_compiled(system, [0, 10], [1.0, 1.0], "ode23s", jacobian=A)
    assert_same(python, compiled, 4)
    tight = solve_compiled(system, [0, 10], [1.0, 1.0], "ode23s", rtol=1e-7, atol=1e-12)
    b = np.exp(-5.0)  # b(10); a(t) = b/(1000 - 0.5) + (1 - 1/999.5) e^(-1000 t)
    assert abs(tight.y[-1, 1] - b) < 1e-4 * b  # second order, local error control: ~200 steps of 1e-7
    assert abs(tight.y[-1, 0] - b / 999.5) < 1e-4 * b / 999.5


def test_the_generated_jacobian_is_the_python_paths():
    """The same complex-step rules; the elementary functions are the C library's where numpy
    may use its own SIMD versions (on AVX-512), so an entry may differ by a rounding."""
    states = ["a", "b"]
    equations = ["sin(a)*exp(b)/(1 + a^2) + t/3 + abs(b) + sqrt(a*a + 1) + atan2(a, b) + min(a, b, 2) + mod(a, 0.7)",
                 "log(1 + a*a)/b + where(a > b, a, b) + tanh(b) + a/b + heaviside(a) + cos(t)*a^2.5 + 2^b"]
    system = CompiledSystem.from_equations(states, equations)
    jac = system.module(jacobian=True).jac
    reference = complex_step_jacobian(equations, states, {})
    rng = np.random.default_rng(7)
    for _ in range(20):
        y, t = rng.uniform(0.1, 2.0, 2), rng.uniform(0.0, 3.0)
        J = np.zeros((2, 2))
        jac(t, y, system.parameter_vector(), J)
        expected = reference(t, y)  # sums of terms of size ~1: a rounding of one term, against that size
        np.testing.assert_allclose(J, expected, rtol=4 * EPS, atol=8 * EPS * np.max(np.abs(expected)))


def test_what_stays_on_python_is_named():
    system = CompiledSystem.from_equations(["x", "v"], ["v", "-x"])
    assert why_not_stiff("ode23t", system) is not None and "ode23t" in why_not_stiff("ode23t", system)
    assert "`mass`" in why_not_stiff("ode23s", system, {"mass": np.eye(2)})
    assert "`jpattern`" in why_not_stiff("ode23s", system, {"jpattern": np.eye(2)})
    assert "Python function" in why_not_stiff("ode23s", system, {"jacobian": lambda t, y: np.eye(2)})
    inputs = CompiledSystem.from_system(["x"], ["-x + u"], inputs=["u"])
    assert "inputs" in why_not_stiff("ode23s", inputs)
    diagram = CompiledSystem.generated(["x"], [], ["    _out[0] = -_y[0]"], [])
    assert "diagrams" in why_not_stiff("ode23s", diagram)
    with_events = system.with_events(["x"], [True], [0])
    assert "[events]" in why_not_stiff("ode23s", with_events)
    with pytest.raises(InputError, match="`events`"):
        solve_compiled(system, [0, 1], [1.0, 0.0], "ode23s", events=lambda t, y: y[0])
    assert all(why_not_stiff(m, system) is None for m in STIFF_METHODS)


def _brusselator(points, alpha=0.02):
    """Hairer & Wanner's 1-D Brusselator (u = 1, v = 3 at both ends), u before v: banded only once
    the states are permuted."""
    u = [f"u{i}" for i in range(points)]
    v = [f"v{i}" for i in range(points)]

    def around(names, i, wall):
        return (names[i - 1] if i else wall), (names[i + 1] if i < points - 1 else wall)

    equations = [f"1 + u{i}^2*v{i} - 4*u{i} + d*({around(u, i, '1')[0]} - 2*u{i} + {around(u, i, '1')[1]})"
                 for i in range(points)]
    equations += [f"3*u{i} - u{i}^2*v{i} + d*({around(v, i, '3')[0]} - 2*v{i} + {around(v, i, '3')[1]})"
                  for i in range(points)]
    y0 = [1 + np.sin(2 * np.pi * (i + 1) / (points + 1)) for i in range(points)] + [3.0] * points
    return u + v, equations, {"d": alpha * (points + 1) ** 2}, y0


PROBLEMS["brusselator"] = (*_brusselator(12)[:3], [0, 10], _brusselator(12)[3], dict(rtol=1e-6, atol=1e-6))


@pytest.mark.parametrize("method", STIFF_METHODS)
@pytest.mark.parametrize("name", ["chain", "brusselator"])
def test_banded_systems_take_the_python_steps_to_the_bit(name, method):
    """Both paths permute the iteration matrix to its band and call LAPACK's dgbtrf/dgbtrs."""
    from odelab.solvers.compiled.stiff import _band_of

    states, equations, parameters, *_ = PROBLEMS[name]
    perm, kl, ku = _band_of(CompiledSystem.from_equations(states, equations, parameters))
    assert perm.size == len(states) and kl + ku <= 6
    python, compiled = _both(name, method)
    assert python.stats.nsteps > 50 and python.stats.nfailed + python.stats.npds > 1
    assert compiled.stats == python.stats
    np.testing.assert_array_equal(compiled.t, python.t)
    np.testing.assert_array_equal(compiled.y, python.y)


def test_small_systems_factor_dense():
    from odelab.solvers.compiled.stiff import _band_of

    for name in ("robertson", "hires", "vdp"):
        states, equations, parameters, *_ = PROBLEMS[name]
        assert _band_of(CompiledSystem.from_equations(states, equations, parameters))[0].size == 0


def test_the_grouped_jacobian_is_the_full_complex_step_to_the_bit():
    """Structurally orthogonal columns perturbed together give each entry the same expression with
    the same inputs as its own column's complex step; entries no equation names are not written."""
    states, equations, parameters, _ = _brusselator(12)
    system = CompiledSystem.from_equations(states, equations, parameters)
    jac = system.module(jacobian=True).jac
    reference = complex_step_jacobian(equations, states, parameters)
    pattern = reference.pattern()
    assert pattern.sum() == 12 * 4 + 2 * 10 * 2 + 2 * 2 and "_JAC_WHICH" in system.source(jacobian=True)
    rng = np.random.default_rng(11)
    for _ in range(10):
        y, t = rng.uniform(0.5, 3.5, 24), rng.uniform(0.0, 10.0)
        J = np.full((24, 24), np.nan)
        jac(t, y, system.parameter_vector(), J)
        expected = reference(t, y)
        np.testing.assert_array_equal(J[pattern], expected[pattern])
        assert np.all(np.isnan(J[~pattern])) and np.all(expected[~pattern] == 0)
