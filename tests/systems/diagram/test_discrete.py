"""Discrete blocks and sample times: sampled-data loops against python-control's c2d closed loops."""

import control as ct
import numpy as np
import pytest

from odelab import diagram as dg
from odelab.signals import Ramp, Step
from odelab.systems.diagram.discrete import (
    PID, DiscretePID, DiscreteStateSpace, DiscreteTransferFcn, UnitDelay, ZeroOrderHold,
)
from odelab.systems.diagram.schedule import SampleTime, hits, sample_time

EPS = np.finfo(float).eps


def at_samples(r, Ts, n, col=0):
    """The output at t = k*Ts (the row after the hit) for k = 0..n-1."""
    out = []
    for k in range(n):
        rows = np.flatnonzero(r.t == k * Ts)
        assert rows.size, f"no row at the hit {k}*Ts"
        out.append(r.y[rows[-1], col])
    return np.array(out)


def test_a_double_integrator_with_zoh_and_a_discrete_controller_is_c2ds_closed_loop_to_round_off():
    # between hits the plant's input is constant, so its response is a polynomial ode45 integrates
    # exactly: the only differences are round-off (in c2d's matrix exponential too)
    Ts, num, den = 0.1, [2.0, -1.6], [1.0, -0.2]
    d = dg.Diagram({"r": Step(time=0), "e": dg.Sum(signs="+-", inputs=["r", "y"]),
                    "zoh": ZeroOrderHold(sample_time=Ts, input="e"),
                    "c": DiscreteTransferFcn(num=num, den=den, sample_time=Ts, input="zoh"),
                    "v": dg.Integrator(input="c"), "y": dg.Integrator(input="v")}, {"y": "y", "u": "c"}).compile()
    r = d.simulate([0, 3], rtol=1e-3)
    assert r.success and len(r.hits) == 31
    T = ct.feedback(ct.tf(num, den, Ts) * ct.c2d(ct.tf([1], [1, 0, 0]), Ts, "zoh"), 1)
    k = np.arange(31)
    expect = np.squeeze(ct.step_response(T, T=k * Ts).outputs)
    got = at_samples(r, Ts, 31)
    assert np.max(np.abs(got - expect)) <= 1000 * EPS * np.max(np.abs(expect))
    # the controller's output is held between hits: constant on each sample interval
    inner = (r.t > 0.1) & (r.t < 0.2)
    assert inner.sum() >= 2 and np.ptp(r.y[inner, 1]) == 0.0


def test_a_motor_with_zoh_and_a_discrete_pid_is_c2ds_closed_loop():
    # speed loop: J w' = -b w + K u, discrete PID (forward Euler) on the sampled speed error
    J, b, K, Ts = 0.01, 0.1, 0.5, 0.02
    P, I, D, N = 8.0, 40.0, 0.05, 20.0
    d = dg.Diagram({"ref": Step(time=0, final=2.0), "e": dg.Sum(signs="+-", inputs=["ref", "w"]),
                    "zoh": ZeroOrderHold(sample_time=Ts, input="e"),
                    "pid": DiscretePID(P=P, I=I, D=D, N=N, sample_time=Ts, input="zoh"),
                    "w": dg.TransferFcn(num=[K], den=[J, b], input="pid")}, {"w": "w"}).compile()
    r = d.simulate([0, 1], rtol=1e-12, atol=1e-14)
    z = ct.tf([1, 0], [1], Ts)
    C = P + I * Ts / (z - 1) + D * N * (z - 1) / (z - 1 + N * Ts)
    T = ct.feedback(C * ct.c2d(ct.tf([K], [J, b]), Ts, "zoh"), 1)
    k = np.arange(51)
    expect = 2.0 * np.squeeze(ct.step_response(T, T=k * Ts).outputs)
    np.testing.assert_allclose(at_samples(r, Ts, 51), expect, rtol=0, atol=1e-10 * np.max(np.abs(expect)))
    assert d.states == ("zoh", "pid.integral", "pid.filter", "pid", "w")


def test_unit_delay_and_discrete_state_space_against_their_recurrences():
    Ts = 0.5
    A, B, C, D = [[0.5, 0.1], [0.0, 0.8]], [[1.0], [0.5]], [[1.0, -1.0]], [[0.25]]
    d = dg.Diagram({"u": Ramp(slope=1.0), "zd": UnitDelay(initial=3.0, sample_time=Ts, input="u"),
                    "ss": DiscreteStateSpace(A=A, B=B, C=C, D=D, initial=[1.0, 2.0], sample_time=Ts, input="u",
                                             outputs=["q"]),
                    "i": dg.Integrator(input="zd")}, {"zd": "zd", "q": "ss.q", "i": "i"}).compile()
    r = d.simulate([0, 5])
    n = 11
    uk = np.arange(n) * Ts
    delay = np.concatenate([[3.0], uk[:-1]])
    x, q = np.array([1.0, 2.0]), []
    for k in range(n):
        q.append((np.array(C) @ x + np.array(D)[0] * uk[k])[0])
        x = np.array(A) @ x + np.array(B)[:, 0] * uk[k]
    np.testing.assert_array_equal(at_samples(r, Ts, n, 0), delay)
    np.testing.assert_allclose(at_samples(r, Ts, n, 1), q, rtol=0, atol=16 * EPS * np.max(np.abs(q)))


def test_hits_are_counted_not_accumulated_and_several_rates_share_their_instants():
    st = sample_time(0.1)
    t = st.hits(0.0, 10.0)
    assert t.size == 101 and np.array_equal(t, np.arange(101) * 0.1)  # k*Ts, e.g. 3*0.1, not 0.1+0.1+0.1
    assert sample_time([0.15, 0.05]).hits(0, 1).tolist() == [k * 0.15 + 0.05 for k in range(7)]
    times, who = hits({"a": SampleTime((0.1, 0.0)), "b": SampleTime((0.3, 0.0))}, 0.0, 0.9)
    assert times.size == 10 and sorted(who[3]) == ["a", "b"]  # 3*0.1 and 1*0.3 are one instant
    # two rates in one diagram: each ZOH holds the ramp's value at its own hits
    d = dg.Diagram({"u": Ramp(slope=1.0), "fast": ZeroOrderHold(sample_time=0.1, input="u"),
                    "slow": ZeroOrderHold(sample_time=[0.25, 0.05], input="u"),
                    "i": dg.Integrator(input="fast")},
                   {"fast": "fast", "slow": "slow", "i": "i"}).compile()
    r = d.simulate(np.linspace(0, 1, 41))
    tq = r.t
    np.testing.assert_allclose(r.y[:, 0], np.floor(tq / 0.1 + 1e-9) * 0.1, rtol=0, atol=1e-15)
    slow = np.where(tq < 0.05, 0.0, 0.05 + np.floor((tq - 0.05) / 0.25 + 1e-9) * 0.25)
    np.testing.assert_allclose(r.y[:, 1], slow, rtol=0, atol=1e-15)
    # i = integral of the staircase: exact at the output times
    stair = np.floor(tq / 0.1 + 1e-9)
    expect = 0.1 * (0.1 * stair * (stair - 1) / 2 + stair * (tq - 0.1 * stair))
    np.testing.assert_allclose(r.y[:, 2], expect, rtol=0, atol=1e-14)


def test_continuous_pid_is_its_transfer_function():
    P, I, D, N = 2.0, 3.0, 0.5, 10.0
    s = ct.tf("s")
    G = P + I / s + D * N * s / (s + N)
    d = dg.Diagram({"e": Step(time=0), "pid": PID(P=P, I=I, D=D, N=N, input="e")}, {"u": "pid"}).compile()
    assert d.linear
    A, B, C, Dm = d.matrices()
    H = ct.ss2tf(ct.ss(A, B, C, Dm))
    w = np.logspace(-2, 3, 26)  # across the integral, proportional and filtered-derivative bands
    np.testing.assert_allclose(np.polyval(H.num[0][0], 1j * w) / np.polyval(H.den[0][0], 1j * w),
                               G(1j * w), rtol=1e-13)
    t = np.linspace(0, 2, 21)
    r = d.simulate(t, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(r.y[:, 0], P + I * t + D * N * np.exp(-N * t), rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("value", [0, -0.1, [0.1, 0.2], [0.1, -0.01], "x", [1, 2, 3]])
def test_bad_sample_times_are_refused(value):
    with pytest.raises(dg.BlockError, match="sample_time"):
        ZeroOrderHold(sample_time=value, input="u")


def test_a_non_causal_discrete_transfer_function_is_refused():
    with pytest.raises(dg.BlockError, match="not causal"):
        DiscreteTransferFcn(num=[1, 0, 0], den=[1, 0.5], sample_time=0.1, input="u")
