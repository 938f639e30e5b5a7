"""ode113: Shampine & Gordon's variable-order Adams-Bashforth-Moulton PECE (odelab.solvers.adams)."""

import math

import numpy as np
import pytest

import odelab
from odelab.solvers.adams import GSTAR, ntrp113
from odelab.solvers.registry import METHODS


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def kepler(t, y):  # the two-body problem, unit mass and gravitational constant
    r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
    return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3])


ECC = 0.5
ORBIT_Y0 = [1 - ECC, 0.0, 0.0, math.sqrt((1 + ECC) / (1 - ECC))]  # period 2 pi, back at y0


def test_registry_row_is_native_with_matlab_defaults():
    m = METHODS["ode113"]
    assert (m.kind, m.order_label, m.refine) == ("multistep", "1-13", 1)
    assert m.defaults == "rtol 1e-3, atol 1e-6, refine 1, max_step 0.1*span"
    sol = odelab.ode113(lambda t, y: -y, [0, 1], 1.0)
    assert sol.method == "ode113" and sol.warnings == () and sol.message == "ode113 reached t = 1."


def test_exercise1_step_counts_fixed_by_the_algorithm():
    # Phase 1 doubles the step and raises the order every step; then the order/step rules.
    sol = odelab.ode113(lambda t, y: np.cos(t), [0, math.pi], 2.0)
    assert repr(sol.stats) == "Stats(nsteps=14, nfailed=0, nfevals=29)"
    assert sol.t.size == 15  # Refine 1: one output point per step
    err = np.abs(sol.y[:, 0] - (np.sin(sol.t) + 2)).max()
    assert err < 1e-3 * 1e-3  # far inside rtol: high order on a smooth problem


def test_tolerance_proportionality_on_exercise1():
    tols = 10.0 ** -np.arange(6, 13)
    tt = np.linspace(0, math.pi, 201)
    errors = []
    for rtol in tols:
        sol = odelab.ode113(lambda t, y: np.cos(t), [0, math.pi], 2.0, rtol=rtol, atol=rtol * 1e-3)
        errors.append(np.abs(sol(tt)[:, 0] - (np.sin(tt) + 2)).max())
    errors = np.array(errors)
    assert np.all(errors <= 3 * tols)  # max relative error (|y| >= 1 here) within 3 units of rtol
    slope = np.polyfit(np.log10(tols), np.log10(errors), 1)[0]
    assert 0.8 <= slope <= 1.2  # error proportional to the tolerance (measured 0.97)


def test_rigid_body_matlab_example_counts_and_accuracy():
    sol = odelab.ode113(rigid, [0, 12], [0, 1, 1], RelTol=1e-4, AbsTol=[1e-4, 1e-4, 1e-5])
    assert repr(sol.stats) == "Stats(nsteps=59, nfailed=0, nfevals=119)"


@pytest.mark.parametrize("rtol, units", [(1e-4, 4), (1e-6, 3), (1e-8, 1), (1e-10, 1)])
def test_rigid_body_error_in_units_of_rtol(rtol, units):
    times = np.linspace(0, 12, 121)
    ref = odelab.solve(rigid, times, [0, 1, 1], method="DOP853", rtol=1e-13, atol=1e-15)
    sol = odelab.ode113(rigid, times, [0, 1, 1], rtol=rtol, atol=rtol * 1e-3)
    # measured 2.5, 1.3, 0.33, 0.37 units (ode45: 3.3, 1.9, 1.9, 1.9)
    assert np.abs(sol.y - ref.y).max() < units * rtol


def test_two_body_orbit_at_rtol_1e_10_fewer_evaluations_than_ode45():
    T = 2 * math.pi
    adams = odelab.ode113(kepler, [0, T], ORBIT_Y0, rtol=1e-10, atol=1e-10)
    rk = odelab.ode45(kepler, [0, T], ORBIT_Y0, rtol=1e-10, atol=1e-10)
    err_adams = np.abs(adams.y[-1] - ORBIT_Y0).max()
    err_rk = np.abs(rk.y[-1] - ORBIT_Y0).max()
    assert err_adams < 20e-10 and err_rk < 60e-10  # measured 10 and 41 units of rtol
    # Two evaluations per step against ode45's six: 375 against 1369 evaluations here.
    assert adams.stats.nfevals < 0.35 * rk.stats.nfevals


@pytest.mark.parametrize("problem, y0, tspan", [
    (kepler, ORBIT_Y0, [0, 4 * math.pi]),
    (rigid, [0, 1, 1], [0, 12]),
    (lambda t, y: y ** 2, [1.0], [0, 2]),  # blows up at t = 1: many failures, then step underflow
])
def test_function_evaluations_are_pece_as_matlab_counts_them(problem, y0, tspan):
    with pytest.warns(odelab.SolverWarning) if tspan == [0, 2] else _nothing():
        sol = odelab.ode113(problem, tspan, y0, rtol=1e-8, atol=1e-10)
    s = sol.stats
    # f at t0, one evaluation per attempt (the prediction), one more per accepted step (the correction)
    assert s.nfevals == 1 + 2 * s.nsteps + s.nfailed
    if sol.success:
        assert s.nfevals / s.nsteps < 2.1


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_gstar_is_shampine_and_gordons_table():
    # |gamma*_i|: the error constants of the Adams-Moulton formulas (1/2, 1/12, 1/24, 19/720, ...)
    exact = [1 / 2, 1 / 12, 1 / 24, 19 / 720, 3 / 160, 863 / 60480, 275 / 24192]
    np.testing.assert_allclose(GSTAR[1:8], exact, rtol=6e-3)


def test_refine_and_deval_follow_the_interpolant():
    sol = odelab.ode113(rigid, [0, 12], [0, 1, 1], rtol=1e-6, atol=1e-9, refine=4)
    plain = odelab.ode113(rigid, [0, 12], [0, 1, 1], rtol=1e-6, atol=1e-9)
    assert sol.stats == plain.stats and sol.t.size == 4 * sol.stats.nsteps + 1
    np.testing.assert_array_equal(sol.t[::4], plain.t)  # the steps' ends are the Refine-1 points
    np.testing.assert_allclose(sol(sol.t), sol.y, rtol=0, atol=8 * np.finfo(float).eps)
    np.testing.assert_array_equal(sol(12.0), sol.y[-1])
    ref = odelab.solve(rigid, np.linspace(0, 12, 241), [0, 1, 1], method="DOP853", rtol=1e-12, atol=1e-14)
    assert np.abs(plain(ref.t) - ref.y).max() < 5e-6  # between the steps as accurate as at them


def test_vector_tspan_outputs_exactly_there_with_the_same_steps():
    times = np.linspace(0, 12, 25)
    at_points = odelab.ode113(rigid, times, [0, 1, 1], rtol=1e-6, atol=1e-9)
    mesh = odelab.ode113(rigid, [0, 12], [0, 1, 1], rtol=1e-6, atol=1e-9)
    np.testing.assert_array_equal(at_points.t, times)
    assert at_points.stats == mesh.stats
    np.testing.assert_allclose(mesh(times), at_points.y, rtol=0, atol=8 * np.finfo(float).eps)


def test_backward_in_time_and_odextend():
    back = odelab.ode113(lambda t, y: -y, [2, 0], math.exp(-2), rtol=1e-8, atol=1e-12)
    assert abs(back.y[-1, 0] - 1) < 5e-8 and abs(back(1.0)[0] - math.exp(-1)) < 5e-9
    first = odelab.ode113(lambda t, y: -y, [0, 1], 1.0, rtol=1e-8, atol=1e-12)
    both = odelab.odextend(first, None, 2.0)
    assert both.t[-1] == 2.0 and both.method == "ode113"
    np.testing.assert_allclose(both([0.5, 1.5])[:, 0], np.exp([-0.5, -1.5]), rtol=2e-8)


def test_ntrp113_reproduces_the_step_end_and_its_slope():
    sol = odelab.ode113(rigid, [0, 1], [0, 1, 1], rtol=1e-8, atol=1e-10)
    d = sol.interpolant
    i = d.t.size - 1
    ki = int(d.order[i])
    phi = d.phi[d.offsets[i]:d.offsets[i] + ki]
    values, slopes = ntrp113([d.t_ref[i]], d.t_ref[i], d.y_ref[i], phi, d.psi[i, :ki - 1], ki)
    np.testing.assert_array_equal(values[0], d.y_ref[i])
    np.testing.assert_allclose(slopes[0], rigid(1.0, d.y_ref[i]), atol=1e-14)  # phi_1 + ... = f(t_end, y_end)


def test_events_terminal_and_repeated():
    G = 9.81
    sol = odelab.ode113(lambda t, y: [y[1], -G], [0, 5], [10, 0], Events=lambda t, y: ([y[0]], [1], [-1]))
    exact = math.sqrt(20 / G)
    assert abs(sol.te[0] - exact) <= 128 * math.ulp(exact)  # the interpolant is exact on a parabola
    assert sol.t[-1] == sol.te[0] and np.array_equal(sol.y[-1], sol.ye[0])
    assert sol.message == f"ode113 stopped at t = {sol.te[0]:.10g}: terminal event 0 occurred."
    osc = odelab.ode113(lambda t, y: [y[1], -y[0]], [0, 20], [0, 1], events=lambda t, y: ([y[0]], [0], [0]),
                        rtol=1e-8, atol=1e-10)
    # the zero at t0 is not an event (MATLAB's odezero ignores the initial point): pi, ..., 6 pi
    np.testing.assert_allclose(osc.te, math.pi * np.arange(1, 7), rtol=0, atol=1e-8)
    assert osc.t[-1] == 20


def test_nonnegative_mass_and_complex():
    clipped = odelab.ode113(lambda t, y: [-1.0], [0, 2], 1.0, NonNegative=[1])
    assert clipped.y.min() == 0.0 and clipped.y[-1, 0] == 0.0
    assert abs(clipped(0.5)[0] - 0.5) < 1e-9
    heavy = odelab.ode113(lambda t, y: [-y[0]], [0, 1], 1.0, mass=[[2.0]], rtol=1e-8, atol=1e-12)
    assert abs(heavy.y[-1, 0] - math.exp(-0.5)) < 1e-8
    rotating = odelab.ode113(lambda t, y: -1j * y, [0, 2 * math.pi], 1 + 0j, rtol=1e-8, atol=1e-10)
    assert abs(rotating.y[-1, 0] - 1) < 3e-6


def test_messages():
    with pytest.raises(odelab.InputError) as info:
        odelab.ode113(lambda t, y: -y, [0, 1], 1.0, jacobian=[[1.0]])
    assert str(info.value).startswith("`jacobian` does not apply to ode113; it accepts: rtol, atol, max_step, "
                                      "initial_step, refine, norm_control, max_steps, events, nonnegative")
    with pytest.warns(odelab.SolverWarning):
        sol = odelab.ode113(lambda t, y: y ** 2, [0, 2], 1.0)
    assert sol.status == "failed" and sol.message.startswith("ode113 failed at t = 1.00")
    assert "the step size fell below" in sol.message and "finite-time blow-up" in sol.message
    with pytest.warns(odelab.SolverWarning):
        capped = odelab.ode113(lambda t, y: -y, [0, 2], 1.0, max_steps=5)
    assert capped.stats.nsteps == 5 and capped.message.startswith("ode113 stopped at t = ")


def test_norm_control_and_output_function():
    ref = odelab.solve(rigid, [0, 12], [0, 1, 1], method="DOP853", rtol=1e-13, atol=1e-15).y[-1]
    sol = odelab.ode113(rigid, [0, 12], [0, 1, 1], rtol=1e-6, atol=1e-9, NormControl="on")
    assert np.linalg.norm(sol.y[-1] - ref) / np.linalg.norm(ref) < 10e-6  # measured 4.4 units of rtol
    calls = []

    def out(t, y, flag):
        calls.append(flag)
        return flag == "" and len(calls) > 5

    stopped = odelab.ode113(rigid, [0, 12], [0, 1, 1], OutputFcn=out)
    assert calls == ["init"] + [""] * 5 + ["done"] and stopped.t.size == 6 and stopped.status == "success"
    assert stopped.message == f"ode113 stopped at t = {stopped.t[-1]:.10g}: the output function asked to stop."
