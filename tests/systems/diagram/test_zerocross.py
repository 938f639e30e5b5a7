"""Zero-crossing detection: switching blocks switch at the instants their formulas change,
located on the solver's interpolant, whatever the tolerances (closed forms as references)."""

import numpy as np
import pytest

from odelab import diagram as dg
from odelab.signals import Ramp, Sine, Step
from odelab.systems.diagram import zerocross
from odelab.systems.diagram.switching import Abs, MinMax, Relay, Sign, Switch

EPS = np.finfo(float).eps


def ramp_into_saturation(**sat):
    return dg.Diagram({"r": Ramp(slope=1.0), "sat": dg.Saturation(lower=-0.5, upper=0.5, input="r", **sat),
                       "i": dg.Integrator(input="sat")}, {"y": "sat", "q": "i"})


def q_exact(t):
    return np.minimum(t, 0.5) ** 2 / 2 + 0.5 * np.maximum(t - 0.5, 0.0)


@pytest.mark.parametrize("rtol", [1e-3, 1e-6, 1e-9, 1e-12])
def test_a_ramp_into_a_saturation_switches_at_half_to_round_off_at_any_tolerance(rtol):
    r = ramp_into_saturation().compile().simulate([0, 2], rtol=rtol, atol=1e-14)
    assert r.success and list(r.crossings) == ["sat"] and len(r.crossings["sat"]) == 1
    assert abs(r.crossings["sat"][0] - 0.5) <= 4 * EPS
    # the integral of the saturated ramp is a polynomial on each piece: ode45 is exact on it
    err = np.max(np.abs(r.x[:, 0] - q_exact(r.t)))
    assert err <= 16 * EPS
    assert "sat (saturation) 1" in r.message


def test_without_detection_the_corner_is_stepped_over_and_the_error_follows_the_tolerance():
    for d in (ramp_into_saturation(zero_crossing=False).compile(), ramp_into_saturation().compile(zero_crossing=False)):
        r = d.simulate([0, 2], rtol=1e-3, atol=1e-6)
        assert r.success and not getattr(r, "crossings", {})
        err = np.max(np.abs(r.x[:, 0] - q_exact(r.t)))
        assert 1e3 * EPS < err < 1e-3  # tolerance-sized, not round-off: what detection fixes


@pytest.mark.parametrize("rtol", [1e-3, 1e-8])
def test_relay_bang_bang_loop_with_hysteresis_switches_at_the_closed_form_times(rtol):
    # x' = relay(x): off (+1) until x reaches 1, on (-2) until x falls to -1, and so on:
    # 0 -> 1 in 1 s, 1 -> -1 in 1 s, -1 -> 1 in 2 s: switches at 1, 2, 4, 5, 7, 8, 10, 11, ...
    d = dg.Diagram({"x": dg.Integrator(input="r"),
                    "r": Relay(on_point=1, off_point=-1, on_value=-2, off_value=1, input="x")}, {"y": "x"})
    r = d.compile().simulate([0, 9.5], rtol=rtol)
    times = np.array(r.crossings["r"])
    expect = np.array([1.0, 2.0, 4.0, 5.0, 7.0, 8.0])
    assert times.size == expect.size
    np.testing.assert_allclose(times, expect, rtol=0, atol=2048 * EPS * 10)
    # the relay's output is a state: a step-like line, each switch listed before and after
    k = list(r.states).index("r")
    at = np.flatnonzero(r.t == r.crossings["r"][0])
    assert at.size == 2 and r.x[at[0], k] == 1.0 and r.x[at[1], k] == -2.0


def test_a_limited_integrator_reaches_its_limits_at_the_closed_form_times():
    # x' = 1 until x = 1 (t = 1), held; x' = -1 from t = 2 until x = 0 (t = 3)
    d = dg.Diagram({"u": Step(time=2.0, initial=1.0, final=-1.0),
                    "x": dg.Integrator(input="u", initial=0.0, lower=0.0, upper=1.0)}, {"x": "x"})
    r = d.compile().simulate([0, 4], rtol=1e-3)
    np.testing.assert_allclose(r.crossings["x"], [1.0, 3.0], rtol=0, atol=256 * EPS * 3)
    assert np.all((r.y[:, 0] >= 0.0) & (r.y[:, 0] <= 1.0))
    np.testing.assert_allclose(r.x[:, 0], np.clip(np.where(r.t < 2, r.t, 3 - r.t), 0, 1), atol=1e-13)


def test_switch_abs_sign_and_min_max_against_their_integrals():
    d = dg.Diagram({
        "c": Sine(amplitude=1, frequency=1), "a": Step(time=0, final=2), "b": Step(time=0, final=-1),
        "half": Step(time=0, final=0.5),
        "sw": Switch(inputs=["a", "c", "b"]), "ab": Abs(input="c"), "sg": Sign(input="c"),
        "mm": MinMax(function="min", inputs=["c", "half"]),
        "x1": dg.Integrator(input="sw"), "x2": dg.Integrator(input="ab"), "x3": dg.Integrator(input="sg"),
        "x4": dg.Integrator(input="mm")}, {"y1": "x1", "y2": "x2", "y3": "x3", "y4": "x4"})
    r = d.compile().simulate([0, 10], rtol=1e-10, atol=1e-12)
    pos = 2 * np.pi  # the lengths where sin >= 0 and < 0 on [0, 10]
    neg = 10 - pos
    tail = 10 - 3 * np.pi
    expect = [2 * pos - neg, 6 + 1 - np.cos(tail), pos - neg, 1 - np.cos(10) - 2 * (np.sqrt(3) - np.pi / 3)]
    np.testing.assert_allclose(r.y[-1], expect, rtol=0, atol=1e-8)
    for name in ("sw", "ab"):
        np.testing.assert_allclose(r.crossings[name], [np.pi, 2 * np.pi, 3 * np.pi], rtol=0, atol=1e-9)
    k = np.pi / 6
    np.testing.assert_allclose(r.crossings["mm"], [k, 5 * k, 2 * np.pi + k, 2 * np.pi + 5 * k], rtol=0, atol=1e-9)


def test_a_chattering_switch_is_a_clear_failure_with_partial_results(monkeypatch):
    monkeypatch.setattr(zerocross, "MAX_CONSECUTIVE", 25)
    # x' = -sign(x) from 1: reaches 0 at t = 1, then the sign chatters
    d = dg.Diagram({"x": dg.Integrator(input="g", initial=1.0), "s": Sign(input="x"),
                    "g": dg.Gain(gain=-1, input="s")}, {"y": "x"})
    r = d.compile().simulate([0, 3], rtol=1e-6)
    assert r.status == "failed" and "consecutive zero crossings of block `s`" in r.message
    assert abs(r.t[-1] - 1.0) < 1e-9 and "zero_crossing = false" in r.message


def test_block_key_checks():
    with pytest.raises(dg.BlockError, match="criteria"):
        Switch(inputs=["a", "b", "c"], criteria="u2 >= 0")
    with pytest.raises(dg.BlockError, match="on_point"):
        Relay(input="u", on_point=-1, off_point=1)


def test_initial_modes_come_from_where_the_switching_functions_go():
    # sign(sin t) from t = 0, where sin is exactly zero: the mode is +1 from the start (the
    # direction sin leaves zero in), not sign(0) = 0 held until an event at t0 (the solver
    # reports none there, as MATLAB). Its integral over [0, pi] is pi; the only crossing is pi.
    d = dg.Diagram({"c": Sine(amplitude=1, frequency=1), "sg": Sign(input="c"), "ab": Abs(input="c"),
                    "x": dg.Integrator(input="sg"), "z": dg.Integrator(input="ab")}, {"x": "x", "z": "z"})
    r = d.compile().simulate([0, 4], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(r.crossings["sg"], [np.pi], rtol=0, atol=1e-9)
    k = np.searchsorted(r.t, np.pi)
    np.testing.assert_allclose(r.y[-1], [np.pi - (4 - np.pi), 2 + 1 - np.cos(4 - np.pi)], rtol=0, atol=1e-8)
    assert r.y[k - 1, 0] == pytest.approx(r.t[k - 1], abs=1e-9)  # x = t while sin > 0


def test_a_sources_jump_is_listed_before_and_after_with_the_inputs_and_outputs_of_each_side():
    # what the report draws as a step: the row before the jump reads the source's left limit
    d = dg.Diagram({"u": Step(time=1.0, final=2.0), "g": dg.Gain(gain=3.0, input="u"),
                    "i": dg.Integrator(input="u"), "sat": dg.Saturation(input="i")}, {"g": "g", "s": "sat"})
    r = d.compile().simulate([0, 2])
    rows = np.flatnonzero(r.t == 1.0)
    assert rows.size == 2 and rows[1] == rows[0] + 1
    assert r.u[rows[0], 0] == 0.0 and r.u[rows[1], 0] == 2.0
    assert r.y[rows[0], 0] == 0.0 and r.y[rows[1], 0] == 6.0
    # the crossing of the saturation's corner (i = 0.5 at t = 1.25) is listed twice too
    t_sat = r.crossings["sat"][0]
    assert np.count_nonzero(r.t == t_sat) == 2 and abs(t_sat - 1.25) <= 256 * EPS * 1.25  # odezero: 128 ulps
