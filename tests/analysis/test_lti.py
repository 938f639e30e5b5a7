"""Exact LTI responses against closed forms derived by hand, and against python-control.

The lab plant: m x'' + b x' + k x = u with m = 1, k = 3, b = 4, y = q x with q = 10, so

    G(s) = Y(s)/U(s) = 10 / (s^2 + 4 s + 3) = 10 / ((s + 1)(s + 3)),

poles -1 and -3. Every closed form below comes from partial fractions of G(s) U(s); each
derivation sits next to its test. "Exact" means agreement to a few units of round-off of
the largest value involved (eps = 2.2e-16).
"""

from __future__ import annotations

import numpy as np
import pytest

from odelab.analysis.lti import NoExactForm, lti_response
from odelab.exceptions import InputError
from odelab.signals import Constant, Function, Pulse, Ramp, Sine, Step, Table, Term, Terms
from odelab.systems.statespace import StateSpace

EPS = np.finfo(float).eps
T = np.linspace(0.0, 10.0, 1001)


@pytest.fixture
def plant() -> StateSpace:
    return StateSpace([[0, 1], [-3, -4]], [[0], [1]], [[10, 0]], [[0]], states=["x", "v"])


def assert_exact(actual, expected, ulps=40):
    """|actual - expected| <= ulps * eps * max(1, max |expected|)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    bound = ulps * EPS * max(1.0, float(np.max(np.abs(expected))))
    err = float(np.max(np.abs(actual - expected)))
    assert err <= bound, f"max error {err:.3g} > {bound:.3g}"


def step_response(t):
    # 10 / (s (s+1)(s+3)) = 10 [ 1/(3 s) - 1/(2 (s+1)) + 1/(6 (s+3)) ]
    #   residues: at 0: 1/(1*3) = 1/3; at -1: 1/((-1)(2)) = -1/2; at -3: 1/((-3)(-2)) = 1/6
    return 10 * (1 / 3 - np.exp(-t) / 2 + np.exp(-3 * t) / 6)


def ramp_response(t):
    # U = 1/s^2: 10 / (s^2 (s+1)(s+3)) = 10 [ a/s^2 + b/s + c/(s+1) + d/(s+3) ]
    #   a = 1/(1*3) = 1/3
    #   b = d/ds [1/((s+1)(s+3))] at 0 = -(2s+4)/((s+1)(s+3))^2 at 0 = -4/9
    #   c = 1/((-1)^2 (2)) = 1/2,  d = 1/((-3)^2 (-2)) = -1/18   (check: b + c + d = 0)
    return 10 * (t / 3 - 4 / 9 + np.exp(-t) / 2 - np.exp(-3 * t) / 18)


def sine_response(t, w=0.2):
    # U = w/(s^2 + w^2), w = 0.2. Steady state: 10 Im[G0(iw) e^{iwt}] with
    #   G0(iw) = 1/((1 + 0.2i)(3 + 0.2i)) = 1/(2.96 + 0.8i) = (2.96 - 0.8i)/9.4016,
    #   9.4016 = 2.96^2 + 0.8^2, so y_ss = 10 (2.96 sin wt - 0.8 cos wt) / 9.4016.
    # Transient residues of 10 w / ((s^2 + w^2)(s+1)(s+3)):
    #   at -1: 10*0.2 / ((1 + 0.04)(2))  = 1/1.04 = 25/26
    #   at -3: 10*0.2 / ((9 + 0.04)(-2)) = -1/9.04 = -25/226
    # (check y(0) = 25/26 - 25/226 - 8/9.4016 = 0 and y'(0) = 0, as C B = 0.)
    d = 2.96**2 + 0.8**2
    steady = 10 * (2.96 * np.sin(w * t) - 0.8 * np.cos(w * t)) / d
    return steady + 25 / 26 * np.exp(-t) - 25 / 226 * np.exp(-3 * t)


class TestClosedForms:
    def test_unit_step(self, plant):
        x, y = lti_response(plant, T, [0, 0], Step())
        assert x.shape == (T.size, 2) and y.shape == (T.size, 1)
        assert np.max(np.abs(y[:, 0] - step_response(T))) < 2e-14
        # velocity v = x' = (e^{-t} - e^{-3t}) / 2
        assert_exact(x[:, 1], (np.exp(-T) - np.exp(-3 * T)) / 2)

    def test_ramp(self, plant):
        _, y = lti_response(plant, T, [0, 0], Ramp())
        assert_exact(y[:, 0], ramp_response(T))

    def test_sine(self, plant):
        _, y = lti_response(plant, T, [0, 0], Sine(frequency=0.2))
        assert_exact(y[:, 0], sine_response(T))

    def test_cosine_through_the_phase(self, plant):
        # cos(0.2 t) = sin(0.2 t + pi/2); by linearity its response is the derivative of
        # the sine's divided by w: y_c = y_s' / 0.2, and
        # y_s' = 10 w (2.96 cos wt + 0.8 sin wt)/9.4016 - 25/26 e^{-t} + 75/226 e^{-3t}.
        w, d = 0.2, 2.96**2 + 0.8**2
        expected = (10 * w * (2.96 * np.cos(w * T) + 0.8 * np.sin(w * T)) / d - 25 / 26 * np.exp(-T)
                    + 75 / 226 * np.exp(-3 * T)) / w
        _, y = lti_response(plant, T, [0, 0], Sine(frequency=0.2, phase=np.pi / 2))
        assert_exact(y[:, 0], expected, ulps=100)  # cos from sin(. + pi/2): pi/2 is rounded

    def test_step_at_one(self, plant):
        t = np.linspace(0.0, 5.0, 501)  # t = 1 is on the grid (index 100)
        x, y = lti_response(plant, t, [0, 0], Step(1.0))
        assert np.all(x[t < 1] == 0.0) and np.all(y[t < 1] == 0.0)
        assert y[100, 0] == 0.0  # continuous output (D = 0) at the step time
        assert_exact(y[:, 0], np.where(t >= 1, step_response(np.maximum(t - 1, 0)), 0.0))

    def test_nonzero_initial_state(self, plant):
        # zero-input: x'' + 4x' + 3x = 0, x(0) = 1, x'(0) = 0 -> x = 3/2 e^{-t} - 1/2 e^{-3t};
        # with a unit step on top the responses add.
        free = 10 * (1.5 * np.exp(-T) - 0.5 * np.exp(-3 * T))
        _, y = lti_response(plant, T, [1, 0], None)
        assert_exact(y[:, 0], free)
        _, y = lti_response(plant, T, [1, 0], Step())
        assert_exact(y[:, 0], free + step_response(T))

    def test_exponential_input(self, plant):
        # u = e^{-2t}: 10 / ((s+1)(s+2)(s+3)), residues 1/2, -1, 1/2
        u = Terms((Term(1.0, rate=-2.0),), start=0.0)
        _, y = lti_response(plant, T, [0, 0], u)
        assert_exact(y[:, 0], 10 * (np.exp(-T) / 2 - np.exp(-2 * T) + np.exp(-3 * T) / 2))

    def test_input_at_a_pole_double_root(self, plant):
        # u = e^{-t}, a pole of the plant: 10 / ((s+1)^2 (s+3)) =
        #   10 [ 1/(2 (s+1)^2) - 1/(4 (s+1)) + 1/(4 (s+3)) ]   (d/ds 1/(s+3) at -1 = -1/4)
        # so y = 10 (t e^{-t}/2 - e^{-t}/4 + e^{-3t}/4): a Jordan block that an
        # eigen-decomposition could not handle.
        u = Terms((Term(1.0, rate=-1.0),), start=0.0)
        _, y = lti_response(plant, T, [0, 0], u)
        assert_exact(y[:, 0], 10 * (T * np.exp(-T) / 2 - np.exp(-T) / 4 + np.exp(-3 * T) / 4))

    def test_quadratic_input(self, plant):
        # u = t^2 = 2 * integral of t, so y = 2 * integral_0^t of the ramp response:
        # y = 20 (t^2/6 - 4t/9 + 1/2 - 1/54 - e^{-t}/2 + e^{-3t}/54)
        u = Terms((Term(1.0, power=2),), start=0.0)
        _, y = lti_response(plant, T, [0, 0], u)
        expected = 20 * (T**2 / 6 - 4 * T / 9 + 13 / 27 - np.exp(-T) / 2 + np.exp(-3 * T) / 54)
        assert_exact(y[:, 0], expected)

    def test_undamped_resonance(self):
        # x'' + w^2 x = sin(w t), x(0) = x'(0) = 0: x = (sin wt - w t cos wt) / (2 w^2)
        # (particular -t cos(wt)/(2w) plus sin(wt)/(2w^2) to make x'(0) = 0)
        w = 3.0
        osc = StateSpace([[0, 1], [-w * w, 0]], [0, 1])
        t = np.linspace(0, 20, 801)
        x, _ = lti_response(osc, t, [0, 0], Sine(frequency=w))
        assert_exact(x[:, 0], (np.sin(w * t) - w * t * np.cos(w * t)) / (2 * w * w), ulps=100)

    def test_one_output_time_and_repeated_times(self, plant):
        x, y = lti_response(plant, [2.0], [1.0, -1.0], Step())
        np.testing.assert_array_equal(x, [[1.0, -1.0]])
        np.testing.assert_array_equal(y, [[10.0]])
        x, _ = lti_response(plant, [0.0, 1.0, 1.0, 2.0], [0, 0], Step())
        np.testing.assert_array_equal(x[1], x[2])


class TestSuperposition:
    def test_sum_of_inputs(self, plant):
        u = Step() + 2 * Ramp() - 3 * Sine(frequency=0.2)
        _, y = lti_response(plant, T, [0, 0], u)
        assert_exact(y[:, 0], step_response(T) + 2 * ramp_response(T) - 3 * sine_response(T))

    def test_pulse_is_a_sum_of_shifted_steps(self, plant):
        # a pulse of height 2, period 2, width 25%, delay 0.5: steps up at 0.5 + 2k, down at 1 + 2k
        u = Pulse(amplitude=2.0, period=2.0, width=0.25, delay=0.5)
        _, y = lti_response(plant, T, [0, 0], u)
        expected = np.zeros_like(T)
        for k in range(5):
            for tau, sign in ((0.5 + 2 * k, 1.0), (1.0 + 2 * k, -1.0)):
                expected += sign * 2.0 * np.where(T >= tau, step_response(np.maximum(T - tau, 0)), 0.0)
        assert_exact(y[:, 0], expected)

    def test_two_inputs_and_feedthrough(self, plant):
        # u1 enters the force, u2 the force twice over and the output through D = [0, 1]
        mimo = StateSpace([[0, 1], [-3, -4]], [[0, 0], [1, 2]], [10, 0], [0, 1], inputs=["F", "d"])
        _, y = lti_response(mimo, T, [0, 0], {"F": Step(), "d": Sine(frequency=0.2)})
        assert_exact(y[:, 0], step_response(T) + 2 * sine_response(T) + np.sin(0.2 * T))
        _, y_seq = lti_response(mimo, T, [0, 0], [Step(), Sine(frequency=0.2)])
        np.testing.assert_array_equal(y, y_seq)

    def test_output_jumps_with_the_input_when_D_is_nonzero(self):
        direct = StateSpace([[-1.0]], [1.0], [1.0], [2.0])
        x, y = lti_response(direct, [0.0, np.nextafter(1.0, 0.0), 1.0, 2.0], [0.0], Step(1.0))
        assert y[1, 0] == 0.0 and y[2, 0] == 2.0  # u(1) is the value after the step
        # x' = -x + u after the step: x = 1 - e^{-(t-1)}
        assert_exact(x[:, 0], [0.0, 0.0, 0.0, 1 - np.exp(-1.0)])


class TestAgainstPythonControl:
    """``control.forced_response`` interpolates the input linearly between the time points
    and integrates that exactly (its docs: "assuming linear interpolation of the inputs
    between time points"), so it is exact for inputs linear between the points."""

    control = pytest.importorskip("control")

    def forced(self, plant, t, u_samples, x0):
        sys = self.control.ss(plant.A, plant.B, plant.C, plant.D)
        r = self.control.forced_response(sys, t, u_samples, X0=x0)
        return r.states.T, np.atleast_1d(r.outputs)

    @pytest.mark.parametrize(
        "signal",
        [Step(), Ramp(), Ramp(slope=-0.5, start=2.0, initial=1.0), Table([0, 2, 3, 7], [0, 1, -1, 2])],
        ids=["step", "ramp", "delayed ramp", "table"],
    )
    def test_piecewise_linear_inputs(self, plant, signal):
        # every kink of these inputs is on the grid, so linear interpolation is exact
        x_ref, y_ref = self.forced(plant, T, signal(T), [0.5, -1.0])
        x, y = lti_response(plant, T, [0.5, -1.0], signal)
        assert_exact(x, x_ref, ulps=200)  # forced_response steps along the grid: a little
        assert_exact(y[:, 0], y_ref, ulps=200)  # round-off accumulates on its side

    def test_long_measured_table(self, plant):
        t = np.arange(2001) * 0.01
        u = Table(t, np.sin(t) + 0.1 * np.cos(7 * t))
        x_ref, y_ref = self.forced(plant, t, u(t), [0, 0])
        _, y = lti_response(plant, t, [0, 0], u)
        assert_exact(y[:, 0], y_ref, ulps=400)


class TestErrors:
    def test_function_has_no_exact_form(self, plant):
        with pytest.raises(NoExactForm) as info:
            lti_response(plant, T, [0, 0], Function(np.sin, label="sin(t)"))
        err = info.value
        assert isinstance(err, InputError) and isinstance(err, ValueError)
        assert err.key == "u1"
        assert "Input `u1` is Function('sin(t)'), which has no exact form" in str(err)
        assert "high-accuracy numerical reference" in str(err)

    def test_sum_with_a_function_has_no_exact_form(self, plant):
        with pytest.raises(NoExactForm, match="Input `u1`"):
            lti_response(plant, T, [0, 0], Step() + Function(np.sin))

    @pytest.mark.parametrize(
        "t, x0, u, message",
        [
            ([0.0, 2.0, 1.0], [0, 0], None, r"non-decreasing.*t\[2\] = 1.0 comes before t\[1\] = 2.0"),
            ([0.0, np.nan], [0, 0], None, "`t` must be finite"),
            ([], [0, 0], None, "non-empty"),
            (T, [0, 0, 0], None, r"`x0` has 3 entries but the system has 2 states \(x, v\)"),
            (T, [0, np.inf], None, "`x0` must be finite"),
            (T, [0, 0], [Step(), Step()], "has 2 signals but the system has 1 input"),
            (T, [0, 0], "step", "`u` must be a signal"),
        ],
    )
    def test_bad_arguments(self, plant, t, x0, u, message):
        with pytest.raises(InputError, match=message):
            lti_response(plant, t, x0, u)


def test_many_output_times_in_chunks(plant):
    # more output times than one stacked expm call takes (CHUNK = 2048)
    t = np.linspace(0.0, 10.0, 5001)
    _, y = lti_response(plant, t, [0, 0], Step() + Constant(1.0))
    assert_exact(y[:, 0], 2 * step_response(t))
