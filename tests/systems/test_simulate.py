"""simulate(): accuracy against the exact LTI response, restarts at input breakpoints,
output times, fixed-step methods, failures and the Response type.

Errors are asserted in units of the tolerance: |x - x_exact| / (rtol |x_exact| + atol),
the weighted error ode45 controls (per step; the global error is what is measured here).
"""

from __future__ import annotations

import numpy as np
import pytest

from odelab.analysis.lti import lti_response
from odelab.exceptions import InputError
from odelab.signals import Function, Ramp, Sine, Step, Table
from odelab.solution import Stats
from odelab.solvers.api import solve
from odelab.systems.simulate import Response, simulate
from odelab.systems.statespace import StateSpace


@pytest.fixture
def plant() -> StateSpace:
    # the lab's mass-spring-damper m = 1, k = 3, b = 4, sensor gain q = 10
    return StateSpace([[0, 1], [-3, -4]], [[0], [1]], [[10, 0]], [[0]], states=["x", "v"], inputs=["F"],
                      outputs=["y"])


def tolerance_units(x, x_exact, rtol, atol):
    return np.abs(x - x_exact) / (rtol * np.abs(x_exact) + atol)


def peak_units(x, x_exact, rtol, atol):
    """Like tolerance_units, with each state's peak |x| as its scale: the global error
    near a zero crossing of an oscillating state is not small relative to the state."""
    return np.abs(x - x_exact) / (rtol * np.max(np.abs(x_exact), axis=0) + atol)


def naive(plant, u, tspan, **options):
    """A solve that ignores the breakpoints: one call over the whole span."""
    return solve(lambda t, x: plant.dynamics(t, x, np.array([u(t)])), tspan, [0.0, 0.0], **options)


class TestUnitStep:
    @pytest.mark.parametrize("rtol, atol", [(1e-3, 1e-6), (1e-6, 1e-9), (1e-9, 1e-12)])
    def test_ode45_within_the_tolerance(self, plant, rtol, atol):
        r = simulate(plant, [0, 10], [0, 0], Step(), rtol=rtol, atol=atol)
        x_exact, y_exact = lti_response(plant, r.t, [0, 0], Step())
        # measured max 0.60, 0.46, 0.83 tolerance units
        assert tolerance_units(r.x, x_exact, rtol, atol).max() < 1.5
        assert tolerance_units(r.y, y_exact, rtol, 10 * atol).max() < 1.5  # y = 10 x

    def test_default_tolerances_max_error(self, plant):
        r = simulate(plant, [0, 10], [0, 0], Step())
        _, y_exact = lti_response(plant, r.t, [0, 0], Step())
        err = np.abs(r.y - y_exact).max()
        assert 1e-6 < err < 3e-4  # measured 9.1e-5 with MATLAB's rtol = 1e-3 (y reaches 3.33)

    def test_response_fields(self, plant):
        r = simulate(plant, [0, 10], [0, 0], Step())
        assert isinstance(r, Response) and r.success and r.status == "success"
        assert r.method == "ode45" and r.message == "ode45 reached t = 10."
        assert (r.states, r.inputs, r.outputs) == (("x", "v"), ("F",), ("y",))
        n = r.t.size
        assert r.x.shape == (n, 2) and r.u.shape == (n, 1) and r.y.shape == (n, 1)
        assert np.all(r.u == 1.0)
        np.testing.assert_array_equal(r.y[:, 0], 10 * r.x[:, 0])
        np.testing.assert_array_equal(r.signal("y"), r.y[:, 0])
        np.testing.assert_array_equal(r.signal("v"), r.x[:, 1])
        np.testing.assert_array_equal(r.signal("F"), r.u[:, 0])
        with pytest.raises(InputError, match="no signal named 'z'"):
            r.signal("z")
        assert r.breakpoints == ()
        with pytest.raises(ValueError):
            r.t[0] = 1.0  # read-only

    def test_without_breakpoints_it_is_one_solve_on_the_user_tspan(self, plant):
        # MATLAB parity: the same call as ode45(@(t, x) A x + B u(t), [0 10], x0)
        r = simulate(plant, [0, 10], [0.5, 0], Sine(frequency=2.0))
        sol = solve(lambda t, x: plant.dynamics(t, x, np.array([np.sin(2.0 * t)])), [0, 10], [0.5, 0])
        np.testing.assert_array_equal(r.t, sol.t)
        np.testing.assert_array_equal(r.x, sol.y)
        assert r.stats == sol.stats


class TestStepAtOne:
    def test_zero_before_the_step_and_exact_just_after(self, plant):
        rtol, atol = 1e-3, 1e-6
        r = simulate(plant, [0, 5], [0, 0], Step(1.0))
        assert r.breakpoints == (1.0,)
        assert "restarted at the input breakpoints t = 1" in r.message
        before = r.t < 1
        assert before.sum() >= 2
        assert np.all(r.x[before] == 0.0) and np.all(r.y[before] == 0.0)  # exactly
        assert np.count_nonzero(r.t == 1.0) == 1  # once, from the second piece
        x_exact, y_exact = lti_response(plant, r.t, [0, 0], Step(1.0))
        first = np.searchsorted(r.t, 1.0, side="right")
        # measured 5e-11 units: the restarted solver takes a tiny first step
        assert tolerance_units(r.x[first], x_exact[first], rtol, atol).max() < 1e-3
        assert tolerance_units(r.x, x_exact, rtol, atol).max() < 1.0  # measured 0.18

    def test_against_a_solve_that_ignores_the_breakpoint(self, plant):
        rtol, atol = 1e-3, 1e-6
        r = simulate(plant, [0, 5], [0, 0], Step(1.0))
        sol = naive(plant, Step(1.0), [0, 5])
        x_exact, _ = lti_response(plant, r.t, [0, 0], Step(1.0))
        x_naive, _ = lti_response(plant, sol.t, [0, 0], Step(1.0))
        after = (sol.t >= 1.0) & (sol.t <= 1.5)
        # the step inside a step of the integrator: rejected steps, and an error of tens
        # of tolerance units around t = 1 (measured 72), even a response before the step
        assert sol.stats.nfailed >= 5 and r.stats.nfailed == 0  # measured 12 and 0
        assert r.stats.nfevals < sol.stats.nfevals  # measured 110 and 223
        assert tolerance_units(sol.y[after], x_naive[after], rtol, atol).max() > 10
        assert np.abs(sol.y[sol.t < 1]).max() > 0  # measured 5.9e-5: dense output in the straddling step
        assert tolerance_units(r.x, x_exact, rtol, atol).max() < 1.0

    def test_stats_are_the_pieces_summed(self, plant):
        r = simulate(plant, [0, 5], [0, 0], Step(1.0), max_step=0.5)
        one = solve(lambda t, x: plant.dynamics(t, x, np.zeros(1)), [0, 1], [0, 0], max_step=0.5)
        two = solve(lambda t, x: plant.dynamics(t, x, np.ones(1)), [1, 5], one.y[-1], max_step=0.5)
        assert r.stats == Stats(
            one.stats.nsteps + two.stats.nsteps,
            one.stats.nfailed + two.stats.nfailed,
            one.stats.nfevals + two.stats.nfevals,
        )
        np.testing.assert_array_equal(r.t, np.concatenate([one.t[:-1], two.t]))
        np.testing.assert_array_equal(r.x, np.concatenate([one.y[:-1], two.y]))

    def test_output_jumps_at_the_breakpoint_with_feedthrough(self):
        direct = StateSpace([[-1.0]], [1.0], [1.0], [2.0])  # y = x + 2u
        r = simulate(direct, [0, 3], [0.0], Step(1.0))
        at = int(np.flatnonzero(r.t == 1.0)[0])
        assert r.y[at - 1, 0] == 0.0 and r.u[at - 1, 0] == 0.0
        assert r.u[at, 0] == 1.0 and r.y[at, 0] == 2.0  # the value after the step
        assert r.x[at, 0] == 0.0

    def test_default_max_step_is_that_of_the_whole_span(self, plant):
        # zero input and state on [0, 1): ode45 grows its step up to max_step. MATLAB's
        # default for [0, 10] is 1; one tenth of the piece [0, 1] would force 10 steps.
        r = simulate(plant, [0, 10], [0, 0], Step(1.0), refine=1)
        assert np.count_nonzero(r.t < 1) < 10
        r = simulate(plant, [0, 10], [0, 0], Step(1.0), refine=1, MaxStep=0.05)
        assert np.count_nonzero(r.t < 1) >= 20

    def test_ode113_pieces_keep_the_whole_span_max_step(self, plant):
        # At rest on [0, 1) ode113's first step is the whole piece (max_step 1, not 0.1).
        r = simulate(plant, [0, 10], [0, 0], Step(1.0), method="ode113")
        assert np.count_nonzero(r.t < 1) == 1
        assert r.stats.nfevals == 2 + 2 * r.stats.nsteps + r.stats.nfailed  # f(t0) once per piece
        x_exact, _ = lti_response(plant, r.t, [0, 0], Step(1.0))
        assert tolerance_units(r.x, x_exact, 1e-3, 1e-6).max() < 1.5  # measured 0.99


class TestOutputTimes:
    def test_vector_tspan_exactly_as_given(self, plant):
        tspan = np.linspace(0, 10, 41)  # 0.25 apart: 1.0 is a user time, 1.1 is not
        for u in (Step(1.0), Step(1.1), Step() + Ramp(start=2.6), Sine()):
            r = simulate(plant, tspan, [0, 0], u)
            np.testing.assert_array_equal(r.t, tspan)
            x_exact, _ = lti_response(plant, tspan, [0, 0], u)
            assert peak_units(r.x, x_exact, 1e-3, 1e-6).max() < 1.0

    def test_backward_in_time(self, plant):
        tspan = np.linspace(3, 0, 13)
        x3 = np.array([1.0, -0.5])
        r = simulate(plant, tspan, x3, Step(1.3), rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(r.t, tspan)
        # integrate the exact solution forward from the state found at t = 0
        x_exact, _ = lti_response(plant, tspan[::-1], r.x[-1], Step(1.3))
        np.testing.assert_allclose(r.x[::-1], x_exact, rtol=1e-7, atol=1e-9)
        np.testing.assert_array_equal(r.x[0], x3)
        r2 = simulate(plant, [3, 0], x3, Step(1.3))
        assert r2.breakpoints == (1.3,) and np.all(np.diff(r2.t) < 0)


class TestFixedStep:
    def test_rk4_with_h(self, plant):
        r = simulate(plant, [0, 5], [0, 0], Step(), method="rk4", h=0.1)
        np.testing.assert_allclose(r.t, np.linspace(0, 5, 51), rtol=0, atol=1e-15)
        assert r.method == "rk4" and r.stats == Stats(nsteps=50, nfailed=0, nfevals=200)
        _, y_exact = lti_response(plant, r.t, [0, 0], Step())
        assert np.abs(r.y - y_exact).max() < 1e-4  # measured 5.2e-5

    def test_rk4_keeps_order_four_across_an_off_grid_step(self, plant):
        # a step at t = 1.05, between grid points of h = 0.1: restarting there keeps
        # the error O(h^4); integrating across it makes it O(h).
        u = Step(1.05)
        errors, naive_errors = [], []
        for h in (0.1, 0.05, 0.025):
            r = simulate(plant, [0, 5], [0, 0], u, method="rk4", h=h)
            assert 1.05 in r.t
            _, y_exact = lti_response(plant, r.t, [0, 0], u)
            errors.append(np.abs(r.y - y_exact).max())
            sol = naive(plant, u, [0, 5], method="rk4", h=h)
            x_exact, _ = lti_response(plant, sol.t, [0, 0], u)
            naive_errors.append(np.abs(sol.y - x_exact).max())
        order = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
        naive_order = np.log2(np.array(naive_errors[:-1]) / np.array(naive_errors[1:]))
        assert np.all(order > 3.8)  # measured 4.2, 4.1 (errors 5.2e-5, 2.9e-6, 1.7e-7)
        assert np.all(naive_order < 2.0)  # measured 1.6 then 1.0
        assert errors[-1] < 1e-3 * naive_errors[-1]

    def test_scipy_method(self, plant):
        r = simulate(plant, np.linspace(0, 5, 11), [0, 0], Step(1.0), method="DOP853", rtol=1e-10, atol=1e-12)
        x_exact, _ = lti_response(plant, r.t, [0, 0], Step(1.0))
        assert tolerance_units(r.x, x_exact, 1e-10, 1e-12).max() < 10


class TestInputsAndSystems:
    def test_two_inputs_by_name(self):
        mimo = StateSpace([[0, 1], [-3, -4]], [[0, 0], [1, 2]], [10, 0], inputs=["F", "d"])
        u = {"F": Step(), "d": Table([0, 2, 4], [0, 1, 0])}
        r = simulate(mimo, [0, 6], [0, 0], u, rtol=1e-8, atol=1e-11)
        assert r.breakpoints == (2.0, 4.0)  # the table's kinks; t = 0 is the start
        x_exact, _ = lti_response(mimo, r.t, [0, 0], u)
        assert peak_units(r.x, x_exact, 1e-8, 1e-11).max() < 1.0
        np.testing.assert_array_equal(r.u[:, 1], u["d"](r.t))

    def test_no_inputs(self):
        decay = StateSpace([[-2.0]])
        r = simulate(decay, [0, 1], [1.0], rtol=1e-10, atol=1e-12)
        assert r.u.shape == (r.t.size, 0) and r.inputs == ()
        np.testing.assert_allclose(r.x[:, 0], np.exp(-2 * r.t), rtol=1e-9)
        with pytest.raises(InputError, match="no inputs"):
            simulate(decay, [0, 1], [1.0], Step())

    def test_function_input_has_no_breakpoints(self, plant):
        r = simulate(plant, [0, 2], [0, 0], Function(lambda t: np.where(t >= 1, 1.0, 0.0)))
        assert r.breakpoints == ()

    def test_any_object_with_the_protocol(self):
        class Pendulum:
            states, inputs, outputs = ("theta", "omega"), ("tau",), ("theta",)

            def dynamics(self, t, x, u):
                return np.array([x[1], -np.sin(x[0]) + u[0]])

            def output(self, t, x, u):
                return x[:1]

        r = simulate(Pendulum(), [0, 2], [0.1, 0.0], 0.0, rtol=1e-10, atol=1e-12)
        # energy E = omega^2/2 - cos(theta) is conserved without torque
        energy = r.x[:, 1] ** 2 / 2 - np.cos(r.x[:, 0])
        assert np.ptp(energy) < 1e-9
        np.testing.assert_array_equal(r.y[:, 0], r.x[:, 0])

    def test_a_failed_piece_stops_the_simulation(self):
        class Breaks:
            states, inputs, outputs = ("x",), ("u",), ("y",)

            def dynamics(self, t, x, u):
                if t > 2.5:
                    raise ZeroDivisionError("boom")
                return -x + u

            def output(self, t, x, u):
                return x

        r = simulate(Breaks(), [0, 5], [0.0], Step(1.0))
        assert r.status == "failed" and not r.success
        assert "ZeroDivisionError: boom" in r.message
        assert r.t[-1] <= 2.5 and r.t[0] == 0.0 and 1.0 in r.t
        assert r.x.shape == (r.t.size, 1) and r.y.shape == (r.t.size, 1)


class TestArguments:
    @pytest.mark.parametrize(
        "args, kwargs, message",
        [
            (([0, 1], [0, 0, 0]), {}, r"`x0` has 3 entries but the system has 2 states \(x, v\)"),
            (([0, 1], [0, np.nan]), {}, "`x0` must be finite"),
            (([0, 0], [0, 0]), {}, "`tspan` starts and ends at the same time"),
            (([0, 1], [0, 0], [Step(), Step()]), {}, "has 2 signals but the system has 1 input"),
            (([0, 1], [0, 0]), {"method": "ode99"}, "not a method odelab knows"),
            (([0, 1], [0, 0]), {"method": "rk4"}, "give the step `h`"),
        ],
    )
    def test_bad_arguments(self, plant, args, kwargs, message):
        with pytest.raises(InputError, match=message):
            simulate(plant, *args, **kwargs)

    def test_not_a_system(self):
        with pytest.raises(InputError, match="`system` must have dynamics"):
            simulate(object(), [0, 1], [0.0])
