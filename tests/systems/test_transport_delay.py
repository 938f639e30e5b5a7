"""The transport-delay block: diagrams with delays run as delay equations by dde23, and their Pade linear model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import odelab
from odelab import diagram as dg
from odelab.exceptions import InputError
from odelab.signals import Step
from odelab.systems.delay import DelayEquations
from odelab.systems.diagram.delay import DelayDiagram, TransportDelay, pade_coefficients, pade_diagram

EPS = np.finfo(float).eps


def negative_feedback_loop(initial=1.0):
    """x' = -x(t - 1) as a diagram: integrator -> transport delay -> gain -1 -> integrator."""
    return dg.Diagram({
        "x": dg.Integrator(input="fb", initial=1.0),
        "dly": TransportDelay(delay=1.0, initial=initial, input="x"),
        "fb": dg.Gain(gain=-1.0, input="dly"),
    }, outputs={"y": "x", "yd": "dly"}).compile()


@pytest.mark.parametrize("rtol", [1e-3, 1e-6])
def test_a_delay_in_a_loop_is_the_same_equation_written_with_lag(rtol):
    c = negative_feedback_loop()
    block = odelab.solve(DelayDiagram(c, 0.0), [0, 5], c.x0, method="dde23", rtol=rtol, atol=1e-3 * rtol)
    equation = odelab.solve(DelayEquations({"x": "-lag(x, 1)"}), [0, 5], [1.0], method="dde23", rtol=rtol,
                            atol=1e-3 * rtol)
    assert block.success and equation.success
    # the same delay equation, the same method: the same numbers, to round-off (far inside the tolerance)
    assert block.t.size == equation.t.size and np.max(np.abs(block.t - equation.t)) <= 10 * EPS * 5
    assert np.max(np.abs(block.y - equation.y)) <= 10 * EPS
    # and both are the exact solution within the tolerance (y(5) = 19/120)
    assert abs(block.y[-1, 0] - 19 / 120) <= 0.5 * rtol
    assert 1.0 in block.t.tolist() and 2.0 in block.t.tolist() and 3.0 in block.t.tolist()


def test_initial_output_before_the_delay_has_elapsed():
    # initial = 0: x' = 0 on [0, 1) (x = 1), then x' = -x(t - 1): x = 2 - t on [1, 2],
    # x = -(3(t - 2) - (t^2 - 4)/2) on [2, 3]: polynomials of degree <= 2, exact to round-off
    c = negative_feedback_loop(initial=0.0)
    dd = DelayDiagram(c, 0.0)
    sol = odelab.solve(dd, [0, 3], c.x0, method="dde23")
    assert 1.0 in sol.t.tolist() and 2.0 in sol.t.tolist()  # the output's jump at t0 + T is a mesh point
    t = np.linspace(0, 3, 61)
    exact = np.where(t <= 1, 1.0, np.where(t <= 2, 2 - t, -(3 * (t - 2) - (t**2 - 4) / 2)))
    assert np.max(np.abs(sol.deval(t)[:, 0] - exact)) <= 100 * EPS
    # the block's output: initial before t = 1, x(t - 1) after (Simulink's Transport Delay)
    out = dd.output_many(t, sol.deval(t))
    delayed = np.where(t < 1, 0.0, np.interp(t - 1, t, exact))
    assert np.max(np.abs(out[:, 1] - delayed)) <= 100 * EPS


def test_a_step_into_a_delayed_loop_and_its_source_breakpoint():
    # y' = -y + K (r - y(t - T)) with r a unit step at t = 0.5: the step and its echoes are mesh points
    K, T = 2.0, 0.3
    c = dg.Diagram({
        "r": Step(time=0.5),
        "e": dg.Sum(signs="+-", inputs=["r", "dly"]),
        "u": dg.Gain(gain=K, input="e"),
        "plant": dg.TransferFcn(num=[1], den=[1, 1], input="u"),
        "dly": TransportDelay(delay=T, input="plant"),
    }, outputs={"y": "plant"}).compile()
    dd = DelayDiagram(c, 0.0)
    sol = odelab.solve(dd, [0, 6], c.x0, method="dde23", rtol=1e-7, atol=1e-10)
    for point in (0.5, 0.5 + T, 0.5 + 2 * T):
        assert np.min(np.abs(sol.t - point)) <= 10 * EPS
    equation = DelayEquations({"y": f"-y + {K}*((t >= 0.5) - lag(y, {T}))"})
    ref = odelab.dde23(lambda t, y, Z: equation.ddefun(t, y, Z), equation.lags, [0.0], [0, 6],
                       RelTol=1e-7, AbsTol=1e-10, Jumps=[0.5])
    tt = np.linspace(0, 6, 121)
    assert np.max(np.abs(sol.deval(tt)[:, 0] - ref.deval(tt)[:, 0])) <= 1e-6
    # the closed loop settles at K/(1 + K) of the step (the delay does not change the DC gain)
    assert abs(sol.y[-1, 0] - K / (1 + K)) <= 1e-3


def test_what_the_delay_driver_refuses():
    with pytest.raises(InputError, match="positive"):
        TransportDelay(delay=0.0, input="x")
    with pytest.raises(InputError, match="pade_order"):
        TransportDelay(delay=1.0, pade_order=-1, input="x")
    series = dg.Diagram({
        "x": dg.Integrator(input="fb", initial=1.0),
        "d1": TransportDelay(delay=0.5, input="x"),
        "d2": TransportDelay(delay=0.5, input="d1"),
        "fb": dg.Gain(gain=-1.0, input="d2"),
    }, outputs={"y": "x"}).compile()
    with pytest.raises(InputError, match="delays in series"):
        DelayDiagram(series, 0.0)
    c = negative_feedback_loop()
    with pytest.raises(InputError, match="dde23"):
        odelab.solve(DelayDiagram(c, 0.0), [0, 1], c.x0, method="ode45")


@pytest.mark.parametrize("order", [1, 2, 3, 5])
@pytest.mark.parametrize("T", [0.1, 1.0, 2.5])
def test_pade_coefficients_are_python_controls(T, order):
    control = pytest.importorskip("control")
    num, den = pade_coefficients(T, order)
    cnum, cden = control.pade(T, order)
    np.testing.assert_allclose(num, cnum, rtol=1e-13, atol=0)
    np.testing.assert_allclose(den, cden, rtol=1e-13, atol=0)


def test_linearising_a_delayed_loop_uses_the_pade_approximation():
    control = pytest.importorskip("control")
    T = 0.4
    c = dg.Diagram({
        "r": Step(time=0.0),
        "e": dg.Sum(signs="+-", inputs=["r", "dly"]),
        "plant": dg.TransferFcn(num=[2], den=[1, 1], input="e"),
        "dly": TransportDelay(delay=T, input="plant"),
    }, outputs={"y": "plant"}).compile()
    lin = pade_diagram(c)
    assert any("Pade approximation of order 2" in n for n in lin.notes)
    ss = lin.system  # every block linear now: the exact A, B, C, D
    assert ss.states == ("plant", "dly.x1", "dly.x2")
    G = control.tf([2], [1, 1])
    D = control.tf(*control.pade(T, 2))
    closed = control.feedback(G, D)  # y/r with the delay's Pade approximation in the feedback path
    ours = control.ss(ss.A, ss.B, ss.C, ss.D)
    np.testing.assert_allclose(np.sort_complex(control.poles(ours)), np.sort_complex(control.poles(closed)),
                               rtol=1e-10)
    for w in (0.0, 0.3, 1.0, 4.0):
        assert abs(control.evalfr(ours, 1j * w) - control.evalfr(closed, 1j * w)) <= 1e-12 * 10


def test_pade_order_zero_is_the_wire():
    c = negative_feedback_loop()
    c0 = dg.Diagram({
        "x": dg.Integrator(input="fb", initial=1.0),
        "dly": TransportDelay(delay=1.0, pade_order=0, input="x"),
        "fb": dg.Gain(gain=-1.0, input="dly"),
    }, outputs={"y": "x"}).compile()
    assert pade_diagram(c0).system.A.tolist() == [[-1.0]]
    assert pade_diagram(c).system.A.shape == (3, 3)


def test_in_an_experiment_file(tmp_path):
    from typer.testing import CliRunner

    from odelab.cli import app
    from odelab.run.runner import run_experiment

    diagram = tmp_path / "loop.toml"
    diagram.write_text("""
[system]
kind = "diagram"
outputs = { y = "x", yd = "dly" }
[blocks]
x = { type = "integrator", input = "fb", initial = 1 }
dly = { type = "transport-delay", delay = "tau", initial = 1, input = "x" }
fb = { type = "gain", gain = -1, input = "dly" }
[parameters]
tau = 1
[time]
stop = 5
points = 51
""")
    equation = tmp_path / "lag.toml"
    equation.write_text("""
[system]
states = ["x"]
[system.equations]
x = "-lag(x, 1)"
[initial]
x = 1
[time]
stop = 5
points = 51
""")
    (a,) = run_experiment(diagram)
    (b,) = run_experiment(equation)
    assert a.status == b.status == "success" and a.case.problem.method == "dde23"
    assert np.max(np.abs(a.x - b.x)) <= 10 * EPS
    # the delay's output: x(t - 1) after t = 1, its initial value 1 before
    assert np.max(np.abs(a.y[10:, 1] - a.x[:-10, 0])) <= 1e-3 and np.all(a.y[:10, 1] == 1.0)
    bad = tmp_path / "bad.toml"
    bad.write_text(diagram.read_text() + "[linearize]\n")
    out = CliRunner().invoke(app, ["validate", str(bad)])
    assert out.exit_code == 2 and "Pade" in out.output and "Traceback" not in out.output
    out = CliRunner().invoke(app, ["explain", "blocks.transport-delay"])
    assert out.exit_code == 0 and "delay" in out.output and "initial" in out.output


def test_analysis_of_a_delayed_loop_in_an_experiment_file(tmp_path):
    control = pytest.importorskip("control")
    from odelab.run.runner import run_experiment

    path = tmp_path / "loop.toml"
    path.write_text("""
[system]
kind = "diagram"
outputs = { y = "plant" }
[blocks]
ref   = { type = "step", time = 0.5 }
error = { type = "sum", signs = "+-", inputs = ["ref", "delay"] }
gain  = { type = "gain", gain = 2, input = "error" }
plant = { type = "transfer-fcn", num = [1], den = [1, 1], input = "gain" }
delay = { type = "transport-delay", delay = 0.3, input = "plant" }
[time]
stop = 10
[analysis]
""")
    (r,) = run_experiment(path)
    assert r.status == "success"
    assert any("Pade approximation of order 2" in w for w in r.warnings)  # the run says so
    closed = control.feedback(control.tf([2], [1, 1]), control.tf(*control.pade(0.3, 2)))
    ss = r.case.problem.system.model
    ours = control.ss(ss.A, ss.B, ss.C, ss.D)
    np.testing.assert_allclose(np.sort_complex(control.poles(ours)), np.sort_complex(control.poles(closed)),
                               rtol=1e-10)
    # the run itself is the delay equation: it settles at the closed loop's DC gain 2/3
    assert abs(r.x[-1, 0] - 2 / 3) <= 1e-3
