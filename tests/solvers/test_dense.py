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


# --- [y, yp] = deval(sol, t): the slope of the interpolant (MATLAB's deval, second output) -----

SLOPE_METHODS = ["ode23", "ode45", "ode78", "ode89", "ode113", "ode23t", "ode23tb"]  # those with dense output


def _rigid_slope(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def _step_bounds(sol):
    d = sol.interpolant
    if hasattr(d, "t_ref"):  # ode113's AdamsDenseOutput (steps end at t_end)
        return np.asarray(d.t), np.asarray(d.t_end)
    return np.asarray(d.t), np.asarray(d.t) + np.asarray(d.h)


@pytest.mark.parametrize("method", SLOPE_METHODS)
def test_deval_returns_the_slope_of_the_interpolant(method):
    import odelab

    sol = odelab.solve(_rigid_slope, [0, 12], [0, 1, 1], method=method, rtol=1e-6, atol=1e-9)
    starts, ends = _step_bounds(sol)
    mids = (starts + ends) / 2
    y, yp = odelab.deval(sol, mids, derivative=True)
    assert y.shape == yp.shape == (mids.size, 3)
    np.testing.assert_array_equal(y, odelab.deval(sol, mids))  # the states are deval's own
    scale = np.abs(yp).max()
    # the interpolant's derivative, against its central difference inside each step (second
    # order in delta: delta^2 |y'''| plus eps |y| / delta of round-off)
    delta = 1e-5 * (ends - starts)
    plus, minus = odelab.deval(sol, mids + delta), odelab.deval(sol, mids - delta)
    fd = (plus - minus) / (2 * delta[:, None])
    roundoff = 16 * np.finfo(float).eps * np.abs(y).max() / delta[:, None]  # tiny first steps
    assert (np.abs(yp - fd) <= 1e-6 * scale + roundoff).all()
    # and an approximation of f(t, y(t)) on the interpolant, to about the tolerance's size
    f = np.array([_rigid_slope(t, row) for t, row in zip(mids, y)])
    assert np.abs(yp - f).max() <= 1e-3 * scale
    # a scalar time gives one row of each
    y1, yp1 = odelab.deval(sol, float(mids[3]), derivative=True)
    np.testing.assert_array_equal(yp1, yp[3])


@pytest.mark.parametrize("method", ["ode23", "ode45", "ode78", "ode89"])
def test_deval_slope_at_the_start_of_each_step_is_f_there(method):
    # a Runge-Kutta extension starts with slope K_0 = f(t_n, y_n) (ntrp23/ntrp45, Verner's):
    # equal to f up to round-off of the stages' size
    import odelab

    from odelab.solvers.dense import basis_slopes

    sol = odelab.solve(_rigid_slope, [0, 12], [0, 1, 1], method=method, rtol=1e-6, atol=1e-9)
    d = sol.interpolant
    starts, _ = _step_bounds(sol)
    y, yp = odelab.deval(sol, starts, derivative=True)
    f = np.array([_rigid_slope(t, row) for t, row in zip(starts, y)])
    # round-off of the slope's terms at s = 0: |D'_j(0)| |K_j| summed (Verner's Chebyshev
    # coefficients reach 32, their derivatives at -1 k^2 times that)
    weights = np.abs(d.coefficients) @ np.abs(basis_slopes(0.0, d.coefficients.shape[1], d.basis))[:, 0]
    terms = np.einsum("j,kjn->kn", weights, np.abs(d.K))
    assert (np.abs(yp - f) <= 16 * np.finfo(float).eps * (terms + np.abs(f))).all()


@pytest.mark.parametrize("method, options", [("ode45", {}), ("ode78", {}), ("ode45", {"NonNegative": [1]})])
def test_deval_block_by_block_is_deval_at_once_to_the_bit(monkeypatch, method, options):
    # a long query is evaluated DEVAL_BLOCK times at a time (bounded temporaries); each time from its own step
    from odelab.solvers import dense

    sol = odelab.solve(rigid, [0, 12], [0, 1, 1], method=method, **RIGID, **options)
    times = np.concatenate([np.linspace(0, 12, 997), sol.t[::3], [12.0]])
    whole = sol.deval(times, derivative=True)
    monkeypatch.setattr(dense, "DEVAL_BLOCK", 64)
    blocks = sol.deval(times, derivative=True)
    for a, b in zip(whole, blocks):
        assert a.shape == b.shape == (times.size, 3)
        assert a.tobytes() == b.tobytes()
    assert sol.deval(times[:5]).tobytes() == whole[0][:5].tobytes() and sol(3.0).shape == (3,)
