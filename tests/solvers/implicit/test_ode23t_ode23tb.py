"""ode23t (trapezoidal rule) and ode23tb (TR-BDF2): the formulas, their error estimates, observed
order, accuracy on stiff problems in units of the tolerance, the DAE, options and statistics."""

import numpy as np
import pytest

import odelab
from odelab.solvers.implicit import ode23t as tr
from odelab.solvers.implicit import ode23tb as tb
from odelab.solvers.implicit.common import Newton, Work

from .test_ode15s_ode23s import ROBERTSON, rober, rober_jac, smooth, vdp

VDP_JAC = lambda t, y: [[0, 1], [-2000 * y[0] * y[1] - 1, 1000 * (1 - y[0] ** 2)]]  # noqa: E731
# van der Pol, mu = 1000, at t = 1000, 2000, 3000: SciPy's Radau at rtol 1e-12, atol 1e-14.
VDP_REF = np.array([[-1.8636462548079e+00, 7.5354308654377e-04],
                    [1.7061677321704e+00, -8.9280970102400e-04],
                    [-1.5106069367440e+00, 1.1783800007311e-03]])
T = np.linspace(0, 10, 21)


@pytest.fixture(scope="module")
def smooth_ref():
    return odelab.solve(smooth, T, [1, 0], method="DOP853", rtol=1e-13, atol=1e-14).y


def test_tr_bdf2_coefficients():
    # gamma = 2 - sqrt 2 makes both stages' diagonal the same: gamma/2 = (1 - gamma)/(2 - gamma).
    assert tb.D == pytest.approx((1 - tb.GAMMA) / (2 - tb.GAMMA), rel=1e-15)
    c = np.array([0.0, tb.GAMMA, 1.0])
    A = np.array([[0, 0, 0], [tb.D, tb.D, 0], [tb.W, tb.W, tb.D]])
    np.testing.assert_allclose(A.sum(axis=1), c, atol=1e-15)
    # b (stiffly accurate: the last row of A) is second order, bhat third order, not fourth.
    np.testing.assert_array_equal(tb.B, A[2])
    for b, order in ((tb.B, 2), (tb.BHAT, 3)):
        assert b.sum() == pytest.approx(1) and b @ c == pytest.approx(1 / 2)
        if order == 3:
            assert b @ c**2 == pytest.approx(1 / 3) and b @ (A @ c) == pytest.approx(1 / 6)
        else:
            assert b @ c**2 != pytest.approx(1 / 3)
    assert tb.BHAT @ c**3 != pytest.approx(1 / 4)


def _nonlinear(t, y):
    return np.array([-y[0] + np.sin(t) * y[1], -2 * y[1] + y[0] ** 2])


def _flow(t0, y0, t1):
    return odelab.solve(_nonlinear, [t0, t1], y0, method="DOP853", rtol=1e-13, atol=1e-15).y[-1]


@pytest.mark.parametrize("method", ["ode23t", "ode23tb"])
def test_error_estimate_is_asymptotically_correct(method):
    # One step from an exact state: |estimate| / |true local error| -> 1 as h -> 0, componentwise,
    # and the true local error shrinks by 8 per halving (third-order local error).
    t0, y0 = 0.3, np.array([1.0, 0.5])
    ratios, errors = [], []
    for h in 0.1 / 2.0 ** np.arange(4):
        work = Work(_nonlinear, 2)
        J = work.jacobian(t0, y0, None, np.full(2, 1e-8))
        if method == "ode23tb":
            lu = work.factor(np.eye(2) - tb.D * h * J)
            ynew, _, _, est, ok = tb.trbdf2_attempt(work, lu, t0, y0, h * _nonlinear(t0, y0), np.zeros(2), h,
                                                    np.ones(2), 1e-10, Newton())
        else:
            history = [(t0 - 2 * h, _flow(t0, y0, t0 - 2 * h)), (t0 - h, _flow(t0, y0, t0 - h)), (t0, y0)]
            ypred = tr.predict(history, t0 + h)
            z = h * _nonlinear(t0, y0)
            lu = work.factor(np.eye(2) - 0.5 * h * J)
            ynew, _, ok = tr.solve_z(work, lu, t0 + h, ypred, 2 * (ypred - y0) - z, 0.5, h, np.ones(2), 1e-10,
                                     Newton())
            est = -tr.local_error(history, t0 + h, ynew)  # the rule's error is -h^3 y'''/12
        assert ok
        true = ynew - _flow(t0, y0, t0 + h)
        ratios.append(np.abs(est / true))
        errors.append(np.abs(true).max())
    ratios = np.array(ratios)
    # ode23t's y''' comes from a cubic over 3h (MATLAB's): its gap to 1 halves with h (0.69 ... 0.14)
    assert np.all(np.abs(ratios[-1] - 1) < (0.06 if method == "ode23tb" else 0.16)), ratios
    assert np.all(np.diff(np.abs(ratios - 1).max(axis=1)) < 0)  # closing in on 1
    np.testing.assert_allclose(np.array(errors[:-1]) / errors[1:], 8, rtol=0.15)


def test_predictor_is_exact_for_quadratics_and_the_estimate_for_cubics():
    q = lambda t: np.array([1 + 2 * t - 3 * t**2])  # noqa: E731
    history = [(-0.5, q(-0.5)), (-0.3, q(-0.3)), (0.0, q(0.0))]
    np.testing.assert_allclose(tr.predict(history, 0.2), q(0.2), rtol=1e-13)
    assert abs(tr.local_error(history, 0.2, q(0.2))[0]) < 1e-14
    # for a cubic the estimate is h^3 y'''/12 exactly (y''' = 24 here), whatever the spacing
    c = lambda t: q(t) + 4 * t**3  # noqa: E731
    history = [(-0.5, c(-0.5)), (-0.3, c(-0.3)), (0.0, c(0.0))]
    assert tr.local_error(history, 0.2, c(0.2))[0] == pytest.approx(24 * 0.2**3 / 12, rel=1e-12)
    # the cubic Hermite midpoint is exact for cubics (z = h y' at both ends)
    h, dc = 0.2, (lambda t: 2 - 6 * t + 12 * t**2)  # noqa: E731
    mid = tr.hermite_midpoint(c(0.0), h * np.array([dc(0.0)]), c(h), h * np.array([dc(h)]))
    np.testing.assert_allclose(mid, c(h / 2), rtol=1e-14)


def test_ringing_is_told_from_a_smooth_solution():
    smooth_history = [(0.0, np.array([1.0])), (0.1, np.array([1.1])), (0.2, np.array([1.15]))]
    assert not tr.rings(smooth_history, np.array([1.17]), 0)
    ringing = [(0.0, np.array([1.0])), (0.1, np.array([1.2])), (0.2, np.array([1.0]))]
    assert tr.rings(ringing, np.array([1.2]), 0) and not tr.rings(ringing, np.array([0.9]), 0)


def observed_order(method):
    """Slope of log(error) against log(h) on constant steps (max_step = initial_step = h)."""
    ref = odelab.solve(smooth, [0, 2], [1, 0], method="DOP853", rtol=1e-13, atol=1e-14).y[-1]
    hs = 0.1 / 2.0 ** np.arange(3)
    errs = []
    for h in hs:
        sol = odelab.solve(smooth, [0, 2], [1, 0], method=method, rtol=0.5, atol=0.5, initial_step=h, max_step=h)
        assert sol.stats.nsteps == round(2 / h) and sol.stats.nfailed == 0
        errs.append(np.abs(sol.y[-1] - ref).max())
    return np.polyfit(np.log(hs), np.log(errs), 1)[0]


@pytest.mark.parametrize("method", ["ode23t", "ode23tb"])
def test_observed_order_two_on_constant_steps(method):
    assert abs(observed_order(method) - 2) < 0.1


@pytest.mark.parametrize("method, units", [("ode23t", (1.7, 4.0, 8.7, 19.0, 41.3)),
                                           ("ode23tb", (1.15, 2.75, 5.9, 13.1, 28.2))])
def test_accuracy_in_units_of_the_tolerance(smooth_ref, method, units):
    # tspan output comes from each method's interpolant, so this checks it too. Controlling the
    # error per step, a second-order method's global error goes as rtol^(2/3) (h ~ rtol^(1/3)),
    # so in units of rtol it grows by 10^(1/3) = 2.15 per decade, as ode23s's does (1.7 ... 36).
    rtols = 10.0 ** -np.arange(3, 8)
    errs = []
    for rtol, most in zip(rtols, units):
        sol = odelab.solve(smooth, T, [1, 0], method=method, rtol=rtol, atol=rtol * 1e-3)
        np.testing.assert_array_equal(sol.t, T)
        errs.append(np.abs(sol.y - smooth_ref).max() / (rtol * np.abs(smooth_ref).max()))
        assert errs[-1] < 1.01 * most
    slope = np.polyfit(np.log(rtols), np.log(np.array(errs) * rtols), 1)[0]
    assert abs(slope - 2 / 3) < 0.05


@pytest.mark.parametrize("method", ["ode23t", "ode23tb"])
def test_refine_points_lie_on_the_solution(smooth_ref, method):
    # Between steps the interpolant adds no more than the steps' own (global) error.
    sol = odelab.solve(smooth, [0, 10], [1, 0], method=method, rtol=1e-6, atol=1e-9, refine=4)
    assert sol.t.size == 4 * sol.stats.nsteps + 1
    ref = odelab.solve(smooth, sol.t, [1, 0], method="DOP853", rtol=1e-13, atol=1e-14).y
    err = np.abs(sol.y - ref).max(axis=1)
    at_steps = err[::4].max()
    assert err.max() < 1.1 * at_steps and at_steps < 20 * 1e-6


@pytest.mark.parametrize("method, most, units", [("ode23t", 800, 8), ("ode23tb", 700, 5)])
def test_van_der_pol_mu_1000_in_units_of_the_tolerance(method, most, units):
    # MATLAB's defaults (rtol 1e-3, atol 1e-6); the error is global, after three relaxation cycles.
    sol = odelab.solve(vdp, [0, 1000, 2000, 3000], [2, 0], method=method, jacobian=VDP_JAC)
    assert sol.success and sol.stats.nsteps < most, sol.stats
    err = np.abs(sol.y[1:, 0] - VDP_REF[:, 0]) / (1e-3 * np.abs(VDP_REF[:, 0]) + 1e-6)
    assert err.max() < units, err


@pytest.mark.parametrize("method, most, units", [("ode23t", 2000, 12), ("ode23tb", 400, 8)])
def test_robertson_in_units_of_the_tolerance(method, most, units):
    rtol, atol = 1e-4, np.array([1e-8, 1e-14, 1e-8])
    tspan = np.array([0, 0.4, 4, 40, 400, 4e3, 4e4, 4e5, 4e6, 4e8, 4e10])
    ref = np.vstack([[1, 0, 0], ROBERTSON])
    sol = odelab.solve(rober, tspan, [1, 0, 0], method=method, rtol=rtol, atol=atol, jacobian=rober_jac)
    assert sol.success and sol.stats.nsteps < most, sol.stats
    assert (np.abs(sol.y - ref) / (rtol * np.abs(ref) + atol)).max() < units
    assert abs(sol.y[-1].sum() - 1) < 1e-8


def test_ode23t_solves_robertson_as_an_index1_dae():
    def dae(t, y):
        return [-0.04 * y[0] + 1e4 * y[1] * y[2], 0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2,
                y[0] + y[1] + y[2] - 1]

    rtol, atol = 1e-4, np.array([1e-8, 1e-14, 1e-8])
    tspan = np.array([0, 0.4, 4, 40, 400, 4e3, 4e4, 4e5, 4e6, 4e8, 4e10])
    sol = odelab.ode23t(dae, tspan, [1, 0, 0], Mass=np.diag([1.0, 1.0, 0.0]), RelTol=rtol, AbsTol=atol)
    assert sol.success and sol.stats.nsteps < 3000, sol.stats  # 1692 as an ODE, 2635 as the DAE
    ref = np.vstack([[1, 0, 0], ROBERTSON])
    assert (np.abs(sol.y - ref) / (rtol * np.abs(ref) + atol)).max() < 12
    np.testing.assert_allclose(sol.y.sum(axis=1), 1, atol=1e-12)  # the algebraic equation holds
    with pytest.raises(ValueError, match=r"`mass` is singular \(a DAE\); ode23tb needs a nonsingular mass matrix"):
        odelab.ode23tb(dae, [0, 1], [1, 0, 0], Mass=np.diag([1.0, 1.0, 0.0]))


def test_a_nonsingular_mass_matrix():
    # M y' = M g(y) takes the very steps of y' = g(y)
    M = np.array([[2.0, 1.0], [0.0, 1.0]])
    for method in ("ode23t", "ode23tb"):
        s = odelab.solve(lambda t, y: M @ np.array([-y[0], -2 * y[1]]), [0, 1], [1, 1], method=method, mass=M,
                         rtol=1e-6, atol=1e-9)
        plain = odelab.solve(lambda t, y: np.array([-y[0], -2 * y[1]]), [0, 1], [1, 1], method=method, rtol=1e-6,
                             atol=1e-9)
        np.testing.assert_array_equal(s.t, plain.t)
        np.testing.assert_allclose(s.y, plain.y, rtol=1e-12)
        np.testing.assert_allclose(s.y[-1], [np.exp(-1), np.exp(-2)], rtol=1e-4)


@pytest.mark.parametrize("method", ["ode23t", "ode23tb"])
def test_options_jacobian_jpattern_vectorized_agree(method):
    plain = odelab.solve(vdp, [0, 50], [2, 0], method=method)
    jac = odelab.solve(vdp, [0, 50], [2, 0], method=method, jacobian=VDP_JAC)
    # the evaluations besides Newton's (one per solve): no column differences with a Jacobian
    assert jac.stats.nfevals - jac.stats.nsolves < plain.stats.nfevals - plain.stats.nsolves
    np.testing.assert_allclose(jac.y[-1], plain.y[-1], rtol=1e-2)

    def vec(t, Y):
        Y = np.asarray(Y)
        return np.array([Y[1], 1000 * (1 - Y[0] ** 2) * Y[1] - Y[0]])

    v = odelab.solve(vec, [0, 50], [2, 0], method=method, Vectorized="on")
    # one call per Jacobian, but MATLAB's numjac counts its n evaluations (the columns) all the same
    assert v.stats.as_dict() == plain.stats.as_dict()
    np.testing.assert_array_equal(v.y, plain.y)

    n = 30

    def chain(t, y):
        d = np.zeros(n)
        d[0] = -2 * y[0] + y[1]
        d[1:-1] = y[:-2] - 2 * y[1:-1] + y[2:]
        d[-1] = y[-2] - 2 * y[-1]
        return 1e4 * d

    pattern = np.eye(n) + np.eye(n, k=1) + np.eye(n, k=-1)
    dense = odelab.solve(chain, [0, 1], np.ones(n), method=method)
    sparse = odelab.solve(chain, [0, 1], np.ones(n), method=method, JPattern=pattern)
    np.testing.assert_allclose(sparse.y, dense.y, rtol=1e-6, atol=1e-9)
    assert sparse.stats.nfevals - dense.stats.nfevals == (3 - n) * dense.stats.npds  # 3 groups, not n columns
    with pytest.raises(ValueError, match=f"`MaxOrder` does not apply to {method}"):
        odelab.solve(vdp, [0, 1], [2, 0], method=method, MaxOrder=2)


def test_statistics_count_what_matlab_counts():
    # ode23t: one evaluation and one solve per Newton iteration; the first evaluation, one for
    # y''(t0), n per finite-difference Jacobian (plus f(t, y) for each refreshed one).
    s = odelab.ode23t(vdp, [0, 3000], [2, 0]).stats
    assert s.nfevals == 1 + 1 + s.nsolves + 2 * s.npds + (s.npds - 1)
    assert s.npds < 80 and s.ndecomps <= s.nsteps + s.nfailed + s.npds and s.nsolves >= s.nsteps
    # ode23tb: as ode23t without the y'' probe, plus one solve per attempt whose stages both
    # converged (the filtered error estimate), so nsteps <= that count <= nsteps + nfailed.
    s = odelab.ode23tb(vdp, [0, 3000], [2, 0]).stats
    estimates = s.nsolves - (s.nfevals - 1 - 2 * s.npds - (s.npds - 1))
    assert s.nsteps <= estimates <= s.nsteps + s.nfailed
    assert s.nsolves >= 3 * s.nsteps and s.npds < 100
    assert "LU decompositions" in s.matlab()


@pytest.mark.parametrize("method", ["ode23t", "ode23tb"])
def test_native_and_registered_without_a_mapping(method):
    m = odelab.METHODS[method]
    assert m.kind == "implicit" and m.order == 2
    sol = odelab.solve(smooth, [0, 1], [1, 0], method=method)
    assert sol.method == method and sol.warnings == ()


@pytest.mark.parametrize("method", ["ode23t", "ode23tb"])
def test_backwards_in_time(method):
    # y' = -y from t = 1 back to 0 is u' = u forward from 0 to 1: the same steps, mirrored.
    back = odelab.solve(lambda t, y: -y, [1, 0], [np.exp(-1)], method=method, rtol=1e-6, atol=1e-9)
    forward = odelab.solve(lambda t, y: y, [0, 1], [np.exp(-1)], method=method, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(1 - back.t, forward.t, atol=1e-14)
    np.testing.assert_allclose(back.y, forward.y, rtol=1e-9)  # round-off in t differs
    assert back.y[-1, 0] == pytest.approx(1, rel=40e-6)


@pytest.mark.parametrize("method", ["ode23t", "ode23tb"])
def test_deval_is_the_refine_interpolant(method):
    sol = odelab.solve(smooth, [0, 10], [1, 0], method=method, rtol=1e-6, atol=1e-9, refine=4)
    coarse = odelab.solve(smooth, [0, 10], [1, 0], method=method, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(coarse.deval(sol.t), sol.y, rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(coarse(coarse.t), coarse.y)  # exact at the steps
    assert odelab.deval(coarse, 10.0).shape == (2,)
    with pytest.raises(ValueError, match="cannot evaluate the solution at t = 11"):
        coarse.deval(11.0)


def test_quadratic_through_three_points():
    from odelab.solvers.implicit.common import quadratic_through

    q = lambda s: np.array([1 + 2 * s - 3 * s**2])  # noqa: E731
    a1, a2 = quadratic_through(-0.7, q(0), q(-0.7), q(1))
    np.testing.assert_allclose([a1[0], a2[0]], [2, -3], rtol=1e-13)
