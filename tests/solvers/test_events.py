"""Event location (MATLAB's odezero): exact event times, directions, several events per step, terminal events."""

import math

import numpy as np
import pytest

import odelab

G = 9.81


def free_fall(t, y):
    return [y[1], -G]


def floor(t, y):
    return [y[0]], [1], [-1]


def oscillator(t, y):  # x = sin t with y0 = [0, 1]
    return [y[1], -y[0]]


@pytest.mark.parametrize("method", ["ode23", "ode45"])
def test_free_fall_hits_the_floor_at_the_exact_time(method):
    # h = 10 - g t^2/2 is a quadratic: both methods and their interpolants are exact on it, so
    # the located time is exact up to the location tolerance (odezero's 128 max(eps(t), eps(tnew))
    # for the step [t, tnew] that holds it, tnew <= tfinal = 5), and the state there is the
    # quadratic at te up to round-off (eps times the height's scale, 10).
    sol = odelab.solve(free_fall, [0, 5], [10, 0], method=method, Events=floor)
    exact = math.sqrt(20 / G)
    located = 128 * math.ulp(5.0)
    assert sol.te.shape == (1,) and sol.ye.shape == (1, 2) and sol.ie.tolist() == [0]
    te = sol.te[0]
    assert abs(te - exact) <= located
    eps = np.finfo(float).eps
    assert abs(sol.ye[0, 0] - (10 - G * te**2 / 2)) <= 64 * eps * 10
    assert abs(sol.ye[0, 1] + G * te) <= 64 * eps * G * exact
    # so the height is zero to the speed times te's tolerance
    assert abs(sol.ye[0, 0]) <= G * exact * located + 64 * eps * 10
    # A terminal event ends the solution at te, that point included (as MATLAB's output).
    assert sol.t[-1] == sol.te[0] and np.array_equal(sol.y[-1], sol.ye[0])
    assert sol.status == "success" and sol.message == f"{method} stopped at t = {sol.te[0]:.10g}: terminal event 0 occurred."


def test_harmonic_oscillator_zero_crossings_at_k_pi():
    sol = odelab.ode45(oscillator, [0, 20], [0, 1], events=lambda t, y: ([y[0]], [0], [0]), rtol=1e-8, atol=1e-10)
    # The zero at t0 is not an event (MATLAB's odezero ignores the initial point); every
    # crossing k*pi up to 20 is.
    assert sol.te.size == 6 and sol.ie.tolist() == [0] * 6
    errors = np.abs(sol.te - np.pi * np.arange(1, 7))
    assert errors.max() < 0.2 * 1e-8  # global error of the solution, well inside rtol
    # Events never change the steps: the same run without events takes exactly the same mesh.
    plain = odelab.ode45(oscillator, [0, 20], [0, 1], rtol=1e-8, atol=1e-10)
    np.testing.assert_array_equal(sol.t, plain.t)
    assert sol.stats == plain.stats


@pytest.mark.parametrize("direction, expected", [(1, [2 * np.pi, 4 * np.pi]), (-1, [np.pi, 3 * np.pi, 5 * np.pi])])
def test_direction_filter(direction, expected):
    sol = odelab.ode45(oscillator, [0, 17], [0, 1], events=lambda t, y: ([y[0]], [0], [direction]),
                       rtol=1e-8, atol=1e-10)
    # the zero at t0 is not an event (MATLAB), whichever way the function leaves it
    np.testing.assert_allclose(sol.te, expected, atol=2e-9)


def test_several_events_in_one_step_in_time_order():
    # y = t exactly; MaxStep 1 puts 1.5, 1.6 and 1.7 in the step [1, 2] (and 1.5 twice).
    def events(t, y):
        return [y[0] - 1.5, y[0] - 1.7, y[0] - 1.6, 1.5 - y[0]], [0, 0, 0, 0], [0, 0, 0, 0]

    sol = odelab.ode45(lambda t, y: 1.0, [0, 10], 0.0, events=events, initial_step=1)
    assert sol.t[4] == 1 and sol.t[8] == 2  # refine 4: one step per unit
    assert sol.ie.tolist() == [0, 3, 2, 1]  # two events at 1.5 are reported together
    # located to odezero's tolerance 128 max(eps(t), eps(tnew)) on the step [1, 2]; y = t on
    # the interpolant to its round-off
    np.testing.assert_allclose(sol.te, [1.5, 1.5, 1.6, 1.7], rtol=0, atol=128 * math.ulp(2.0))
    np.testing.assert_allclose(sol.ye[:, 0], sol.te, rtol=0, atol=16 * math.ulp(2.0))
    assert sol.t[-1] == 10


def test_terminal_event_at_the_last_point():
    sol = odelab.ode45(lambda t, y: 1.0, [0, 5], 0.0, events=lambda t, y: ([y[0] - 5], [1], [0]))
    assert sol.te.tolist() == [5.0] and sol.ye[0, 0] == sol.y[-1, 0]
    assert sol.t[-1] == 5.0 and np.all(np.diff(sol.t) > 0)  # no duplicated last point
    assert "terminal event 0" in sol.message


def test_event_at_t0_is_not_terminal():
    # a zero at the initial point is not an event at all (MATLAB's odezero), terminal or not
    sol = odelab.ode45(lambda t, y: 1.0, [0, 3], 0.0, events=lambda t, y: ([y[0]], [1], [0]))
    assert sol.status == "success" and sol.t[-1] == 3 and sol.message == "ode45 reached t = 3."
    assert sol.te.size == 0
    # falling only: the zero at t0 moves up, so nothing is registered at all
    sol = odelab.ode45(lambda t, y: 1.0, [0, 3], 0.0, events=lambda t, y: ([y[0]], [1], [-1]))
    assert sol.te.size == 0 and sol.ye.shape == (0, 1) and sol.t[-1] == 3


def test_terminal_event_cuts_the_refined_output_of_the_last_step():
    sol = odelab.ode45(free_fall, [0, 5], [10, 0], events=floor)
    last4 = sol.t[-5:]
    # Refine output on the shortened step [t, te]: four equal parts
    np.testing.assert_allclose(np.diff(last4), (last4[-1] - last4[0]) / 4, rtol=1e-12)
    exact_h = 10 - G * sol.t**2 / 2
    np.testing.assert_allclose(sol.y[:, 0], exact_h, atol=1e-12)


def test_terminal_event_with_a_vector_tspan_outputs_te():
    sol = odelab.ode45(free_fall, np.linspace(0, 5, 11), [10, 0], events=floor)
    np.testing.assert_array_equal(sol.t[:-1], [0, 0.5, 1.0])
    assert sol.t[-1] == sol.te[0]


def test_scipy_style_event_functions():
    def ground(t, y):
        return y[0]

    ground.terminal = True
    ground.direction = -1

    def apex(t, y):
        return y[1]

    ours = odelab.ode45(free_fall, [0, 5], [10, 5], events=[ground, apex])
    matlab = odelab.ode45(free_fall, [0, 5], [10, 5], events=lambda t, y: ([y[0], y[1]], [1, 0], [-1, 0]))
    np.testing.assert_array_equal(ours.te, matlab.te)
    assert ours.ie.tolist() == [1, 0]
    np.testing.assert_allclose(ours.te, [5 / G, 5 / G + math.sqrt(2 * (10 + 25 / (2 * G)) / G)], atol=1e-13)


def test_extra_args_reach_events():
    sol = odelab.ode45(lambda t, y, g: [y[1], -g], [0, 5], [10, 0], args=(G,),
                       events=lambda t, y, g: ([y[0]], [1], [-1]))
    exact = math.sqrt(20 / G)
    assert abs(sol.te[0] - exact) <= 128 * math.ulp(5.0)  # odezero's tolerance (a step ends by t = 5)


def test_bad_events_functions_say_what_to_return():
    with pytest.raises(odelab.InputError, match=r"must return three arrays \(value, isterminal, direction\)"):
        odelab.ode45(free_fall, [0, 1], [10, 0], events=lambda t, y: y[0])
    with pytest.raises(odelab.InputError, match="returned 2 values but 3 isterminal flags"):
        odelab.ode45(free_fall, [0, 1], [10, 0], events=lambda t, y: ([y[0], y[1]], [1, 0, 0], [0, 0]))
    with pytest.raises(odelab.InputError, match="`events` must be a function"):
        odelab.ode45(free_fall, [0, 1], [10, 0], Events=3)
    with pytest.raises(odelab.InputError, match="`events` does not apply to rk4"):
        odelab.solve(free_fall, [0, 1], [10, 0], method="rk4", h=0.1, events=floor)


def test_an_events_function_that_raises_is_named():
    def boom(t, y):
        if t > 0.5:
            raise KeyError("oops")
        return [y[0]], [1], [-1]

    with pytest.warns(odelab.SolverWarning, match="the events function raised KeyError"):
        sol = odelab.ode45(free_fall, [0, 1], [10, 0], events=boom)
    assert sol.status == "failed" and sol.t[-1] <= 0.5


@pytest.mark.parametrize("k", [1, 3, 8, 9, 20])
def test_the_bracket_test_on_python_floats_is_numpys(k):
    # Up to 8 events the bracket test runs on Python floats; zeros of both signs, infinities
    # and NaN included, it must pick exactly the events numpy's expression picks.
    from odelab.solvers.events import _bracketed

    rng = np.random.default_rng(k)
    values = np.array([0.0, -0.0, 1.0, -1.0, 2.5, np.inf, -np.inf, np.nan, 1e-300, -1e-300])
    for _ in range(3000):
        vL, vR = rng.choice(values, k), rng.choice(values, k)
        direction = rng.choice([-1.0, 0.0, 1.0], k)
        with np.errstate(invalid="ignore"):
            expected = np.flatnonzero((np.sign(vL) != np.sign(vR)) & (direction * (vR - vL) >= 0))
        np.testing.assert_array_equal(_bracketed(vL, vR, direction), expected)


def test_isterminal_and_direction_are_read_at_every_call():
    # MATLAB reads them from every call: a list the function changes in place (the engine keeps
    # a copy of the last one it converted), and a list that holds an array, still count.
    flags = [0]

    def crossings(t, y):
        if t > 5:
            flags[0] = 1  # terminal from t = 5 on
        return [y[0]], flags, [0]

    sol = odelab.ode45(oscillator, [0, 20], [0, 1], events=crossings, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(sol.te, [np.pi, 2 * np.pi], atol=1e-8)  # stops at the first after 5
    assert sol.t[-1] == sol.te[-1] and "terminal event 0" in sol.message
    rising = odelab.ode45(oscillator, [0, 20], [0, 1], rtol=1e-8, atol=1e-10,
                          events=lambda t, y: ([y[0]], [0], [np.array(1.0) if t < 10 else -1]))
    # rising crossings before t = 10, falling ones after: 2 pi, then 5 pi (4 pi rises)
    np.testing.assert_allclose(rising.te, [2 * np.pi, 5 * np.pi], atol=1e-8)


@pytest.mark.parametrize("method", ["ode23", "ode45", "ode89", "ode113", "ode15s"])
def test_a_zero_at_the_initial_point_is_not_an_event_but_its_return_is(method):
    # MATLAB's odezero ignores a zero at t0: a ball released from the floor reports nothing at
    # t0; y = sin t leaves zero and comes back at pi, 2 pi, which are reported. Terminal too:
    # the initial zero does not stop the integration.
    up = odelab.solve(lambda t, y: [1.0], [0, 2], [0.0], method=method, events=lambda t, y: ([y[0]], [1], [0]))
    assert up.te.size == 0 and up.t[-1] == 2 and up.status == "success"
    sine = odelab.solve(lambda t, y: [np.cos(t)], [0, 7], [0.0], method=method, rtol=1e-8, atol=1e-10,
                        events=lambda t, y: ([y[0]], [0], [0]))
    np.testing.assert_allclose(sine.te, [np.pi, 2 * np.pi], atol=1e-6)
    # a function that is zero at t0 and returns within the first step (MaxStep > the return
    # time) is located where it returns
    quick = odelab.solve(lambda t, y: [np.cos(t)], [0, 4], [0.0], method=method, events=lambda t, y: ([y[0]], [1], [-1]),
                         initial_step=3.5, max_step=4, rtol=1e-3) if method in ("ode23", "ode45") else None
    if quick is not None:
        assert quick.te.size == 1 and abs(quick.te[0] - np.pi) < 0.1 and quick.t[-1] == quick.te[0]


@pytest.mark.parametrize("method", ["ode23", "ode45", "ode15s"])
@pytest.mark.parametrize("direction", [-1, 0])
def test_free_fall_from_the_floor_going_up_stops_when_it_comes_back(method, direction):
    # MATLAB: h(0) = 0 is not an event (odezero ignores the initial point), terminal or not; the
    # ball thrown up at 10 m/s lands at 2 v0 / g, where the terminal event stops it. The height
    # is a quadratic, which ode23/ode45 and their interpolants integrate exactly: te to the
    # location tolerance of its step; ode15s to its own error (rtol 1e-8 on a 2 s flight).
    sol = odelab.solve(free_fall, [0, 5], [0.0, 10.0], method=method, rtol=1e-8, atol=1e-10,
                       events=lambda t, y: ([y[0]], [1], [direction]))
    landing = 2 * 10.0 / G
    assert sol.te.size == 1 and sol.t[-1] == sol.te[0] and "terminal event 0" in sol.message
    bound = 128 * math.ulp(5.0) if method != "ode15s" else 1e-6
    assert abs(sol.te[0] - landing) <= bound, (sol.te[0] - landing)


def test_an_oscillator_started_at_a_zero_reports_only_its_returns():
    # x = sin t: zero at t0 (ignored), then k pi; terminal at the first return, pi, not at 0
    sol = odelab.ode45(oscillator, [0, 20], [0, 1], events=lambda t, y: ([y[0]], [1], [0]), rtol=1e-8, atol=1e-10)
    assert sol.te.size == 1 and abs(sol.te[0] - np.pi) < 0.2 * 1e-8 and sol.t[-1] == sol.te[0]
