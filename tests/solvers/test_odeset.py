"""The rest of MATLAB's odeset: NonNegative, Mass, OutputFcn, complex y0, args, failure warnings."""

import numpy as np
import pytest

import odelab


def decay(t, y):
    return -np.abs(y)


@pytest.mark.parametrize("method", ["ode23", "ode45"])
def test_nonnegative_keeps_the_solution_nonnegative(method):
    # MATLAB's documented example: y' = -|y|, y(0) = 1 on [0, 40]; exact exp(-t) > 0.
    plain = odelab.solve(decay, [0, 40], 1.0, method=method)
    kept = odelab.solve(decay, [0, 40], 1.0, method=method, NonNegative=[1])
    assert plain.y.min() < -1.0  # plain ode45/ode23 drift far below zero
    assert kept.y.min() == 0.0 and kept(np.linspace(0, 40, 400)).min() >= 0.0
    np.testing.assert_allclose(kept.y[:, 0], np.exp(-kept.t), atol={"ode23": 5e-3, "ode45": 5e-4}[method])
    same = odelab.solve(decay, [0, 40], 1.0, method=method, nonnegative=[0])  # 0-based spelling
    np.testing.assert_array_equal(same.y, kept.y)


def test_nonnegative_bad_indices_and_initial_state():
    with pytest.raises(odelab.InputError, match=r"`NonNegative` holds MATLAB's 1-based state indices; got \[0\]"):
        odelab.ode45(decay, [0, 1], 1.0, NonNegative=[0])
    with pytest.raises(odelab.InputError, match="`nonnegative` index 1 is out of range"):
        odelab.ode45(decay, [0, 1], 1.0, nonnegative=[1])
    with pytest.raises(odelab.InputError, match=r"y0\[0\] = -1"):
        odelab.ode45(decay, [0, 1], -1.0, nonnegative=[0])


M = np.array([[2.0, 1.0], [1.0, 3.0]])


def spring(t, y):
    return np.array([y[1], -4 * y[0] - 0.1 * y[1] + np.sin(t)])


def test_constant_mass_matrix_equals_the_inverse_applied():
    Minv = np.linalg.inv(M)
    with_mass = odelab.ode45(spring, [0, 10], [1, 0], mass=M, rtol=1e-6)
    explicit = odelab.ode45(lambda t, y: Minv @ spring(t, y), [0, 10], [1, 0], rtol=1e-6)
    # Solving with M and multiplying by inv(M) differ by round-off only. The same steps: no
    # attempt of either run has its error ratio err/rtol within 0.5 of the acceptance threshold 1.
    assert with_mass.stats.nsteps == explicit.stats.nsteps and with_mass.stats.nfailed == explicit.stats.nfailed
    # The step sizes differ by round-off amplified by the error estimate's cancellation (about
    # eps/rtol relative), so the output times do; the states, compared at the same times, by
    # round-off of the solution's size (measured: 10 eps times max|y|).
    eps = np.finfo(float).eps
    np.testing.assert_allclose(with_mass.t, explicit.t, rtol=eps / 1e-6, atol=0)
    scale = np.abs(explicit.y).max()
    np.testing.assert_allclose(with_mass.y, explicit(with_mass.t), rtol=0, atol=1000 * eps * scale)
    # MATLAB evaluates f0 again once the mass matrix is folded in
    assert with_mass.stats.nfevals == explicit.stats.nfevals + 1


def test_time_and_state_dependent_mass():
    def Mt(t):
        return np.array([[1.0, 0.0], [0.0, 2.0 + np.sin(t)]])

    def Mty(t, y):
        return np.array([[1.0, 0.0], [0.0, 2.0 + np.sin(t)]]) + 0.0 * y[0]

    ref = odelab.ode23(lambda t, y: np.linalg.solve(Mt(t), spring(t, y)), [0, 5], [1, 0])
    for mass, extra in ((Mt, {}), (Mty, {}), (Mty, {"MStateDependence": "strong"})):
        sol = odelab.ode23(spring, [0, 5], [1, 0], Mass=mass, **extra)
        np.testing.assert_array_equal(sol.t, ref.t)
        np.testing.assert_allclose(sol.y, ref.y, rtol=0, atol=1e-14)


def test_singular_mass_points_to_a_dae_method():
    with pytest.raises(odelab.InputError, match=r"singular\. M y' = f with a singular M is a differential-algebraic"):
        odelab.ode45(spring, [0, 1], [1, 0], mass=[[1, 0], [0, 0]])
    with pytest.raises(odelab.InputError, match="has shape \\(3, 3\\) but the state has 2"):
        odelab.ode45(spring, [0, 1], [1, 0], mass=np.eye(3))


def test_output_fcn_flags_selection_and_stop():
    calls = []

    def watch(t, y, flag):
        calls.append((flag, np.array(t, copy=True), np.array(y, copy=True)))
        return flag == "" and t[-1] > 1.0

    sol = odelab.ode45(spring, [0, 10], [1, 0], OutputFcn=watch, OutputSel=[2])
    flags = [c[0] for c in calls]
    assert flags[0] == "init" and flags[-1] == "done" and set(flags[1:-1]) == {""}
    np.testing.assert_array_equal(calls[0][1], [0, 10])
    np.testing.assert_array_equal(calls[0][2], [0])  # OutputSel=[2] is the 0-based state 1
    assert all(c[2].shape == (4, 1) for c in calls[1:-1])  # Refine 4 points per step, one column
    assert sol.t[-1] > 1.0 and sol.t[-5] <= 1.0  # stopped after the first step past t = 1
    assert sol.status == "success" and "the output function asked to stop" in sol.message
    streamed = np.concatenate([c[1] for c in calls[1:-1]])
    np.testing.assert_array_equal(streamed, sol.t[1:])


def test_complex_y0_matches_the_split_real_system():
    lam = -0.1 + 1j
    z = odelab.ode45(lambda t, y: lam * y, [0, 10], 1 + 0j, rtol=1e-6, atol=1e-9)
    xy = odelab.ode45(lambda t, y: [-0.1 * y[0] - y[1], y[0] - 0.1 * y[1]], [0, 10], [1, 0], rtol=1e-6, atol=1e-9)
    assert z.y.dtype == complex
    split = xy.y[:, 0] + 1j * xy.y[:, 1]
    # The error norm is on |y| for complex states, componentwise for the split system, so the
    # steps differ; both solutions agree within the tolerance.
    assert np.abs(z(xy.t)[:, 0] - split).max() < 1e-6
    assert abs(z.y[-1, 0] - np.exp(lam * 10)) < 1e-6
    with pytest.raises(odelab.InputError, match="a complex `y0` is integrated by ode23/ode45"):
        odelab.solve(lambda t, y: lam * y, [0, 1], 1j, method="rk4", h=0.1)


def test_args_are_passed_to_fun():
    a = odelab.ode45(lambda t, y, k, c: -k * y + c, [0, 2], 1.0, args=(3.0, 0.5))
    b = odelab.ode45(lambda t, y: -3.0 * y + 0.5, [0, 2], 1.0)
    np.testing.assert_array_equal(a.y, b.y)
    r = odelab.solve(lambda t, y, k: -k * y, [0, 1], 1.0, method="RK45", args=(2.0,))
    assert abs(r.y[-1, 0] - np.exp(-2)) < 1e-3
    with pytest.raises(odelab.InputError, match=r"`args` must be a tuple .* e.g. args=\(k,\); got 3"):
        odelab.ode45(lambda t, y, k: -k * y, [0, 1], 1.0, args=3)


def test_failures_warn_with_the_message():
    with pytest.warns(odelab.SolverWarning) as record:
        sol = odelab.ode45(lambda t, y: y**2, [0, 2], 1.0)  # blows up at t = 1
    assert sol.status == "failed" and str(record[0].message) == sol.message
    assert record[0].filename == __file__  # points at the caller's line
    with pytest.warns(odelab.SolverWarning, match="could not start"):
        odelab.solve(lambda t, y: 1 / 0, [0, 1], 1.0)
