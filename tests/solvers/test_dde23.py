"""dde23 (MATLAB's DDE solver, Shampine & Thompson 2001) against exact and independent references.

The exact test: y' = -y(t - 1), y = 1 for t <= 0. By the method of steps, on [k, k+1] the
solution is y(k) - integral_k^t y(s - 1) ds, a polynomial of degree k + 1 (1 - t on [0, 1]);
computed here in exact rational arithmetic.
"""

from __future__ import annotations

import math
import warnings
from fractions import Fraction

import numpy as np
import pytest

import odelab
from odelab.exceptions import InputError, SolverWarning
from odelab.solvers.dde23 import discontinuities

EPS = np.finfo(float).eps


def exact_pieces(k_max: int) -> list[list[Fraction]]:
    """Coefficients of y on [k, k+1] in powers of (t - k), k = 0 .. k_max - 1."""
    pieces = [[Fraction(1), Fraction(-1)]]  # 1 - t on [0, 1]
    for _ in range(1, k_max):
        prev = pieces[-1]  # y(t - 1) on [k, k+1] is prev at s = t - k
        start = sum(prev)  # y(k): prev at s = 1
        pieces.append([start] + [-c / (i + 1) for i, c in enumerate(prev)])
    return pieces


PIECES = exact_pieces(5)


def exact(t) -> np.ndarray:
    t = np.atleast_1d(np.asarray(t, dtype=float))
    out = np.empty_like(t)
    for i, ti in enumerate(t):
        k = min(int(math.floor(ti)), len(PIECES) - 1)
        s = Fraction(ti) - k
        out[i] = float(sum(c * s**j for j, c in enumerate(PIECES[k])))
    return out


def negative_feedback(t, y, Z):
    return -Z[:, 0]


def test_exact_pieces_are_the_known_values():
    # y(1) = 0, y(2) = -1/2, y(3) = -1/6, y(4) = 5/24, y(5) = 19/120 (continuity and the integrals)
    ends = [sum(p) for p in PIECES]
    assert ends == [0, Fraction(-1, 2), Fraction(-1, 6), Fraction(5, 24), Fraction(19, 120)]


@pytest.mark.parametrize("rtol", [1e-3, 1e-5, 1e-7, 1e-9])
def test_exact_solution_in_units_of_the_tolerance(rtol):
    sol = odelab.dde23(negative_feedback, [1.0], [1.0], [0, 5], {"RelTol": rtol, "AbsTol": 1e-3 * rtol})
    assert sol.success and sol.method == "dde23"
    # the points of low smoothness t = 1, 2, 3 are mesh points, exactly
    for point in (1.0, 2.0, 3.0):
        assert point in sol.t.tolist()
    assert sol.t[0] == 0.0 and sol.t[-1] == 5.0
    # at the mesh and between (the Hermite interpolant)
    err_mesh = np.max(np.abs(sol.y[:, 0] - exact(sol.t)))
    tt = np.linspace(0, 5, 501)
    err_dense = np.max(np.abs(sol.deval(tt)[:, 0] - exact(tt)))
    # measured 0.05-0.17 RelTol (|y| <= 1): the global error is a fraction of the tolerance
    assert err_mesh <= 0.5 * rtol
    assert err_dense <= 0.5 * rtol


def test_exact_to_round_off_while_the_solution_is_a_cubic():
    # On [0, 3] the solution is piecewise of degree <= 3 and the delayed values are polynomials of
    # degree <= 2 that the Hermite cubics reproduce: the third-order pair is exact there, at any
    # tolerance, up to round-off (eps times the solution's scale, 1, times the ~20 steps).
    sol = odelab.dde23(negative_feedback, [1.0], [1.0], [0, 3])
    tt = np.linspace(0, 3, 301)
    assert np.max(np.abs(sol.y[:, 0] - exact(sol.t))) <= 100 * EPS
    assert np.max(np.abs(sol.deval(tt)[:, 0] - exact(tt))) <= 100 * EPS
    # and the slopes at the mesh are -y(t - 1), the equation's
    yp_exact = -np.where(sol.t <= 1, 1.0, exact(np.maximum(sol.t - 1, 0)))
    assert np.max(np.abs(sol.yp[:, 0] - yp_exact)) <= 100 * EPS


def test_error_falls_with_the_tolerance():
    errors = []
    for rtol in (1e-4, 1e-6, 1e-8):
        sol = odelab.dde23(negative_feedback, [1.0], [1.0], [0, 5], RelTol=rtol, AbsTol=1e-3 * rtol)
        errors.append(np.max(np.abs(sol.y[:, 0] - exact(sol.t))))
    # a third-order method: 100x tighter tolerance, about 100x smaller error (at least 30x)
    assert errors[0] / errors[1] > 30 and errors[1] / errors[2] > 30


def test_discontinuity_points():
    assert discontinuities(0.0, 5.0, [1.0]).tolist() == [1.0, 2.0, 3.0, 5.0]
    # ddex1's lags: sums of up to three of {1, 0.2} up to tf, merged to 10 eps
    points = discontinuities(0.0, 5.0, [1.0, 0.2])
    expected = sorted({round(a + b + c, 12) for a in (0, 0.2, 1) for b in (0, 0.2, 1) for c in (0, 0.2, 1)} - {0.0})
    assert np.allclose(points[:-1], expected, rtol=0, atol=1e-14) and points[-1] == 5.0
    # InitialY: the solution itself jumps at t0, one more level
    assert discontinuities(0.0, 5.0, [1.0], levels=4).tolist() == [1.0, 2.0, 3.0, 4.0, 5.0]


def ddex1(t, y, Z):
    ylag1, ylag2 = Z[:, 0], Z[:, 1]
    return [ylag1[0], ylag1[0] + ylag2[1], y[1]]


def method_of_steps_ddex1(tf=5.0):
    """ddex1 by the method of steps with SciPy's DOP853 at rtol 1e-12 (no code of ours): on each
    interval of length 0.2 both lags point into intervals already solved."""
    from scipy.integrate import solve_ivp

    width = 0.2
    segments = []

    def past(tq):
        if tq <= 0:
            return np.ones(3)
        k = min(int(tq / width + 1e-9), len(segments) - 1)
        return segments[k].sol(tq)

    y = np.ones(3)
    for k in range(int(round(tf / width))):
        a, b = k * width, (k + 1) * width
        seg = solve_ivp(lambda t, y: [past(t - 1)[0], past(t - 1)[0] + past(t - 0.2)[1], y[1]], [a, b], y,
                        method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
        segments.append(seg)
        y = seg.y[:, -1]
    return past


@pytest.fixture(scope="module")
def ddex1_reference():
    past = method_of_steps_ddex1()
    tt = np.linspace(0, 5, 51)
    return tt, np.array([past(t) for t in tt])


@pytest.mark.parametrize("rtol", [1e-3, 1e-5, 1e-7])
def test_ddex1_against_an_independent_method_of_steps(rtol, ddex1_reference):
    tt, ref = ddex1_reference
    sol = odelab.dde23(ddex1, [1, 0.2], np.ones(3), [0, 5], RelTol=rtol, AbsTol=1e-3 * rtol)
    assert sol.success
    rel = np.max(np.abs(sol.deval(tt) - ref) / np.abs(ref))
    # measured 0.06-0.19 RelTol
    assert rel <= 0.5 * rtol
    # the steps are longer than the 0.2 lag (the short-lag iteration) at the loose tolerance
    if rtol == 1e-3:
        assert np.max(np.diff(sol.t)) > 0.2 and sol.stats.nfevals > 1 + 3 * (sol.stats.nsteps + sol.stats.nfailed)


def test_ddex1_lags_in_any_order(ddex1_reference):
    # Z's columns follow the order of the lags given, as MATLAB's
    tt, ref = ddex1_reference
    sol = odelab.dde23(lambda t, y, Z: ddex1(t, y, Z[:, ::-1]), [0.2, 1], [1, 1, 1], [0, 5], RelTol=1e-6,
                       AbsTol=1e-9)
    assert np.max(np.abs(sol.deval(tt) - ref) / np.abs(ref)) <= 0.5e-6


def test_lag_much_shorter_than_the_steps():
    # y' = a y(t - tau) with a = -exp(-tau) has the exact solution exp(-t) when the history is exp(-t):
    # no discontinuity anywhere, so the steps grow to ~60 lags and need the iteration on the cubic.
    tau = 0.01
    a = -math.exp(-tau)
    sol = odelab.dde23(lambda t, y, Z: a * Z[:, 0], [tau], lambda t: math.exp(-t), [0, 10])
    assert sol.success and np.max(np.diff(sol.t)) > 20 * tau
    assert np.max(np.abs(sol.y[:, 0] - np.exp(-sol.t))) <= 0.1 * 1e-3  # measured 0.03 RelTol


def test_history_function_and_initial_y():
    # y' = -y(t - 1) with the history 1 - t: y' = -(1 - (t - 1)) = t - 2 on [0, 1], so
    # y = 1 - 2t + t^2/2 there, a quadratic: exact to round-off.
    sol = odelab.dde23(negative_feedback, 1.0, lambda t: [1.0 - t], [0, 1])
    tt = np.linspace(0, 1, 11)
    assert np.max(np.abs(sol.deval(tt)[:, 0] - (1 - 2 * tt + tt**2 / 2))) <= 50 * EPS
    # InitialY: y(0) = 2 with the constant history 1: y = 2 - t on [0, 1]
    sol = odelab.dde23(negative_feedback, 1.0, [1.0], [0, 1], InitialY=[2.0])
    assert np.max(np.abs(sol.deval(tt)[:, 0] - (2 - tt))) <= 50 * EPS


def test_continuing_a_solution():
    first = odelab.dde23(negative_feedback, [1.0], [1.0], [0, 2.5], RelTol=1e-6, AbsTol=1e-9)
    more = odelab.dde23(negative_feedback, [1.0], first, [2.5, 5], RelTol=1e-6, AbsTol=1e-9)
    assert more.t[0] == 0.0 and more.t[-1] == 5.0 and 3.0 in more.t.tolist()
    assert more.stats.nsteps > first.stats.nsteps
    assert np.max(np.abs(more.y[:, 0] - exact(more.t))) <= 0.5e-6
    with pytest.raises(InputError, match="continues from where it ends"):
        odelab.dde23(negative_feedback, [1.0], first, [3, 5])


def test_terminal_event():
    # y = 1 - t on [0, 1]: y = 0.5 at t = 0.5, to the location tolerance
    def half(t, y, Z):
        return [y[0] - 0.5], [1], [-1]

    sol = odelab.dde23(negative_feedback, [1.0], [1.0], [0, 5], Events=half)
    assert sol.success and sol.te.size == 1 and sol.ie.tolist() == [0]
    assert abs(sol.te[0] - 0.5) <= 128 * math.ulp(1.0)
    assert sol.t[-1] == sol.te[0] and abs(sol.y[-1, 0] - 0.5) <= 128 * EPS


def test_events_see_the_delayed_state():
    # an event on Z: y(t - 1) = 0 first when t - 1 = 1, i.e. at t = 2 (non-terminal, both directions)
    def lagged_zero(t, y, Z):
        return [Z[0, 0]], [0], [0]

    sol = odelab.dde23(negative_feedback, [1.0], [1.0], [0, 3], Events=lagged_zero)
    assert sol.te.size >= 1 and abs(sol.te[0] - 2.0) <= 1e-9


def test_deval_and_slopes():
    sol = odelab.dde23(negative_feedback, [1.0], [1.0], [0, 5])
    y, yp = sol.deval([0.25, 1.5], derivative=True)
    assert y.shape == (2, 1) and yp.shape == (2, 1)
    assert abs(yp[0, 0] + 1.0) <= 10 * EPS  # y' = -1 on [0, 1]
    assert sol.deval(5.0).shape == (1,) and sol.deval(5.0)[0] == sol.y[-1, 0]
    with pytest.raises(InputError, match="covers"):
        sol.deval(6.0)


@pytest.mark.parametrize("lags, match", [([0.0], "positive"), ([-1.0], "positive"), ([float("nan")], "positive")])
def test_bad_lags(lags, match):
    with pytest.raises(InputError, match=match):
        odelab.dde23(negative_feedback, lags, [1.0], [0, 5])


def test_bad_input_messages():
    with pytest.raises(InputError, match="tf > t0"):
        odelab.dde23(negative_feedback, [1.0], [1.0], [5, 0])
    with pytest.raises(InputError, match="Did you mean 'RelTol'"):
        odelab.dde23(negative_feedback, [1.0], [1.0], [0, 5], {"RelTo": 1e-4})
    with pytest.raises(InputError, match="returned 2 values"):
        odelab.dde23(lambda t, y, Z: [1.0, 2.0], [1.0], [1.0], [0, 5])
    with pytest.raises(InputError, match="history"):
        odelab.dde23(negative_feedback, [1.0], "one", [0, 5])


def test_a_blow_up_fails_with_partial_results():
    with warnings.catch_warnings():
        warnings.simplefilter("error", SolverWarning)
        with pytest.raises(SolverWarning, match="Unable to meet integration tolerances|NaN or infinite"):
            odelab.dde23(lambda t, y, Z: [y[0] ** 2 + Z[0, 0]], [1.0], [1.0], [0, 5])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SolverWarning)
        sol = odelab.dde23(lambda t, y, Z: [y[0] ** 2 + Z[0, 0]], [1.0], [1.0], [0, 5])
    assert sol.status == "failed" and 0 < sol.t[-1] < 5 and sol.t.size == sol.y.shape[0]


def test_no_lags_is_an_ode():
    sol = odelab.dde23(lambda t, y, Z: -y, [], [1.0], [0, 1], RelTol=1e-8, AbsTol=1e-10)
    assert abs(sol.y[-1, 0] - math.exp(-1)) <= 1e-8
