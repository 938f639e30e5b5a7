"""Dense output: deval / sol(t) with ntrp23/ntrp45, and odextend."""

import numpy as np
import pytest

import odelab


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


RIGID = dict(rtol=1e-4, atol=[1e-4, 1e-4, 1e-5])


@pytest.mark.parametrize("method, refine", [("ode23", 1), ("ode45", 4), ("ode45", 7)])
def test_deval_at_the_output_points_is_the_output_to_round_off(method, refine):
    sol = odelab.solve(rigid, [0, 12], [0, 1, 1], method=method, refine=refine, **RIGID)
    diff = np.abs(sol.deval(sol.t) - sol.y).max()
    assert diff <= 8 * np.finfo(float).eps  # |y| <= 1.1: a few roundings of the same formula
    np.testing.assert_array_equal(sol(sol.t[-1]), sol.y[-1])  # the end point exactly
    assert sol(3.0).shape == (3,) and sol([3.0, 4.0]).shape == (2, 3)
    np.testing.assert_array_equal(odelab.deval(sol, [3.0, 4.0]), sol([3.0, 4.0]))


def test_deval_reproduces_a_vector_tspan_solution():
    times = np.linspace(0, 12, 25)
    at_points = odelab.ode45(rigid, times, [0, 1, 1], **RIGID)
    mesh = odelab.ode45(rigid, [0, 12], [0, 1, 1], **RIGID)
    # The same steps either way, so interpolating the mesh solution gives the vector-tspan output.
    assert at_points.stats == mesh.stats
    np.testing.assert_allclose(mesh(times), at_points.y, rtol=0, atol=8 * np.finfo(float).eps)


@pytest.mark.parametrize("method, tol", [("ode23", 1e-5), ("ode45", 1e-6)])
def test_deval_between_the_steps_is_within_tolerance(method, tol):
    sol = odelab.solve(rigid, [0, 12], [0, 1, 1], method=method, rtol=tol, atol=tol * 1e-3)
    ref = odelab.solve(rigid, np.linspace(0, 12, 241), [0, 1, 1], method="DOP853", rtol=1e-12, atol=1e-14)
    err = np.abs(sol(ref.t) - ref.y).max()
    assert err < 20 * tol  # global error of the run, not worse between the steps


def test_deval_backwards_and_outside_the_span():
    sol = odelab.ode45(lambda t, y: -y, [2, 0], 1.0)
    np.testing.assert_allclose(sol([1.5, 0.25])[:, 0], np.exp(-np.array([1.5, 0.25]) + 2), rtol=1e-4)
    with pytest.raises(odelab.InputError, match=r"cannot evaluate the solution at t = 2.5: it covers \[0, 2\] only"):
        sol(2.5)


def test_methods_without_an_interpolant_say_so():
    sol = odelab.solve(lambda t, y: -y, [0, 1], 1.0, method="rk4", h=0.1)
    with pytest.raises(odelab.InputError, match="rk4 does not provide one"):
        sol.deval(0.5)


def test_odextend_continues_the_solution():
    first = odelab.ode45(rigid, [0, 6], [0, 1, 1], **RIGID)
    longer = odelab.odextend(first, None, 12)
    assert longer.t[0] == 0 and longer.t[-1] == 12 and np.all(np.diff(longer.t) > 0)
    np.testing.assert_array_equal(longer.y[: first.t.size], first.y)
    assert longer.stats.nsteps > first.stats.nsteps
    whole = odelab.ode45(rigid, [0, 12], [0, 1, 1], **RIGID)
    np.testing.assert_allclose(longer(np.linspace(0, 12, 50)), whole(np.linspace(0, 12, 50)), atol=2e-3)
    np.testing.assert_array_equal(longer(5.0), first(5.0))  # dense output joined, not recomputed
