"""The compiled backend takes the Python engine's steps and gives its values to round-off."""

from pathlib import Path

import numpy as np
import pytest

import odelab
from odelab.exceptions import InputError
from odelab.expressions import compile_vector
from odelab.run.backend import simulate_problem
from odelab.solvers.compiled.capability import why_not_compiled
from odelab.experiment.loader import load_experiment, load_experiments
from odelab.run.runner import run_case
from odelab.solvers.compiled import AUTO_STEPS, CompiledSystem, solve_compiled
from odelab.solvers.registry import get_method

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted((ROOT / "experiments").glob("*.toml"))
RIGID = CompiledSystem.from_equations(["y1", "y2", "y3"], ["y2*y3", "-y1*y3", "a*y1*y2"], {"a": -0.51})


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def assert_same_run(a, b, rtol, atol):
    """Same steps, same output times, values equal to round-off in units of the tolerance."""
    assert a.stats == b.stats
    assert a.status == b.status and a.message == b.message
    assert a.t.shape == b.t.shape and a.y.shape == b.y.shape
    np.testing.assert_allclose(a.t, b.t, rtol=1e-9, atol=1e-12)  # see the shipped-case test
    # round-off accumulated over the run, relative to the size of the solution (a different step
    # would differ by about the tolerance, 1e-6 here, not 1e-10)
    assert np.max(np.abs(a.y - b.y)) < 1e-9 * max(1.0, np.max(np.abs(b.y)))


def _shipped():
    """(path, experiment index, case index, case) of every shipped case; of a study's sweep (which
    re-runs the lab's systems with many settings) the first and the last case of each problem."""
    for path in SHIPPED:
        for i, exp in enumerate(load_experiments(path)):
            picks = range(len(exp.cases)) if exp.sweep is None else sorted({0, len(exp.cases) - 1})
            for j in picks:
                yield path, i, j, exp.cases[j]


def _why_python(case):
    p = case.problem
    return why_not_compiled(get_method(p.method), p.system.compiled, p.options)


def compiled_cases():
    return [pytest.param(path, i, j, id=f"{path.stem}-{i}-{case.name}") for path, i, j, case in _shipped()
            if _why_python(case) is None]


@pytest.mark.parametrize("path, i, j", compiled_cases())
def test_every_shipped_case_runs_the_same_steps_compiled(path, i, j):
    case = load_experiments(path)[i].cases[j]
    p = case.problem
    if p.linearize is not None:  # the nonlinear model's response, which the linearisation study compares
        options = dict(p.options)
        python, _ = simulate_problem(p, p.tspan, p.method, options, "python")
        compiled, ran = simulate_problem(p, p.tspan, p.method, options, "compiled")
        assert ran == "compiled"
    else:
        python = run_case(case, backend="python")
        compiled = run_case(case, backend="compiled")
        assert (python.backend, compiled.backend) == ("python", "compiled")
        assert [(e["name"], e["occurrence"]) for e in compiled.events] == [(e["name"], e["occurrence"])
                                                                            for e in python.events]
        for ec, ep in zip(compiled.events, python.events):  # the bouncing ball's bounces
            assert ec["t"] == pytest.approx(ep["t"], rel=1e-12)
        if python.event_marks is not None:
            np.testing.assert_array_equal(compiled.event_marks, python.event_marks)
        for q, e in python.errors.items():  # the error tables print the same 4 digits
            assert compiled.errors[q].max_rel == pytest.approx(e.max_rel, rel=1e-4, abs=1e-12)
    assert compiled.stats == python.stats
    assert (compiled.status, compiled.message) == (python.status, python.message)
    assert compiled.t.shape == python.t.shape
    # The next step size is a power of the error estimate, a sum with cancellation: the last
    # bits of its sum order (numpy's BLAS versus the compiled loop) move the step by ~1e-12
    # relative at the lab's tolerances, ~1e-9 at the linearisation's rtol 1e-8 (the error estimate
    # is then itself near round-off); the values follow, to 1e-12..2e-10 of the solution's size.
    span = abs(float(python.t[-1] - python.t[0]))
    np.testing.assert_allclose(compiled.t, python.t, rtol=0, atol=1e-8 * span)
    size = np.maximum(1.0, np.max(np.abs(python.x), axis=0))
    assert np.max(np.abs(compiled.x - python.x) / size) < 1e-9
    if python.u is not None:  # read at those times
        np.testing.assert_allclose(compiled.u, python.u, rtol=1e-9, atol=1e-12)


def test_the_shipped_cases_left_on_python_are_the_documented_ones():
    """README, "The compiled engine": what stays on the Python path, and why."""
    left = {(path.stem, _why_python(case).split(",")[0].split(":")[0]) for path, _, _, case in _shipped()
            if _why_python(case) is not None}
    assert left == {
        ("stiff", "it runs odelab's explicit Runge-Kutta methods (ode23"),  # Radau
        ("stiff", "the compiled stiff solvers are ode23s"),  # ode23t, ode23tb ("ode23s, ode15s: ...")
        ("work-precision", "it runs odelab's explicit Runge-Kutta methods (ode23"),  # SciPy's RK45, DOP853...
        # the saturation's zero crossings are located on the Python path (diagrams, d5a4ce6)
        ("feedback_pi", "its block `actuator` (saturation) has zero crossings located by the Python driver "
                        "(zero_crossing = false on it compiles it)"),
        # issue 21's sampled-data loop and relay: the hybrid driver runs them
        ("speed_control", "its block `sampler` (zero-order-hold) is discrete (sample time 0.05)"),
        ("thermostat", "its block `heater` (relay) switches with memory"),  # ", run by the Python driver"
        ("delayed_feedback", "it solves ordinary differential equations"),  # dde23 runs on the Python path
    }


def test_the_shipped_lab_has_compiled_cases():
    names = {path.stem for path, _, _, case in _shipped() if _why_python(case) is None}
    assert names == {"bouncing_ball", "convergence", "cooling_fit", "damping", "exercise1", "exercise1_2pi", "exercise2", "figure1", "msd_fit",
                     "linearisation", "rigid_body", "stiff", "work-precision"}  # feedback_pi: see above


@pytest.mark.parametrize("method", ["ode23", "ode45"])
@pytest.mark.parametrize("options", [
    {},
    {"refine": 1},
    {"refine": 7},
    {"atol": [1e-8, 1e-9, 1e-10]},
    {"norm_control": True, "atol": 1e-8},
    {"initial_step": 1e-3, "max_step": 0.5},
])
@pytest.mark.parametrize("tspan", [[0, 60], list(np.linspace(0, 60, 97)), [60, 0]])
def test_rigid_body_options_match_the_python_engine(method, options, tspan):
    a = solve_compiled(RIGID, tspan, [0, 1, 1], method, rtol=1e-6, **options)
    b = odelab.solve(rigid, tspan, [0, 1, 1], method, rtol=1e-6, **options)
    assert_same_run(a, b, 1e-6, options.get("atol", 1e-6) if not isinstance(options.get("atol"), list)
                    else np.array(options["atol"]))
    if len(tspan) > 2:
        np.testing.assert_array_equal(a.t, np.asarray(tspan, dtype=float))


def test_matlab_rigid_body_stats():
    sol = solve_compiled(RIGID, [0, 12], [0, 1, 1], "ode45", RelTol=1e-4, AbsTol=[1e-4, 1e-4, 1e-5])
    assert (sol.stats.nsteps, sol.stats.nfailed, sol.stats.nfevals) == (21, 0, 127)
    assert sol.t.size == 85


def test_long_run_fills_block_after_block():
    from odelab.solvers.compiled import rows

    a = solve_compiled(RIGID, [0, 1200], [0, 1, 1], "ode45", rtol=1e-6, atol=1e-9)
    b = odelab.solve(rigid, [0, 1200], [0, 1, 1], "ode45", rtol=1e-6, atol=1e-9)
    assert a.stats == b.stats and a.t.size == 4 * a.stats.nsteps + 1
    np.testing.assert_allclose(a.t, b.t, rtol=1e-9)
    assert rows.block_rows(3, 4) == 65536 and rows.block_rows(3000, 4) == 87 and rows.block_rows(10**6, 8) == 9
    # the loop stopped and resumed at every block: blocks of 7 rows (a step's 4 rows fit once each), same bits
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rows, "BLOCK_BYTES", 8 * 4 * 7)
        c = solve_compiled(RIGID, [0, 1200], [0, 1, 1], "ode45", rtol=1e-6, atol=1e-9)
        d = solve_compiled(OSCILLATOR, [0, 150], [1.0, 0.0], "ode45", rtol=1e-6, atol=1e-9)  # events across blocks
    assert c.stats == a.stats and c.status == a.status and c.message == a.message
    np.testing.assert_array_equal(c.t, a.t)
    np.testing.assert_array_equal(c.y, a.y)
    e = solve_compiled(OSCILLATOR, [0, 150], [1.0, 0.0], "ode45", rtol=1e-6, atol=1e-9)
    assert d.te.size == 72 and d.stats == e.stats
    for got, want in ((d.ie, e.ie), (d.te, e.te), (d.ye, e.ye), (d.t, e.t), (d.y, e.y)):
        np.testing.assert_array_equal(got, want)


class _ListSink:
    """A spool in memory (odelab.store.spool.Spool's protocol): the blocks handed to it, copied."""

    def __init__(self):
        self.blocks, self.rows = [], 0

    def append(self, t, y):
        self.blocks.append((t.copy(), y.copy()))
        self.rows += t.size

    def arrays(self):
        return np.concatenate([t for t, _ in self.blocks]), np.concatenate([y for _, y in self.blocks])


def test_full_blocks_go_to_the_sink_and_the_rows_are_its():
    from odelab.solvers.compiled import rows

    a = solve_compiled(RIGID, [0, 1200], [0, 1, 1], "ode45", rtol=1e-6, atol=1e-9)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rows, "BLOCK_BYTES", 8 * 4 * 7)  # blocks of 7 rows: whole steps of 4 rows, 5 with the first
        sink, events = _ListSink(), _ListSink()
        c = solve_compiled(RIGID, [0, 1200], [0, 1, 1], "ode45", rtol=1e-6, atol=1e-9, rows_to=sink)
        d = solve_compiled(OSCILLATOR, [0, 150], [1.0, 0.0], "ode45", rtol=1e-6, atol=1e-9, rows_to=events)
    assert [t.size for t, _ in sink.blocks[:3]] == [5, 4, 4] and sink.rows == a.t.size
    assert c.stats == a.stats and c.status == a.status and c.message == a.message
    np.testing.assert_array_equal(c.t, a.t)
    np.testing.assert_array_equal(c.y, a.y)
    e = solve_compiled(OSCILLATOR, [0, 150], [1.0, 0.0], "ode45", rtol=1e-6, atol=1e-9)
    assert d.te.size == 72 and d.stats == e.stats and events.rows == e.t.size
    for got, want in ((d.ie, e.ie), (d.te, e.te), (d.ye, e.ye), (d.t, e.t), (d.y, e.y)):
        np.testing.assert_array_equal(got, want)
    untouched = _ListSink()  # one block holds the whole run: nothing goes to the sink
    f = solve_compiled(RIGID, [0, 1200], [0, 1, 1], "ode45", rtol=1e-6, atol=1e-9, rows_to=untouched)
    assert untouched.rows == 0 and not untouched.blocks and f.t.flags.owndata
    np.testing.assert_array_equal(f.y, a.y)


def test_joined_blocks_are_the_rows_in_order():
    from odelab.solvers.compiled.rows import joined, new_block

    blocks = []
    for k, count in enumerate((5, 3, 0, 5)):
        t, y = new_block(5, 2)
        t[:count] = 10 * k + np.arange(count)
        y[:count] = (10 * k + np.arange(count))[:, None] * [1, -1]
        blocks.append((t, y, count))
    t, y = joined(blocks, 2)
    want = np.array([0, 1, 2, 3, 4, 10, 11, 12, 30, 31, 32, 33, 34], dtype=float)
    assert not blocks and t.flags.owndata and y.shape == (13, 2)
    np.testing.assert_array_equal(t, want)
    np.testing.assert_array_equal(y, want[:, None] * [1, -1])
    t, y = new_block(4, 3)
    t[:] = 1.0
    one = [(t, y, 2)]
    del t, y
    t, y = joined(one, 3)
    assert t.size == 2 and y.shape == (2, 3) and t.base is None  # a row count of its own, not the block's


@pytest.mark.parametrize("method", ["euler", "rk4"])
def test_fixed_step_methods(method):
    tspan = [0, 10]
    a = solve_compiled(RIGID, tspan, [0, 1, 1], method, h=0.01)
    b = odelab.solve(rigid, tspan, [0, 1, 1], method, h=0.01)
    assert a.stats == b.stats == odelab.solution.Stats(1000, 0, 1000 * (1 if method == "euler" else 4))
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_allclose(a.y, b.y, rtol=1e-12, atol=1e-14)
    c = solve_compiled(RIGID, np.linspace(0, 10, 11), [0, 1, 1], method, h=0.3)
    d = odelab.solve(rigid, np.linspace(0, 10, 11), [0, 1, 1], method, h=0.3)
    np.testing.assert_array_equal(c.t, d.t)
    np.testing.assert_allclose(c.y, d.y, rtol=1e-12, atol=1e-14)


def test_failures_give_the_python_engine_messages():
    blowup = CompiledSystem.from_equations(["y"], ["y^2 + sqrt(c)"], {"c": 0.0})
    with pytest.warns(odelab.SolverWarning, match="finite-time blow-up"):
        a = solve_compiled(blowup, [0, 2], [1.0], "ode45")
    with pytest.warns(odelab.SolverWarning):
        b = odelab.solve(lambda t, y: y**2, [0, 2], [1.0], "ode45")
    assert a.status == b.status == "failed"
    assert a.stats == b.stats and a.message == b.message
    assert "failed at t = 0.9999" in a.message and "finite-time blow-up" in a.message
    with pytest.warns(odelab.SolverWarning):
        stopped = solve_compiled(RIGID, [0, 100], [0, 1, 1], "ode45", max_steps=7)
    assert stopped.stats.nsteps == 7 and "after max_steps = 7 steps" in stopped.message
    with pytest.warns(odelab.SolverWarning):
        nan = solve_compiled(CompiledSystem.from_equations(["y"], ["y^2 + sqrt(c)"], {"c": -1.0}), [0, 1], [1.0], "ode23")
    assert nan.status == "failed" and nan.message == ("ode23 could not start: the derivative at t = 0 is not finite "
                                                      "([nan]): check the right-hand side at the initial state.")


def test_every_function_of_the_language_matches_numpy():
    texts = ["sin(X) + cos(Y) - tan(X/3)", "asin(X/4) + acos(-X/5) + atan(Y) + atan2(X, Y)",
             "sinh(X/2) * cosh(Y/3) / tanh(X + 0.1)", "exp(-X) + log(abs(Y)) + log10(abs(X) + 1) + sqrt(abs(Y))",
             "sign(X) + floor(Y) + ceil(X) + heaviside(X) + step(Y)", "min(X, Y, 0.5) + max(X, Y) + where(X > Y, X, Y)",
             "(0 < X < 1) + (X >= Y) + (X == Y) + (X != 0) + X^2 - Y**3 + 2^X", "1/X + X/0 + (-1)^0.5 + pi + e"]
    texts = [t.replace("X", "s0").replace("Y", "s1") for t in texts]
    system = CompiledSystem.from_equations([f"s{i}" for i in range(len(texts))], texts)
    F = compile_vector(texts, args=["t", *(f"s{i}" for i in range(len(texts)))])
    module = system.module()
    rng = np.random.default_rng(1)
    samples = [*rng.uniform(-3, 3, (200, 2)), (0.0, 0.0), (1.0, 1.0), (-0.0, 2.0), (np.nan, 1.0), (np.inf, -1.0)]
    for x, y in samples:
        state = np.zeros(len(texts))
        state[:2] = x, y
        out = np.empty(len(texts))
        module.rhs(0.0, state, np.zeros(0), out)
        np.testing.assert_allclose(out, F(0.0, *state), rtol=1e-13, atol=1e-15, equal_nan=True)


def test_the_cache_is_keyed_by_the_generated_text(compiled_cache):
    same = CompiledSystem.from_equations(["y1", "y2", "y3"], ["y2*y3", "-y1*y3", "a*y1*y2"], {"a": 2.0})
    assert same.module() is RIGID.module()  # parameter values are run-time data: one build
    other = CompiledSystem.from_equations(["y"], ["-2*y^2"])
    source = other.source()
    assert "    _out[0] = ((-2.0) * _pow(y, 2.0))\n" in source  # C's pow, as numpy's scalar **
    assert other.module() is not RIGID.module()
    files = sorted((compiled_cache / "compiled").glob("odelab_compiled_*.py"))
    assert other.module().__file__ in map(str, files)
    assert files[0].read_text(encoding="utf-8").startswith("# Generated by odelab")


def test_generated_source_holds_only_validated_names():
    with pytest.raises(Exception, match="not an allowed function"):
        CompiledSystem.from_equations(["y"], ["__import__('os')"]).source()
    with pytest.raises(InputError, match="`eq.y` uses `k`, which is not a state, a parameter or t"):
        CompiledSystem.from_equations(["y"], ["-k*y"], keys=["eq.y"]).source()


def test_scipy_methods_and_python_callbacks_are_refused():
    with pytest.raises(InputError, match="RK45 is SciPy's"):
        solve_compiled(RIGID, [0, 1], [0, 1, 1], "RK45")
    with pytest.raises(InputError, match="does not run `events`"):
        solve_compiled(RIGID, [0, 1], [0, 1, 1], "ode45", events=lambda t, y: y[0])


LONG = """
title = "Rigid body, a long run"
[parameters]
a = -0.51
[system]
states = ["y1", "y2", "y3"]
[system.equations]
y1 = "y2*y3"
y2 = "-y1*y3"
y3 = "a*y1*y2"
[initial]
y1 = 0
y2 = 1
y3 = 1
[time]
stop = 6000
[solver]
method = "ode45"
rtol = 1e-6
atol = 1e-9
refine = 1
"""


def test_auto_keeps_lab_runs_on_python_and_moves_long_runs(tmp_path):
    from odelab.solvers.compiled import COMPILE_SECONDS, expected_compile_seconds

    short = load_experiment(ROOT / "experiments" / "rigid_body.toml").cases[0]
    assert run_case(short).backend == "python"
    (tmp_path / "long.toml").write_text(LONG, encoding="utf-8")
    case = load_experiment(tmp_path / "long.toml").cases[0]
    solve_compiled(RIGID, [0, 1], [0, 1, 1])  # the same module text as the file's: built now
    assert expected_compile_seconds(case.problem.system.compiled) == COMPILE_SECONDS["load"]
    result = run_case(case)  # ~30 000 steps: about 1 s on Python against a 0.5 s load
    # Exact counts: both engines sum in one order without BLAS (odelab.solvers.ordered), so the
    # same bits on every BLAS kernel, and no attempt of the 31 747 has err/rtol within 2e-4 of
    # the acceptance threshold (nor the last step's stretch within 0.15 of its).
    assert result.backend == "compiled" and result.stats.nsteps == 29546 and result.stats.nfailed == 2201
    python = run_case(case, backend="python")
    assert python.stats == result.stats
    np.testing.assert_array_equal(python.t, result.t)
    np.testing.assert_array_equal(python.y, result.y)
    capped = run_case(case, max_steps=500)
    assert capped.backend == "python" and capped.stats.nsteps == 500


def test_auto_stays_on_python_when_the_compile_costs_more_than_the_run(tmp_path, monkeypatch):
    import odelab.solvers.compiled

    (tmp_path / "long.toml").write_text(LONG.replace("stop = 6000", "stop = 2500"), encoding="utf-8")
    case = load_experiment(tmp_path / "long.toml").cases[0]
    # as a first run on a machine would be: the loop and the system to compile, several seconds
    monkeypatch.setattr(odelab.solvers.compiled, "expected_compile_seconds", lambda system, loop="adaptive": 60.0)
    result = run_case(case)
    assert result.backend == "python" and AUTO_STEPS < result.stats.nsteps < 2 * AUTO_STEPS
    assert result.status == "success" and result.stats == run_case(case, backend="compiled").stats


def test_every_compiled_signal_type_gives_the_python_values():
    from odelab import signals as sg

    table = sg.Table([0.0, 0.5, 2.0, 3.0], [1.0, -1.0, 4.0, 4.5])
    signals = [sg.Constant(2.5), sg.Step(time=1.0, initial=-1.0, final=3.0), sg.Ramp(slope=2.0, start=0.5, initial=1.0),
               sg.Sine(amplitude=2.0, frequency=3.0, phase=0.3, bias=1.0), sg.Pulse(amplitude=2.0, period=0.7, width=0.3,
                                                                                     delay=0.2),
               table, 2.0 * sg.Step(time=2.0) - sg.Ramp(slope=0.5) + 1.5, table / 4.0]
    names = [f"u{i}" for i in range(len(signals))]
    system = CompiledSystem.from_system([f"s{i}" for i in range(len(signals))], names, inputs=names)
    system = system.with_signals(signals)
    assert system.why_not() is None
    rhs = system.module().rhs
    p = system.parameter_vector()
    times = np.concatenate([np.linspace(-1, 4, 401), [0.2, 0.41, 0.9, 1.0, 2.0, 0.5, 3.0, 0.2 + 7 * 0.7, np.nextafter(1, 0)]])
    out = np.empty(len(signals))
    for t in times:
        rhs(float(t), np.zeros(len(signals)), p, out)
        expected = [s(t) for s in signals]
        np.testing.assert_array_equal(np.delete(out, 3), np.delete(expected, 3))  # the same operations
        assert out[3] == pytest.approx(expected[3], rel=4e-16, abs=4e-16)  # libm's sin against numpy's
    lo, hi = 0.5, np.nextafter(1.0, 0.0)  # a piece of simulate: the inputs read inside it
    p = system.parameter_vector(lo, hi)
    rhs(1.0, np.zeros(len(signals)), p, out)
    assert out[1] == -1.0 and out[2] == signals[2](hi)
    rhs(0.0, np.zeros(len(signals)), p, out)
    assert out[2] == 1.0 and out[0] == 2.5


def test_a_python_callable_input_stays_on_python_with_the_reason():
    from odelab import signals as sg

    system = CompiledSystem.linear([[0.0]], ["x"], [[1.0]], ["f"]).with_signals([sg.Function(np.cos, label="cos(t)")])
    assert system.why_not() == ("input `f`: a Python function of t (an experiment file's `expression` input is "
                                "compiled; a callable is not)")
    with pytest.raises(InputError, match="cannot run this system: input `f`: a Python function of t"):
        solve_compiled(system, [0, 1], [0.0], "ode45")


EXPRESSION_INPUT = """
title = "A forced oscillator, the force an expression of t"
[parameters]
w = 1.7
k = 3
[system]
states = ["x", "v"]
inputs = ["f"]
[system.equations]
x = "v"
v = "f - 0.4*v - k*x"
[initial]
x = 0
v = 0
[time]
stop = 8
[inputs.f]
type = "expression"
expression = "0.5*sin(w*t) + k*heaviside(t - 2) - max(t - 6, 0)^2"
[solver]
method = "ode45"
"""


def test_an_expression_input_runs_compiled(tmp_path):
    (tmp_path / "forced.toml").write_text(EXPRESSION_INPUT, encoding="utf-8")
    case = load_experiment(tmp_path / "forced.toml").cases[0]
    assert why_not_compiled(get_method("ode45"), case.problem.system.compiled, case.problem.options) is None
    assert "(0.5 * _np.sin((_p[" in case.problem.system.compiled.source()  # w is run-time data, t is _tu
    python, compiled = run_case(case, backend="python"), run_case(case, backend="compiled")
    assert compiled.backend == "compiled" and compiled.stats == python.stats
    np.testing.assert_allclose(compiled.t, python.t, rtol=0, atol=1e-12 * 8)
    np.testing.assert_allclose(compiled.x, python.x, rtol=0, atol=1e-12 * np.max(np.abs(python.x)))


def test_an_expression_input_with_a_parameter_named_e_runs_compiled(tmp_path):
    # a parameter e shadows Euler's number in an input's expression too, on both engines: the
    # same run as the literal 0.5 (odelab.expressions.functions.shadowed_constants)
    named = EXPRESSION_INPUT.replace("w = 1.7", "w = 1.7\ne = 0.5").replace('"0.5*sin(w*t)', '"e*sin(w*t)')
    (tmp_path / "named.toml").write_text(named, encoding="utf-8")
    (tmp_path / "forced.toml").write_text(EXPRESSION_INPUT, encoding="utf-8")
    case = load_experiment(tmp_path / "named.toml").cases[0]
    literal = run_case(load_experiment(tmp_path / "forced.toml").cases[0], backend="python")
    python, compiled = run_case(case, backend="python"), run_case(case, backend="compiled")
    assert compiled.backend == "compiled" and compiled.stats == python.stats == literal.stats
    np.testing.assert_array_equal(python.x, literal.x)
    np.testing.assert_allclose(compiled.x, python.x, rtol=0, atol=1e-12 * np.max(np.abs(python.x)))


LONG_INPUT = """
title = "Exercise 2's plant driven by a pulse train for a long time"
[parameters]
m = 1
b = 0.4
k = 3
[system]
kind = "state-space"
states = ["x", "v"]
inputs = ["f"]
A = [[0, 1], ["-k/m", "-b/m"]]
B = [[0], ["1/m"]]
[initial]
x = 0
v = 0
[time]
stop = 100
[inputs.f]
type = "pulse"
period = 2
[solver]
method = "ode45"
rtol = 1e-6
atol = 1e-9
refine = 1
"""


def test_auto_moves_a_long_run_with_inputs_to_the_compiled_path(tmp_path, monkeypatch):
    import odelab.solvers.compiled

    monkeypatch.setattr(odelab.solvers.compiled, "AUTO_STEPS", 300)  # one budget for all 100 pieces
    monkeypatch.setattr(odelab.solvers.compiled, "expected_compile_seconds", lambda system, loop="adaptive": 0.0)
    (tmp_path / "long.toml").write_text(LONG_INPUT, encoding="utf-8")
    case = load_experiment(tmp_path / "long.toml").cases[0]
    result = run_case(case)
    python = run_case(case, backend="python")
    assert result.backend == "compiled" and python.backend == "python"
    assert result.stats == python.stats and result.stats.nsteps == 1125  # each piece far below the budget
    assert "Integrated in 100 pieces" in result.message and result.message == python.message
    np.testing.assert_allclose(result.t, python.t, rtol=0, atol=1e-8 * 100)
    np.testing.assert_allclose(result.x, python.x, rtol=0, atol=1e-9 * np.max(np.abs(python.x)))


BALL = CompiledSystem.from_equations(["h", "v"], ["v", "-g"], {"g": 9.81}).with_events(
    ["h", "v", "h - 2"], [True, False, False], [-1, 0, 1], {"g": 9.81}, ["events.floor.when", "events.apex.when", None])


def ball(t, y):
    return np.array([y[1], -9.81])


def ball_events(t, y):
    return np.array([y[0], y[1], y[0] - 2]), np.array([True, False, False]), np.array([-1.0, 0.0, 1.0])


@pytest.mark.parametrize("y0, tspan, options", [
    ([10.0, 0.0], [0, 5], {}),  # the floor stops it; the apex and h = 2 rising never come
    ([0.0, 12.0], [0, 5], {"refine": 1}),  # up through h = 2 (rising), the apex, down to the floor
    ([0.0, 12.0], list(np.linspace(0, 5, 41)), {"rtol": 1e-6}),  # output times; the floor's point added
    ([0.0, 12.0], [0, 1.5], {}),  # the end comes first: h = 2 and the apex only
    ([0.0, 0.0], [0, 5], {}),  # h = 0 at t0: not an event (MATLAB), then it falls through the floor
])
def test_events_are_located_as_the_python_engine_does(y0, tspan, options):
    a = solve_compiled(BALL, tspan, y0, "ode45", **options)
    b = odelab.solve(ball, tspan, y0, "ode45", events=ball_events, **options)
    assert a.stats == b.stats and a.status == b.status and a.message == b.message
    np.testing.assert_array_equal(a.ie, b.ie)
    # one order of operations in both engines (odelab.solvers.ordered), no BLAS: the same bits
    for got, want in ((a.te, b.te), (a.ye, b.ye), (a.t, b.t), (a.y, b.y)):
        np.testing.assert_array_equal(got, want)


OSCILLATOR = CompiledSystem.from_equations(["x", "v"], ["v", "-x - 0.01*v"], {}).with_events(
    ["x", "v"], [False, False], [0, 1], {})


def test_many_events_grow_their_arrays_as_the_python_engine_records_them():
    # 48 zero crossings of x and 24 minima (v rising through 0): far past the 4 k + 4 = 12 rows the loop starts with
    a = solve_compiled(OSCILLATOR, [0, 150], [1.0, 0.0], "ode45", rtol=1e-6, atol=1e-9)
    b = odelab.solve(lambda t, y: np.array([y[1], -y[0] - 0.01 * y[1]]), [0, 150], [1.0, 0.0], "ode45",
                     rtol=1e-6, atol=1e-9,
                     events=lambda t, y: (np.array([y[0], y[1]]), np.array([False, False]), np.array([0.0, 1.0])))
    assert a.te.size == 72 and a.stats == b.stats
    for got, want in ((a.ie, b.ie), (a.te, b.te), (a.ye, b.ye), (a.t, b.t), (a.y, b.y)):
        np.testing.assert_array_equal(got, want)


def test_events_need_an_adaptive_method():
    with pytest.raises(InputError, match=r"the compiled backend locates \[events\] with ode23 and ode45 only"):
        solve_compiled(BALL, [0, 1], [10.0, 0.0], "rk4", h=0.1)


def test_auto_counts_only_the_steps_max_steps_allows(monkeypatch):
    import odelab.solvers.compiled

    # stiff.toml's ode45 covers a sliver of [0, 3000] in 10 000 steps (millions needed), but its
    # max_steps = 20 000 leaves one more budget's work: not worth a 10 s compile
    case = next(c for c in load_experiment(ROOT / "experiments" / "stiff.toml").cases if c.name == "ode45")
    monkeypatch.setattr(odelab.solvers.compiled, "expected_compile_seconds", lambda system, loop="adaptive": 10.0)
    result = run_case(case)
    assert result.backend == "python" and result.stats.nsteps == 20_000 and result.status == "failed"


@pytest.mark.parametrize("rule, args, want", [
    ("event_tolerance", (1.0, 1.5), 128 * 2.0 ** -52),  # 128 eps(1.5) = 128 eps(1): the bracket's width
    ("event_tolerance", (1.0, 1.0 + 2.0 ** -46), 2.0 ** -46),  # a step narrower than that: its width
    ("crosses", (1.0, -2.0, 0.0), True),
    ("crosses", (1.0, -2.0, 1.0), False),  # falling, but only rising counts
    ("crosses", (0.0, 0.0, 0.0), False),
    ("crosses", (float("nan"), -1.0, 0.0), False),  # a NaN fails the direction test
    ("root_fraction", (-1.0, 3.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0), 0.25),  # regula falsi
    ("root_fraction", (0.0, 1.0, 5.0, 0.0, 1.0, 2.0, 1.0, 1.0), 0.75),  # the secant through the point tried
    ("root_fraction", (0.0, 1.0, 0.5, 0.0, 1.0, 2.0, 1.0, 1.0), 0.5),  # its root outside [0, 1]: the midpoint
    ("root_fraction", (2.0, 0.0, 1.0, 0.0, 1.0, 0.5, 1.0, 1.0), 0.5),  # the point tried inside: the midpoint
    ("next_try", (0.01, 2.0, 1.0, 0.1, 1.0), 2.05),  # at least tol/2 from the left end
    ("next_try", (0.99, 2.0, -1.0, 0.1, -1.0), 1.05),  # ... and from the right end, going down in t
    ("halved", (4.5e-308,), 2.25e-308),
    ("halved", (4.0e-308,), 4.0e-308),  # halving would leave realmin: kept
    ("stops", (0.0, 0.0, 1e-15, 1e-15), False),  # still at the first step's search start
    ("stops", (0.0, 0.0, 0.5, 1e-15), True),
    ("stops", (2.0, 0.0, 2.0, 2.0), True),
])
def test_both_event_locators_take_odezeros_rule(rule, args, want):
    """locate_events calls odelab.solvers.odezero, the compiled _locate the same text compiled."""
    from odelab.solvers import odezero
    from odelab.solvers.compiled.cache import load_kernels

    assert getattr(odezero, rule)(*args) == want
    assert getattr(load_kernels(), rule)(*args) == want


def test_min_and_max_of_600_arguments_compile_flat_and_give_the_python_values(tmp_path):
    # issue 41: folded left to right in nested calls, 600 arguments nested 599 deep and Python's compiler stopped
    # with "too many nested parentheses" (a traceback). Past 8 arguments they are one tuple, folded
    # in a loop in the same order: the leftmost extreme (a tie keeps the left one), NaN if any is NaN.
    args = ",".join(["x", "y", "-x", "2*y", "x/2", "-y"] * 100)  # 600 arguments, ties among them
    (tmp_path / "many.toml").write_text(
        f'[system]\nstates = ["x", "y"]\n[system.equations]\nx = "-max({args})"\ny = "min({args}) - y"\n'
        '[initial]\nx = 1\ny = -0.5\n[time]\nstop = 2\n[solver]\nmethod = "ode45"\n', encoding="utf-8")
    case = load_experiment(tmp_path / "many.toml").cases[0]
    source = case.problem.system.compiled.source()
    depth = deepest = 0
    for ch in source:
        depth += ch == "("
        depth -= ch == ")"
        deepest = max(deepest, depth)
    assert deepest <= 16, deepest
    python, compiled = run_case(case, backend="python"), run_case(case, backend="compiled")
    assert compiled.backend == "compiled" and compiled.stats == python.stats
    np.testing.assert_array_equal(compiled.x, python.x)
    module = case.problem.system.compiled.module()
    for x, y in [(0.0, -0.0), (-0.0, 0.0), (np.nan, 1.0), (1.0, np.nan), (2.0, 2.0)]:
        out = np.empty(2)
        module.rhs(0.0, np.array([x, y]), case.problem.system.compiled.parameter_vector(), out)
        F = compile_vector([f"-max({args})", f"min({args}) - y"], args=["t", "x", "y"])
        expected = F(0.0, x, y)
        np.testing.assert_array_equal(out, expected)
        assert np.array_equal(np.signbit(out), np.signbit(expected))
