"""The rate-limiter block: ramps of the given slopes, engaged and released at located instants
(closed forms and scipy's brentq on the exact pieces as references)."""

import numpy as np
import pytest
from scipy.optimize import brentq

from odelab import diagram as dg
from odelab.signals import Ramp, Sine, Step
from odelab.systems.diagram.blocks import BlockError
from odelab.systems.diagram.ratelimit import RateLimiter, signal_slope

EPS = np.finfo(float).eps


def located(t):
    """MATLAB's odezero stops within 128 ulps of the crossing's time."""
    return 256 * EPS * max(1.0, abs(t))


@pytest.mark.parametrize("rtol", [1e-3, 1e-9])
@pytest.mark.parametrize("rising, height", [(2.0, 1.0), (0.3, 2.5)])
def test_a_step_into_a_rate_limiter_is_a_ramp_reaching_the_step_at_height_over_slope(rtol, rising, height):
    d = dg.Diagram({"u": Step(time=1.0, final=height), "rl": RateLimiter(rising=rising, input="u")}, {"y": "rl"})
    r = d.compile().simulate([0, 1 + height / rising + 1], rtol=rtol)
    assert r.success and len(r.crossings["rl"]) == 1
    t_reach = 1 + height / rising
    assert abs(r.crossings["rl"][0] - t_reach) <= located(t_reach)
    exact = np.clip(rising * (r.t - 1), 0, height)
    # the ramp is a polynomial of degree 1: the solver integrates it to round-off
    assert np.max(np.abs(r.y[:, 0] - exact)) <= 64 * EPS * height
    assert "rl (rate-limiter) 1" in r.message
    # drawn as the corner it is: the time of the catch is listed before and after the switch
    assert np.count_nonzero(r.t == r.crossings["rl"][0]) == 2


def test_a_step_down_during_a_rising_ramp_turns_it_into_a_falling_ramp():
    # u = 1 on [1, 2), 0 after; rising 0.5: y = 0.5 at t = 2, then falls at 1/s to 0 at t = 2.5
    u = Step(time=1.0, final=1.0) + Step(time=2.0, final=-1.0)
    r = dg.Diagram({"u": u, "rl": RateLimiter(rising=0.5, falling=-1.0, input="u")}, {"y": "rl"}).compile() \
        .simulate([0, 4], rtol=1e-3)
    assert r.success and len(r.crossings["rl"]) == 1 and abs(r.crossings["rl"][0] - 2.5) <= located(2.5)
    exact = np.where(r.t < 1, 0, np.where(r.t <= 2, 0.5 * (r.t - 1), np.maximum(0.5 - (r.t - 2), 0)))
    assert np.max(np.abs(r.y[:, 0] - exact)) <= 256 * EPS
    assert np.max(r.y[:, 0]) == pytest.approx(0.5, abs=16 * EPS)


def test_a_sine_is_followed_where_its_slope_is_within_the_limits_and_ramped_elsewhere():
    # u = sin t, slopes limited to +-0.5. From y(0) = 0 = u(0) with u' = 1 > 0.5: a rising ramp
    # y = 0.5 t until it meets sin t (t1); y = sin t until u' = cos t falls to -0.5 at 2 pi/3;
    # a falling ramp until it meets sin t again (t2), where u' = cos t2 > 0.5: a rising ramp.
    rate = 0.5
    t1 = brentq(lambda t: np.sin(t) - rate * t, 1.0, 2.5, xtol=1e-15)
    te = 2 * np.pi / 3
    t2 = brentq(lambda t: np.sin(t) - (np.sin(te) - rate * (t - te)), 4.5, 6.0, xtol=1e-15)
    tol = 1e-10
    d = dg.Diagram({"u": Sine(amplitude=1.0, frequency=1.0), "rl": RateLimiter(rising=rate, falling=-rate, input="u")},
                   {"y": "rl"})
    r = d.compile().simulate([0, 6.5], rtol=tol, atol=tol)
    c = np.array(r.crossings["rl"])
    assert c.size == 3
    # engaging at 2 pi/3 is a crossing of the input's slope: exact (a complex step), to round-off
    assert abs(c[1] - te) <= located(te)
    # meeting the sine: the tracked state carries the solver's error, in units of the tolerance
    assert abs(c[0] - t1) <= located(t1)  # met from a ramp started at t0: exact
    assert abs(c[2] - t2) <= located(t2)  # the falling ramp starts exactly on sin(2 pi/3)
    y, t = r.y[:, 0], r.t
    ramp1 = t <= c[0]
    assert np.max(np.abs(y[ramp1] - rate * t[ramp1])) <= 64 * EPS
    track = (t > c[0]) & (t <= c[1])
    assert np.max(np.abs(y[track] - np.sin(t[track]))) <= 100 * tol
    fall = (t > c[1]) & (t <= c[2])
    assert np.max(np.abs(y[fall] - (np.sin(te) - rate * (t[fall] - te)))) <= 64 * EPS
    rise = t > c[2]
    assert np.max(np.abs(y[rise] - (np.sin(t2) + rate * (t[rise] - t2)))) <= 64 * EPS
    # the output's slope never leaves the limits (between the listed points)
    dt = np.diff(t)
    slope = np.diff(y)[dt > 0] / dt[dt > 0]
    assert np.all(np.abs(slope) <= rate * (1 + 1e-9))


def test_a_rate_limited_actuator_in_a_loop_ramps_then_meets_its_input_at_the_closed_form_time():
    # x' = rl(k (1 - x)), rising 1: y = t while y < 5 (1 - x), x = t^2/2: they meet where
    # 2.5 t^2 + t - 5 = 0
    d = dg.Diagram({"r": Step(time=0, final=1.0), "e": dg.Sum(signs="+-", inputs=["r", "x"]),
                    "k": dg.Gain(gain=5.0, input="e"), "rl": RateLimiter(input="k"), "x": dg.Integrator(input="rl")},
                   {"x": "x", "y": "rl"})
    r = d.compile().simulate([0, 3], rtol=1e-6)
    meet = (-1 + np.sqrt(51)) / 5
    assert r.success and abs(r.crossings["rl"][0] - meet) <= located(meet)
    first = r.t <= meet
    assert np.max(np.abs(r.y[first, 1] - r.t[first])) <= 64 * EPS
    assert np.max(np.abs(r.y[first, 0] - r.t[first] ** 2 / 2)) <= 64 * EPS
    # after it the actuator's slope stays within [-1, 1] (it falls at -1 first: u' = -5 y < -1)
    dt = np.diff(r.t)
    slope = np.diff(r.y[:, 1])[dt > 0] / dt[dt > 0]
    assert np.all(np.abs(slope) <= 1 + 1e-9) and np.min(slope) < -1 + 1e-9


def test_slopes_of_sources_are_exact_and_taken_on_the_pieces_side():
    s = Sine(amplitude=2.0, frequency=3.0, phase=0.4)
    assert signal_slope(s, 0.7) == pytest.approx(6.0 * np.cos(2.1 + 0.4), rel=4 * EPS)
    ramp = Ramp(slope=2.0, start=1.0)
    assert signal_slope(ramp, 0.5) == 0.0 and signal_slope(ramp, 1.5) == 2.0
    assert signal_slope(ramp, 1.0) == 2.0  # from the right at its corner: the piece that starts there
    assert signal_slope(ramp, 1.0, lo=0.0, hi=1.0) == 0.0  # the end of the piece before the corner


def test_bad_slew_rates_are_refused_naming_the_key():
    with pytest.raises(BlockError, match="`rising` is -1; the rising slew rate must be positive") as e:
        RateLimiter(rising=-1, input="u")
    assert e.value.key == "rising"
    with pytest.raises(BlockError, match="`falling` is 2; the falling slew rate must be negative") as e:
        RateLimiter(falling=2, input="u")
    assert e.value.key == "falling"
