"""Operating points, Jacobians, linearisation and how good the linear model is.

The systems are the lab's: the pendulum, the linear mass-spring-damper plant (m = 1,
b = 4, k = 3, measured as y = 10 x) and the hardening spring
m x'' + b x' + k1 x + k3 x^3 = f with m = 1, b = 4, k1 = 3, k3 = 2.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from odelab.analysis.linearize import (
    AmplitudeStudy,
    LinearizationComparison,
    NoEquilibriumError,
    NotAnEquilibriumWarning,
    OperatingPoint,
    amplitude_study,
    compare_linearization,
    jacobians,
    linearize,
    operating_point,
)
from odelab.exceptions import InputError
from odelab.systems.nonlinear import NonlinearSystem

G, L, C_DAMP = 9.81, 0.5, 0.3  # pendulum
M, B_DAMP, K1, K3 = 1.0, 4.0, 3.0, 2.0  # hardening spring
SPRING_PARAMS = {"m": M, "b": B_DAMP, "k1": K1, "k3": K3}
TIGHT = {"rtol": 1e-10, "atol": 1e-12}


def pendulum_exact_A(theta):
    return np.array([[0.0, 1.0], [-G / L * math.cos(theta), -C_DAMP]])


def pendulum_from_expressions():
    return NonlinearSystem.from_expressions(
        {"theta": "omega", "omega": "-g/L*sin(theta) - c*omega + u"},
        inputs=["u"],
        parameters={"g": G, "L": L, "c": C_DAMP},
    )


def pendulum_numpy():
    return NonlinearSystem(
        lambda t, x, u: np.array([x[1], -G / L * np.sin(x[0]) - C_DAMP * x[1] + u[0]]),
        states=["theta", "omega"],
        inputs=["u"],
    )


class RealOnly:
    """A pendulum written with the math module: rejects complex input with a TypeError."""

    def __init__(self):
        self.complex_calls = 0

    def __call__(self, t, x, u):
        if np.iscomplexobj(x) or np.iscomplexobj(u):
            self.complex_calls += 1
        return [x[1], -G / L * math.sin(x[0]) - C_DAMP * x[1] + u[0]]


def spring_from_expressions():
    return NonlinearSystem.from_expressions(
        {"x": "v", "v": "(f - b*v - k1*x - k3*x^3) / m"}, inputs=["f"], parameters=SPRING_PARAMS
    )


def spring_numpy():
    return NonlinearSystem(
        lambda t, x, u: np.array([x[1], (u[0] - B_DAMP * x[1] - K1 * x[0] - K3 * x[0] ** 3) / M]),
        states=["x", "v"],
        inputs=["f"],
    )


def spring_equilibrium(f_bar):
    """The real root of k3 x^3 + k1 x - f = 0 (Cardano; one real root since k1, k3 > 0)."""
    p, q = K1 / K3, -f_bar / K3
    disc = math.sqrt(q * q / 4 + p**3 / 27)
    return math.copysign(abs(-q / 2 + disc) ** (1 / 3), -q / 2 + disc) + math.copysign(
        abs(-q / 2 - disc) ** (1 / 3), -q / 2 - disc
    )


# ---------------------------------------------------------------------------------------
# Jacobians
# ---------------------------------------------------------------------------------------


class TestJacobians:
    @pytest.mark.parametrize("theta", [0.0, math.pi, 0.7])
    @pytest.mark.parametrize("make", [pendulum_from_expressions, pendulum_numpy])
    def test_pendulum_to_1e12(self, make, theta):
        A, B, C, D = jacobians(make(), [theta, 0.4], [0.2])
        np.testing.assert_allclose(A, pendulum_exact_A(theta), rtol=0, atol=1e-12)
        np.testing.assert_allclose(B, [[0.0], [1.0]], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(C, np.eye(2))  # y = x: exactly
        np.testing.assert_array_equal(D, np.zeros((2, 1)))

    def test_lab_plant_is_exact(self):
        plant = NonlinearSystem.from_expressions(
            {"x": "v", "v": "(f - b*v - k*x) / m"},
            inputs=["f"],
            outputs={"y": "q*x"},
            parameters={"m": 1.0, "b": 4.0, "k": 3.0, "q": 10.0},
        )
        lin = linearize(plant)
        np.testing.assert_allclose(lin.A, [[0.0, 1.0], [-3.0, -4.0]], rtol=0, atol=1e-15)
        np.testing.assert_allclose(lin.B, [[0.0], [1.0]], rtol=0, atol=1e-15)
        np.testing.assert_allclose(lin.C, [[10.0, 0.0]], rtol=0, atol=1e-15)
        np.testing.assert_allclose(lin.D, [[0.0]], rtol=0, atol=1e-15)
        assert lin.states == ("x", "v") and lin.inputs == ("f",) and lin.outputs == ("y",)
        np.testing.assert_array_equal(lin.operating_point.x, [0.0, 0.0])

    def test_real_only_function_falls_back_accurately(self):
        fun = RealOnly()
        sys = NonlinearSystem(fun, states=["theta", "omega"], inputs=["u"])
        for theta in (0.0, math.pi, 0.7):
            A, B, _, _ = jacobians(sys, [theta, 0.4], [0.2])
            np.testing.assert_allclose(A, pendulum_exact_A(theta), rtol=0, atol=1e-9)
            np.testing.assert_allclose(B, [[0.0], [1.0]], rtol=0, atol=1e-9)
        assert fun.complex_calls > 0  # complex step was tried, and rejected

    def test_richardson_accuracy_on_a_nasty_function(self):
        def f(t, x, u):
            return np.array([np.exp(x[0] * x[1]) + u[0] ** 3, np.sin(3 * x[0]) / (1 + x[1] ** 2)])

        def exact(x, u):
            e = math.exp(x[0] * x[1])
            A = [[x[1] * e, x[0] * e], [3 * math.cos(3 * x[0]) / (1 + x[1] ** 2), -2 * x[1] * math.sin(3 * x[0]) / (1 + x[1] ** 2) ** 2]]
            return np.array(A), np.array([[3 * u[0] ** 2], [0.0]])

        sys = NonlinearSystem(f, states=["a", "b"], inputs=["u"])
        x, u = [0.8, -1.3], [2.0]
        A_ex, B_ex = exact(x, u)
        A, B, _, _ = jacobians(sys, x, u, method="richardson")
        np.testing.assert_allclose(A, A_ex, rtol=1e-11, atol=1e-12)
        np.testing.assert_allclose(B, B_ex, rtol=1e-11, atol=1e-12)
        A, B, _, _ = jacobians(sys, x, u, method="complex-step")
        np.testing.assert_allclose(A, A_ex, rtol=1e-15, atol=1e-15)

    def test_non_analytic_function_is_caught_by_the_cross_check(self):
        # Quadratic drag c |v| v accepts complex input but complex step gets it wrong
        # (Im |v + ih| (v + ih) / h = |v|, not 2|v|); the central-difference check catches it.
        sys = NonlinearSystem(
            lambda t, x, u: np.array([x[1], -K1 * x[0] - 0.7 * np.abs(x[1]) * x[1] + u[0]]),
            states=["x", "v"],
            inputs=["f"],
        )
        A, _, _, _ = jacobians(sys, [0.0, 0.5], [0.0])
        assert A[1, 1] == pytest.approx(-0.7 * 2 * 0.5, abs=1e-10)

    def test_forced_complex_step_on_a_real_only_function(self):
        sys = NonlinearSystem(RealOnly(), states=["theta", "omega"], inputs=["u"])
        with pytest.raises(InputError, match="does not support complex-step"):
            jacobians(sys, [0.0, 0.0], [0.0], method="complex-step")
        with pytest.raises(InputError, match="`method` must be one of"):
            jacobians(sys, [0.0, 0.0], [0.0], method="forward")

    def test_output_jacobians(self):
        sys = NonlinearSystem(
            lambda t, x, u: np.array([x[1], -x[0] + u[0]]),
            lambda t, x, u: np.array([x[0] ** 2 + 2 * u[0], np.sin(x[1]) * u[0]]),
            states=["x", "v"],
            inputs=["f"],
            outputs=["p", "q"],
        )
        x, u = [1.5, 0.3], [2.0]
        _, _, C, D = jacobians(sys, x, u)
        np.testing.assert_allclose(C, [[3.0, 0.0], [0.0, math.cos(0.3) * 2.0]], atol=1e-14)
        np.testing.assert_allclose(D, [[2.0], [math.sin(0.3)]], atol=1e-14)

    @settings(max_examples=40, deadline=None)
    @given(
        coef=st.lists(st.floats(-3, 3, allow_nan=False), min_size=5, max_size=5),
        point=st.lists(st.floats(-1.5, 1.5, allow_nan=False), min_size=3, max_size=3),
    )
    def test_complex_step_and_richardson_agree(self, coef, point):
        a, b, c, d, e = coef

        def f(t, x, u):
            return np.array([a * x[0] * x[1] + b * np.sin(x[1]) + u[0], c * np.exp(0.5 * d * x[0]) + e * u[0] ** 2 * x[1]])

        sys = NonlinearSystem(f, states=["p", "q"], inputs=["u"])
        x, u = point[:2], point[2:]
        cs = jacobians(sys, x, u, method="complex-step")
        ri = jacobians(sys, x, u, method="richardson")
        scale = 1.0 + max(np.max(np.abs(M)) for M in cs)
        for M_cs, M_ri in zip(cs, ri):
            np.testing.assert_allclose(M_ri, M_cs, rtol=0, atol=1e-10 * scale)

    def test_statespace_returns_its_own_matrices(self):
        from odelab.systems.statespace import StateSpace

        ss = StateSpace([[0, 1], [-3, -4]], [0, 1], [10, 0], 0)
        A, B, C, D = jacobians(ss, [1.0, 2.0], [3.0])
        for got, want in zip((A, B, C, D), ss.matrices()):
            np.testing.assert_array_equal(got, want)

    def test_agrees_with_python_control(self):
        ct = pytest.importorskip("control")
        sys = spring_numpy()
        x_bar = spring_equilibrium(1.0)
        ref = ct.linearize(
            ct.nlsys(lambda t, x, u, params: sys.dynamics(t, x, u), None, inputs=1, outputs=2, states=2),
            [x_bar, 0.0],
            [1.0],
        )
        A, B, _, _ = jacobians(sys, [x_bar, 0.0], [1.0])
        # python-control uses forward differences (eps = 1e-6): agreement to ~1e-5 only.
        np.testing.assert_allclose(A, ref.A, atol=1e-5)
        np.testing.assert_allclose(B, ref.B, atol=1e-5)


# ---------------------------------------------------------------------------------------
# Operating points
# ---------------------------------------------------------------------------------------


class TestOperatingPoint:
    @pytest.mark.parametrize("make", [spring_from_expressions, spring_numpy])
    def test_hardening_spring_at_f_bar_1(self, make):
        op = operating_point(make(), u0=1.0)
        x_bar = op.x[0]
        assert isinstance(op, OperatingPoint)
        assert K1 * x_bar + K3 * x_bar**3 == pytest.approx(1.0, abs=1e-14)
        assert x_bar == pytest.approx(spring_equilibrium(1.0), rel=1e-14)
        assert op.x[1] == 0.0 or abs(op.x[1]) < 1e-15
        assert op.residual < 1e-14
        np.testing.assert_array_equal(op.u, [1.0])
        np.testing.assert_array_equal(op.y, op.x)
        assert op.states == ("x", "v") and op.inputs == ("f",) and op.t == 0.0
        assert op.as_dict()["x"]["x"] == x_bar
        with pytest.raises((ValueError, AttributeError)):
            op.x[0] = 1.0  # read-only

    def test_tangent_stiffness(self):
        lin = linearize(spring_from_expressions(), u0=1.0)
        x_bar = lin.operating_point.x[0]
        k_tangent = K1 + 3 * K3 * x_bar**2  # f_K'(x̄)
        np.testing.assert_allclose(lin.A, [[0.0, 1.0], [-k_tangent / M, -B_DAMP / M]], rtol=0, atol=1e-14)
        np.testing.assert_allclose(lin.B, [[0.0], [1.0 / M]], rtol=0, atol=1e-15)

    def test_pendulum_equilibrium_depends_on_the_guess(self):
        sys = pendulum_from_expressions()
        assert operating_point(sys, u0=0.0).x == pytest.approx([0.0, 0.0], abs=1e-15)
        op = operating_point(sys, u0=0.0, x_guess={"theta": 3.0})
        assert op.x[0] == pytest.approx(math.pi, abs=1e-14)
        # the inverted pendulum is unstable: A[1,0] = +g/L
        assert linearize(sys, x_guess={"theta": 3.0}).A[1, 0] == pytest.approx(G / L, abs=1e-12)

    def test_fixed_state_and_free_input(self):
        # The lab's question backwards: which force holds the mass at x̄ = 0.5?
        op = operating_point(spring_numpy(), u0=0.0, fixed={"x": 0.5}, free_inputs=["f"])
        assert op.u[0] == pytest.approx(K1 * 0.5 + K3 * 0.125, abs=1e-13)
        assert op.x[0] == 0.5 and op.residual < 1e-13

    def test_fixed_state_that_cannot_be_an_equilibrium(self):
        with pytest.raises(NoEquilibriumError, match=r"holding x = 0.5"):
            operating_point(spring_numpy(), u0=1.0, fixed={"x": 0.5})

    def test_no_equilibrium(self):
        sys = NonlinearSystem(lambda t, x, u: np.array([1.0 + x[0] ** 2 + u[0]]), states=["x"], inputs=["u"])
        with pytest.raises(NoEquilibriumError) as info:
            operating_point(sys, u0=0.0)
        err = info.value
        assert isinstance(err, InputError) and isinstance(err, ValueError)
        text = str(err)
        assert "no equilibrium found for u0 = [u = 0]" in text
        assert "leaves max |f(x̄, ū)| = 1 " in text  # best residual, at x = 0
        assert "`x_guess`" in text
        # ... while u = -2 has equilibria x = ±1
        assert abs(operating_point(sys, u0=-2.0, x_guess=[0.5]).x[0]) == pytest.approx(1.0, abs=1e-14)

    def test_bad_arguments(self):
        sys = spring_numpy()
        with pytest.raises(InputError, match="`fixed` names 'w'"):
            operating_point(sys, u0=0.0, fixed={"w": 1.0})
        with pytest.raises(InputError, match="`free_inputs` names 'g'"):
            operating_point(sys, u0=0.0, free_inputs=["g"])
        with pytest.raises(InputError, match="equilibrium is not unique"):
            operating_point(sys, u0=0.0, free_inputs=["f"])
        with pytest.raises(InputError, match=r"`u0` has 2 values but the system has 1 input \(f\)"):
            operating_point(sys, u0=[1.0, 2.0])
        with pytest.raises(InputError, match="`tol` must be a positive"):
            operating_point(sys, u0=0.0, tol=0)

    def test_statespace_operating_point(self):
        from odelab.systems.statespace import StateSpace

        ss = StateSpace([[0, 1], [-3, -4]], [0, 1], [10, 0], 0, states=["x", "v"], inputs=["f"], outputs=["y"])
        lin = linearize(ss, u0=1.5)
        assert lin == ss  # same matrices and names
        np.testing.assert_allclose(lin.operating_point.x, [0.5, 0.0], atol=1e-15)
        np.testing.assert_allclose(lin.operating_point.y, [5.0], atol=1e-14)


class TestLinearize:
    def test_not_an_equilibrium_warns(self):
        sys = spring_numpy()
        with pytest.warns(NotAnEquilibriumWarning, match=r"max \|f\(x0, u0\)\| = 0.198") as record:
            lin = linearize(sys, x0=[0.1, 0.0], u0=[0.5])
        # f = 0.5 - 0.3 - 0.002 = 0.198 in dv/dt
        assert "dv/dt = 0.198" in str(record[0].message)
        assert lin.operating_point.residual == pytest.approx(0.198, abs=1e-15)
        assert lin.A[1, 0] == pytest.approx(-(K1 + 3 * K3 * 0.01), abs=1e-14)

    def test_a_true_equilibrium_does_not_warn(self):
        x_bar = spring_equilibrium(1.0)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            lin = linearize(spring_from_expressions(), x0=[x_bar, 0.0], u0=1.0)
        assert lin.operating_point.residual < 1e-14

    def test_check_false_skips_the_warning(self):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            linearize(spring_numpy(), x0=[0.1, 0.0], u0=[0.5], check=False)

    def test_x0_and_a_search_are_exclusive(self):
        with pytest.raises(InputError, match="either `x0`"):
            linearize(spring_numpy(), x0=[0.0, 0.0], x_guess=[1.0, 0.0])


# ---------------------------------------------------------------------------------------
# How good is the linear model?
# ---------------------------------------------------------------------------------------


def step(f_bar, a, time=0.5):
    from odelab.signals import Step

    return Step(time=time, initial=f_bar, final=f_bar + a)


def spring_with_output():
    return NonlinearSystem.from_expressions(
        {"x": "v", "v": "(f - b*v - k1*x - k3*x^3) / m"},
        inputs=["f"],
        outputs={"y": "10*x"},
        parameters=SPRING_PARAMS,
    )


class TestCompareLinearization:
    def test_linear_plant_agrees_to_solver_tolerance(self):
        plant = NonlinearSystem.from_expressions(
            {"x": "v", "v": "(f - b*v - k*x) / m"}, inputs=["f"], outputs={"y": "10*x"},
            parameters={"m": 1.0, "b": 4.0, "k": 3.0},
        )
        lin = linearize(plant, u0=1.0)
        cmp = compare_linearization(plant, lin, step(1.0, 2.0), [1 / 3, 0.0], [0.0, 8.0], **TIGHT)
        assert isinstance(cmp, LinearizationComparison) and cmp.success
        assert cmp.max_abs_error["y"] < 1e-8
        assert cmp.error("y").peak_deviation == pytest.approx(10 * 2.0 / 3.0, rel=1e-3)

    def test_arrays_and_error_definitions(self):
        sys = spring_with_output()
        lin = linearize(sys, u0=1.0)
        op = lin.operating_point
        x_init = [op.x[0] + 0.05, 0.0]
        cmp = compare_linearization(sys, lin, step(1.0, 0.8), x_init, [0.0, 6.0], **TIGHT)
        n = cmp.t.size
        assert n > 10
        assert cmp.x_nonlinear.shape == cmp.x_linear.shape == (n, 2)
        assert cmp.y_nonlinear.shape == cmp.y_linear.shape == (n, 1)
        np.testing.assert_allclose(cmp.x_linear[0], x_init, atol=1e-15)  # x̂(0) = x(0) - x̄, x̄ added back
        np.testing.assert_allclose(cmp.x_nonlinear[0], x_init, atol=1e-15)
        # the linear run is in incremental variables, on the same times
        np.testing.assert_array_equal(cmp.linear.t, cmp.t)
        np.testing.assert_allclose(cmp.linear.x + op.x, cmp.x_linear, atol=1e-15)
        x_err = cmp.state_errors["x"]
        assert x_err.max_abs_error == pytest.approx(np.max(np.abs(cmp.x_nonlinear[:, 0] - cmp.x_linear[:, 0])), rel=1e-15)
        assert x_err.peak_deviation == pytest.approx(np.max(np.abs(cmp.x_nonlinear[:, 0] - op.x[0])), rel=1e-15)
        assert x_err.max_rel_error == pytest.approx(x_err.max_abs_error / x_err.peak_deviation, rel=1e-15)
        # y = 10 x: same relative error, ten times the absolute one
        assert cmp.error("y").max_rel_error == pytest.approx(x_err.max_rel_error, rel=1e-9)
        assert cmp.error("y").max_abs_error == pytest.approx(10 * x_err.max_abs_error, rel=1e-9)
        assert 1e-4 < x_err.max_rel_error < 0.2
        with pytest.raises(InputError, match="neither an output"):
            cmp.error("z")

    def test_given_output_times_are_kept(self):
        sys = spring_with_output()
        lin = linearize(sys, u0=1.0)
        times = np.linspace(0.0, 8.0, 81)  # 0.5, the step time, is one of them
        cmp = compare_linearization(sys, lin, step(1.0, 0.3), lin.operating_point.x, times, **TIGHT)
        np.testing.assert_array_equal(cmp.t, times)
        assert cmp.u[5, 0] == 1.3 and cmp.u[4, 0] == 1.0  # right-continuous step at t = 0.5

    def test_a_blow_up_is_a_failed_comparison_not_an_exception(self):
        # x' = x^2 + u about ū = -1, x̄ = -1 (stable, A = -2); u = +1 sends x to infinity.
        sys = NonlinearSystem.from_expressions({"x": "x^2 + u"}, inputs=["u"])
        lin = linearize(sys, u0=-1.0, x_guess=[-2.0])
        assert lin.operating_point.x[0] == -1.0 and lin.A[0, 0] == -2.0
        cmp = compare_linearization(sys, lin, step(-1.0, 2.0), [-1.0], [0.0, 10.0])
        assert cmp.status == "failed" and not cmp.success
        assert cmp.message.startswith("the nonlinear run failed: ")
        assert "The errors cover t <= 2.8" in cmp.message
        assert cmp.t[-1] < 3.0 and np.isfinite(cmp.max_rel_error["x"])
        study = amplitude_study(sys, lin, lambda a: step(-1.0, a), [0.1, 2.0], [-1.0], [0.0, 10.0], threshold=10.0)
        assert [c.success for c in study.comparisons] == [True, False]
        assert study.max_amplitude_within == 0.1  # the failed run counts as exceeding

    def test_needs_an_operating_point(self):
        from odelab.systems.statespace import StateSpace

        with pytest.raises(InputError, match="no operating point"):
            compare_linearization(spring_numpy(), StateSpace([[0, 1], [-3, -4]], [0, 1]), step(0, 1), [0, 0], [0, 1])


def fitted_slope(amplitudes, errors):
    return np.polyfit(np.log(amplitudes), np.log(errors), 1)[0]


class TestAmplitudeStudy:
    AMPLITUDES = [0.05, 0.1, 0.2, 0.4]

    def study(self, f_bar, **kwargs):
        sys = spring_with_output()
        lin = linearize(sys, u0=f_bar)
        x_init = lin.operating_point.x
        return amplitude_study(
            sys, lin, lambda a: step(f_bar, a), self.AMPLITUDES, x_init, [0.0, 8.0], **TIGHT, **kwargs
        )

    def test_error_shrinks_like_amplitude_squared_about_zero(self):
        # f_K is odd about x̄ = 0: the first neglected term is k3 x^3, the relative error ~ a^2.
        study = self.study(0.0)
        assert isinstance(study, AmplitudeStudy) and study.quantity == "y"
        slope = fitted_slope(study.amplitudes, study.relative_error)
        assert abs(slope - 2.0) < 0.2, slope
        assert study.slope() == pytest.approx(slope, rel=1e-12)

    def test_error_shrinks_like_amplitude_about_f_bar_1(self):
        # About x̄ != 0 the quadratic term 3 k3 x̄ x̂^2 remains: the relative error ~ a.
        study = self.study(1.0)
        slope = fitted_slope(study.amplitudes, study.relative_error)
        assert abs(slope - 1.0) < 0.2, slope
        assert abs(study.slope("v") - 1.0) < 0.2

    def test_max_amplitude_within(self):
        study = self.study(1.0, threshold=0.05)
        err = study.relative_error
        assert np.all(np.diff(err) > 0)
        within = [a for a, e in zip(study.amplitudes, err) if e <= 0.05]
        assert within, err
        assert study.max_amplitude_within == max(within)
        k = int(np.searchsorted(study.amplitudes, study.max_amplitude_within))
        if k + 1 < len(study.amplitudes):
            assert study.max_amplitude_within < study.threshold_amplitude < study.amplitudes[k + 1]
        assert len(study.comparisons) == 4
        np.testing.assert_array_equal(study.max_rel_error["y"], err)
        assert study.max_rel_error["x"] == pytest.approx(err, rel=1e-9)

    def test_threshold_amplitude_is_where_the_error_reaches_the_threshold(self):
        study = self.study(1.0, threshold=0.05)
        a = study.threshold_amplitude
        sys = spring_with_output()
        lin = linearize(sys, u0=1.0)
        cmp = compare_linearization(sys, lin, step(1.0, a), lin.operating_point.x, [0.0, 8.0], **TIGHT)
        assert cmp.error("y").max_rel_error == pytest.approx(0.05, rel=0.01)

    def test_nothing_within_a_tiny_threshold(self):
        study = self.study(1.0, threshold=1e-9, quantity="v")
        assert study.quantity == "v"
        assert study.max_amplitude_within is None and study.threshold_amplitude is None

    def test_bad_arguments(self):
        sys = spring_with_output()
        lin = linearize(sys, u0=0.0)
        with pytest.raises(InputError, match="`amplitudes` must be positive"):
            amplitude_study(sys, lin, lambda a: step(0.0, a), [0.0, 0.1], [0, 0], [0, 1])
        with pytest.raises(InputError, match="`quantity`"):
            amplitude_study(sys, lin, lambda a: step(0.0, a), [0.1], [0, 0], [0, 1], quantity="w")
        with pytest.raises(InputError, match="`threshold` must be positive"):
            amplitude_study(sys, lin, lambda a: step(0.0, a), [0.1], [0, 0], [0, 1], threshold=-1)
