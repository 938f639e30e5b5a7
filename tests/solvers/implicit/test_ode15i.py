"""ode15i and decic: MATLAB's examples against closed forms and the Bari test set, in units of the tolerance."""

import math
import warnings

import numpy as np
import pytest

import odelab
from odelab.exceptions import InputError
from odelab.solvers.implicit.decic import DecicError
from odelab.solvers.implicit.ode15i import fornberg_weights


def weissinger(t, y, yp):
    """MATLAB's ode15i example: exact solution y = sqrt(t^2 + 1/2) from y(1) = sqrt(3/2)."""
    return t * y**2 * yp**3 - y**3 * yp**2 + t * (t**2 + 1) * yp - t**2 * y


def weissinger_exact(t):
    return np.sqrt(np.asarray(t) ** 2 + 0.5)


def ihb1dae(t, y, yp):
    """MATLAB's ihb1dae: Robertson's reaction as an implicit DAE (the third equation the conservation law)."""
    return [yp[0] + 0.04 * y[0] - 1e4 * y[1] * y[2],
            yp[1] - 0.04 * y[0] + 1e4 * y[1] * y[2] + 3e7 * y[1] ** 2,
            y[0] + y[1] + y[2] - 1]


def ihb1dae_jacobian(t, y, yp):
    dfdy = np.array([[0.04, -1e4 * y[2], -1e4 * y[1]],
                     [-0.04, 1e4 * y[2] + 6e7 * y[1], 1e4 * y[1]],
                     [1.0, 1.0, 1.0]])
    return dfdy, np.diag([1.0, 1.0, 0.0])


# the Bari test set's reference for ROBER at t = 1e11
ROBER_1E11 = np.array([0.2083340149701255e-7, 0.8333360770334713e-13, 0.9999999791665050])


def test_fornberg_weights_differentiate_polynomials_exactly():
    nodes = [0.0, -0.3, -0.7, -1.2, -1.5]
    z = 0.4
    c = fornberg_weights(nodes, z, 2)
    p = np.polynomial.Polynomial([1.0, -2.0, 0.5, 3.0, -1.0])  # degree 4: 5 nodes interpolate it exactly
    values = p(np.array(nodes))
    for d in range(3):
        got = sum(c[j][d] * values[j] for j in range(len(nodes)))
        assert got == pytest.approx(p.deriv(d)(z), rel=1e-12)


def test_decic_on_matlabs_documented_example():
    # MATLAB's decic page: 0 = 2 y1' - y2, 0 = y1 + y2 with y1 = 1 fixed gives y2 = -1, y1' = -1/2.
    y0, yp0, resnrm = odelab.decic(lambda t, y, yp: [2 * yp[0] - y[1], y[0] + y[1]], 0, [1, 0], [1, 0], [0, 0], [])
    np.testing.assert_allclose(y0, [1, -1], atol=1e-14)
    np.testing.assert_allclose(yp0, [-0.5, 0], atol=1e-14)
    assert resnrm < 1e-14


@pytest.mark.parametrize("rtol", [1e-3, 1e-6, 1e-9])
def test_decic_makes_weissinger_consistent_to_the_tolerance(rtol):
    # y(1) = sqrt(3/2) fixed: the consistent slope is the exact solution's, 1/sqrt(3/2).
    y0, yp0, resnrm = odelab.decic(weissinger, 1, math.sqrt(1.5), [1], 0, [0], {"RelTol": rtol})
    assert y0[0] == math.sqrt(1.5)
    assert abs(yp0[0] - 1 / math.sqrt(1.5)) <= 1e-3 * rtol * 1 / math.sqrt(1.5)
    # the residual left is what a change of y' within the tolerance would make: |F| / |dF/dy'| <= rtol |y'|
    dfdyp = 3 * y0[0] ** 2 * yp0[0] ** 2 - 2 * y0[0] ** 3 * yp0[0] + 2  # at t = 1
    assert abs(weissinger(1.0, y0[0], yp0[0])) / abs(dfdyp) <= 1e-3 * rtol * abs(yp0[0])
    assert resnrm == pytest.approx(abs(weissinger(1.0, y0[0], yp0[0])))


# Measured (max error over the output points in units of RelTol |y| + AbsTol, AbsTol = 1e-3 RelTol):
# 0.68, 7.5, 3.0, 5.6, 8.6, 2.8 at RelTol 1e-3 .. 1e-8, in 27, 39, 56, 75, 110, 162 steps.
@pytest.mark.parametrize("rtol", [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8])
def test_weissinger_within_the_tolerance_of_the_exact_solution(rtol):
    atol = 1e-3 * rtol
    y0, yp0, _ = odelab.decic(weissinger, 1, math.sqrt(1.5), [1], 0, [0], {"RelTol": rtol, "AbsTol": atol})
    sol = odelab.ode15i(weissinger, [1, 10], y0, yp0, RelTol=rtol, AbsTol=atol)
    assert sol.success and sol.t[-1] == 10 and sol.t[0] == 1
    exact = weissinger_exact(sol.t)
    units = np.abs(sol.y[:, 0] - exact) / (rtol * exact + atol)
    assert units.max() < 10, units.max()
    # deval: the BDF polynomials between the steps, as accurate as the steps
    tq = np.linspace(1, 10, 201)
    dense = sol.deval(tq)[:, 0]
    assert (np.abs(dense - weissinger_exact(tq)) / (rtol * weissinger_exact(tq) + atol)).max() < 10
    assert sol.deval(10.0)[0] == sol.y[-1, 0]
    # its slope is a derivative of the interpolating polynomial: one order less (measured over [1.5, 10]:
    # 0.48 to 1.21 times RelTol^(3/4))
    tq = np.linspace(1.5, 10, 101)
    _, yp = sol.deval(tq, derivative=True)
    assert np.abs(yp[:, 0] - tq / weissinger_exact(tq)).max() < 2 * rtol ** 0.75


def test_weissinger_at_matlabs_defaults_counts():
    # MATLAB's example as written: [y0, yp0] = decic(@weissinger, 1, sqrt(3/2), 1, 0, 0);
    # [t, y] = ode15i(@weissinger, [1 10], y0, yp0). (numjac partials, RelTol 1e-3, AbsTol 1e-6)
    y0, yp0, _ = odelab.decic(weissinger, 1, math.sqrt(1.5), [1], 0, [0])
    sol = odelab.ode15i(weissinger, [1, 10], y0, yp0)
    s = sol.stats
    assert (s.nsteps, s.nfailed) == (27, 16) and s.npds == 15 and s.ndecomps == 29 and s.nsolves == 90
    assert len(sol.t) == 28  # Refine 1: the steps
    assert np.abs(sol.y[:, 0] - weissinger_exact(sol.t)).max() < 1e-3 * 10.1


@pytest.mark.parametrize("rtol, units, digits", [(1e-4, 1.0, 3.0), (1e-6, 1.0, 4.9), (1e-8, 1.0, 6.5)])
def test_robertson_as_an_implicit_dae_against_the_bari_reference(rtol, units, digits):
    # MATLAB's ihb1dae with its analytic Jacobian, to t = 1e11 with AbsTol = 1e-6 RelTol. Measured:
    # 0.08, 0.12, 0.35 units of RelTol |y| + AbsTol (3.4, 5.2, 6.8 digits) in 642, 1334, 3343 steps
    # (ode23t on the ODE form: 3.3, 3.8, 5.0 digits in 660, 2820, 12872).
    atol = 1e-6 * rtol
    options = {"RelTol": rtol, "AbsTol": atol, "Jacobian": ihb1dae_jacobian}
    y0, yp0, _ = odelab.decic(ihb1dae, 0, [1, 0, 0], [1, 1, 0], [0, 0, 0], [], options)
    np.testing.assert_allclose(yp0, [-0.04, 0.04, 0.0], atol=1e-15)
    sol = odelab.ode15i(ihb1dae, [0, 1e11], y0, yp0, **options)
    assert sol.success and sol.t[-1] == 1e11
    err = np.abs(sol.y[-1] - ROBER_1E11) / (rtol * ROBER_1E11 + atol)
    assert err.max() < units, err
    assert -np.log10(np.max(np.abs(sol.y[-1] - ROBER_1E11) / ROBER_1E11)) > digits
    assert np.abs(sol.y.sum(axis=1) - 1).max() < 1e-12  # the algebraic equation holds at every step
    assert sol.stats.nfailed < 0.1 * sol.stats.nsteps


def test_matlabs_ihb1dae_demo_runs():
    # The demo's own settings: RelTol 1e-4, AbsTol [1e-6 1e-10 1e-6], y0 guess [1 0 1e-3], output at 4*logspace(-6, 6).
    options = {"RelTol": 1e-4, "AbsTol": [1e-6, 1e-10, 1e-6], "Jacobian": ihb1dae_jacobian}
    y0, yp0, _ = odelab.decic(ihb1dae, 0, [1, 0, 1e-3], [1, 1, 0], [0, 0, 0], [], options)
    assert abs(y0[2]) < 1e-15  # decic frees y3 and puts it on the conservation law
    tspan = np.concatenate([[0], 4 * np.logspace(-6, 6)])
    sol = odelab.ode15i(ihb1dae, tspan, y0, yp0, **options)
    assert sol.success and sol.t.size == tspan.size
    reference = odelab.solve(lambda t, y: [-0.04 * y[0] + 1e4 * y[1] * y[2],
                                           0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2,
                                           3e7 * y[1] ** 2], tspan, [1, 0, 0], method="Radau", rtol=1e-10,
                             atol=[1e-14, 1e-18, 1e-14])
    err = np.abs(sol.y - reference.y) / (1e-4 * np.abs(reference.y) + np.array([1e-6, 1e-10, 1e-6]))
    assert err.max() < 2, err.max()


def test_events_see_y_and_its_slope():
    y0, yp0, _ = odelab.decic(weissinger, 1, math.sqrt(1.5), [1], 0, [0])

    def events(t, y, yp):  # y = 5 (terminal) at t = sqrt(24.5); y' = 0.99 at t = sqrt(0.99^2 0.5 / (1 - 0.99^2))
        return [y[0] - 5, yp[0] - 0.99], [False, True], [0, 1]

    rtol, atol = 1e-6, 1e-9
    sol = odelab.ode15i(weissinger, [1, 10], y0, yp0, RelTol=rtol, AbsTol=atol, Events=events)
    assert list(sol.ie) == [0, 1] and sol.status == "success"
    assert abs(sol.te[0] - math.sqrt(24.5)) * 1.0 < 10 * (rtol * 5 + atol)  # y' ~ 1 there
    t_slope = math.sqrt(0.99**2 * 0.5 / (1 - 0.99**2))
    assert abs(sol.te[1] - t_slope) < 1e-2 * t_slope  # y'' ~ 0.0026 there: a slope error moves it far
    assert sol.t[-1] == sol.te[1] and sol.ye[0][0] == pytest.approx(5.0, abs=1e-12)


def test_refine_and_vector_tspan():
    y0, yp0, _ = odelab.decic(weissinger, 1, math.sqrt(1.5), [1], 0, [0])
    coarse = odelab.ode15i(weissinger, [1, 10], y0, yp0)
    refined = odelab.ode15i(weissinger, [1, 10], y0, yp0, Refine=4)
    assert refined.t.size == 4 * (coarse.t.size - 1) + 1
    assert np.abs(refined.y[:, 0] - weissinger_exact(refined.t)).max() < 1e-2
    at = odelab.ode15i(weissinger, np.linspace(1, 10, 10), y0, yp0)
    np.testing.assert_array_equal(at.t, np.linspace(1, 10, 10))
    assert at.stats.nsteps == coarse.stats.nsteps


def test_an_index_2_system_is_refused_with_the_reason():
    def index2(t, y, yp):  # x' = z, 0 = x - sin t: z = cos t only through the hidden constraint
        return [yp[0] - y[1], y[0] - math.sin(t)]

    with pytest.raises(InputError, match="index 1.*rank 1 of 2.*index 2 or higher"):
        odelab.ode15i(index2, [0, 1], [0, 1], [1, 0])
    with pytest.raises(DecicError, match="index 2 or higher.*index-1 problems"):
        odelab.decic(index2, 0, [0, 1], [1, 1], [0, 0], [])


def test_the_pendulum_in_index_3_form_is_refused():
    def pendulum(t, s, sp):
        x, y, u, v, lam = s
        return [sp[0] - u, sp[1] - v, sp[2] + lam * x, sp[3] + lam * y + 9.81, x * x + y * y - 1]

    with pytest.raises(InputError, match="index 2 or higher"):
        odelab.ode15i(pendulum, [0, 1], [1, 0, 0, 0, 0], [0, 0, 0, -9.81, 0])


def test_decic_says_what_it_cannot_do():
    with pytest.raises(DecicError, match="at most 1 of the 2 components"):
        odelab.decic(weissinger, 1, 1.2, [1], 0, [1])
    with pytest.raises(DecicError, match="did not find consistent initial conditions in 10 iterations"):
        odelab.decic(lambda t, y, yp: [yp[0] ** 2 + 1], 0, [1], [1], [0.5], [])  # no real y' exists
    with pytest.raises(InputError, match="`fixed_y0` must be 1 zeros and ones"):
        odelab.decic(weissinger, 1, 1.2, [2], 0, [0])
    with pytest.raises(InputError, match="`yp0` has 2 entries but `y0` has 1"):
        odelab.decic(weissinger, 1, 1.2, [1], [0, 0], [0])


def test_ode15i_input_errors():
    y0, yp0, _ = odelab.decic(weissinger, 1, math.sqrt(1.5), [1], 0, [0])
    with pytest.raises(InputError, match="`yp0` has 2 entries but `y0` has 1"):
        odelab.ode15i(weissinger, [1, 2], y0, [0, 0])
    with pytest.raises(InputError, match="returned 2 residuals but the state has 1"):
        odelab.ode15i(lambda t, y, yp: [0.0, 0.0], [1, 2], y0, yp0)
    with pytest.raises(InputError, match="ode15i solves fully implicit systems F\\(t, y, y'\\) = 0.*odelab.ode15i"):
        odelab.solve(lambda t, y: -y, [0, 1], [1], method="ode15i")
    with pytest.raises(InputError, match="`NonNegative` is not available for ode15i, as in MATLAB"):
        odelab.ode15i(weissinger, [1, 2], y0, yp0, NonNegative=[0])
    with pytest.raises(InputError, match="`events` of ode15i is one function"):
        odelab.ode15i(weissinger, [1, 2], y0, yp0, Events=[lambda t, y, yp: y[0]])
    with pytest.raises(InputError, match="`jacobian` \\(dF/dy\\) must be an 1-by-1 matrix"):
        odelab.ode15i(weissinger, [1, 2], y0, yp0, Jacobian=(np.eye(2), None))


def test_a_residual_that_raises_or_is_not_finite_fails_honestly():
    y0, yp0, _ = odelab.decic(weissinger, 1, math.sqrt(1.5), [1], 0, [0])

    def late_nan(t, y, yp):
        return weissinger(t, y, yp) + (np.nan if t > 3 else 0.0)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sol = odelab.ode15i(late_nan, [1, 10], y0, yp0)
    assert sol.status == "failed" and 2.5 < sol.t[-1] <= 3.0 + 1e-12


def test_constant_partials_are_not_formed_again():
    # y1' + y1 = 0, y2' + 2 y2 = 0 given as constant {dF/dy, dF/dy'}: one partial derivative in all
    F = lambda t, y, yp: [yp[0] + y[0], yp[1] + 2 * y[1]]  # noqa: E731
    sol = odelab.ode15i(F, [0, 2], [1, 1], [-1, -2], Jacobian=(np.diag([1.0, 2.0]), np.eye(2)), RelTol=1e-6,
                        AbsTol=1e-9)
    assert sol.stats.npds == 1
    np.testing.assert_allclose(sol.y[-1], np.exp([-2.0, -4.0]), rtol=1e-5, atol=1e-8)


def test_a_result_that_cannot_be_right_is_not_silent():
    # MATLAB's ihb1dae demo settings carried to t = 1e11: AbsTol 1e-6 on y1 lets y1 ~ 2e-8 step below zero,
    # and the solution runs off to y1 = -2.4e7 (success by the error test). The stiff solvers' check says so.
    options = {"RelTol": 1e-4, "AbsTol": [1e-6, 1e-10, 1e-6], "Jacobian": ihb1dae_jacobian}
    y0, yp0, _ = odelab.decic(ihb1dae, 0, [1, 0, 1e-3], [1, 1, 0], [0, 0, 0], [], options)
    with pytest.warns(odelab.SolverWarning, match="this result cannot be right: y3 reached"):
        sol = odelab.ode15i(ihb1dae, [0, 1e11], y0, yp0, **options)
    assert any(w.startswith("this result cannot be right") for w in sol.warnings)
