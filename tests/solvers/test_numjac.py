"""MATLAB's numjac: accuracy on known Jacobians, the increment memory FAC, vectorized and sparse forms."""

import math

import numpy as np
import pytest

from odelab.solvers.numjac import FAC_MAX, FAC_MIN, FAC_START, column_groups, numjac

SQRT_EPS = math.sqrt(np.finfo(float).eps)


def f(t, y):
    return np.array([y[0] ** 2 * y[1], np.sin(y[1]) + y[2] ** 3 * t, np.exp(y[0]) * y[2]])


def jac(t, y):
    return np.array([[2 * y[0] * y[1], y[0] ** 2, 0.0],
                     [0.0, np.cos(y[1]), 3 * y[2] ** 2 * t],
                     [np.exp(y[0]) * y[2], 0.0, np.exp(y[0])]])


def column_errors(J, exact):
    return np.abs(np.asarray(J) - exact).max(axis=0) / np.abs(exact).max(axis=0)


@pytest.mark.parametrize("y", [[0.7, -1.3, 2.1], [0.5, 0.4, -2.0]])
def test_a_known_jacobian_to_the_accuracy_of_a_forward_difference(y):
    # increments sqrt(eps) max(|y|, thresh): truncation and round-off both of order sqrt(eps)
    # relative to the column (a few units, the second derivative over the first)
    y = np.array(y)
    r = numjac(f, 0.5, y, f(0.5, y), 1e-6)
    assert r.nfevals == r.nfcalls == 3
    assert np.all(column_errors(r.dfdy, jac(0.5, y)) < 20 * SQRT_EPS), column_errors(r.dfdy, jac(0.5, y))
    np.testing.assert_array_equal(r.fac, FAC_START)  # nothing to adapt here


def test_a_difference_lost_to_roundoff_is_retried_with_a_larger_increment_and_remembered():
    # f = 1e9 + y: an increment of sqrt(eps) is below f's round-off (eps * 1e9): the difference is 0
    g = lambda t, y: np.array([1e9 + y[0], y[1]])  # noqa: E731
    y = np.array([1.0, 1.0])
    assert g(0, y + [SQRT_EPS, 0])[0] == g(0, y)[0]  # what a fixed increment sees
    r = numjac(g, 0, y, g(0, y), 1e-6)
    assert r.nfevals == 3  # two columns and one retry of the first with sqrt(fac)
    assert abs(r.dfdy[0, 0] - 1) < 1e-2 and r.dfdy[1, 1] == pytest.approx(1, rel=1e-7)
    # the retried difference still has few digits (below eps^0.75 Fscale): fac grows 10x more
    assert r.fac[0] == pytest.approx(10 * math.sqrt(FAC_START)) and r.fac[1] == FAC_START
    again = numjac(g, 0, y, g(0, y), 1e-6, r.fac)
    assert again.nfevals == 2 and abs(again.dfdy[0, 0] - 1) < 1e-3  # no retry: the memory serves
    assert again.fac[0] == pytest.approx(10 * r.fac[0])  # still below eps^0.75 Fscale
    third = numjac(g, 0, y, g(0, y), 1e-6, again.fac)
    assert third.fac[0] == again.fac[0] and abs(third.dfdy[0, 0] - 1) < 1e-4


def test_a_difference_with_truncation_error_shrinks_the_increment_call_by_call():
    # f = exp(1e5 (y - 1)): the relative change 1e5 * del exceeds eps^(1/4) until del ~ 1e-9
    g = lambda t, y: np.exp(1e5 * (y - 1.0))  # noqa: E731
    y = np.array([1.0])
    fac, errors, facs = None, [], []
    for _ in range(4):
        r = numjac(g, 0, y, g(0, y), 1e-6, fac)
        fac = r.fac
        errors.append(abs(r.dfdy[0, 0] / 1e5 - 1))
        facs.append(fac[0])
    assert facs[:3] == pytest.approx([FAC_START / 10, FAC_START / 100, FAC_START / 100])
    assert errors[0] > 10 * errors[2] and errors[2] < 1e-4  # the shrunk increment is more accurate
    assert all(FAC_MIN <= v <= FAC_MAX for v in facs)


def test_increments_point_the_way_f_does():
    # |y| at 0 has slope -1 to the left, +1 to the right: the increment takes the sign of f
    for c, slope in ((-1.0, -1.0), (1.0, 1.0)):
        g = lambda t, y, c=c: np.array([abs(y[0]) + c])  # noqa: E731
        r = numjac(g, 0, np.array([0.0]), g(0, np.array([0.0])), 1e-3)
        assert r.dfdy[0, 0] == pytest.approx(slope, rel=1e-4)  # round-off of f: eps / (fac thresh)


def test_vectorized_and_sparse_forms_agree_with_the_dense_one():
    n = 12

    def chain(t, Y):
        Y = np.asarray(Y, dtype=float)
        d = np.zeros_like(Y)
        d[0] = -2 * Y[0] + Y[1] ** 2
        d[1:-1] = Y[:-2] - 2 * Y[1:-1] ** 3 + Y[2:]
        d[-1] = Y[-2] - 2 * Y[-1]
        return d

    y = np.linspace(0.5, 1.5, n)
    fy = chain(0, y)
    dense = numjac(chain, 0, y, fy, 1e-6)
    vec = numjac(chain, 0, y, fy, 1e-6, vectorized=True)
    assert vec.nfcalls == 1 and vec.nfevals == n  # one call, n evaluations (as MATLAB counts them)
    np.testing.assert_array_equal(vec.dfdy, dense.dfdy)
    pattern = np.eye(n) + np.eye(n, k=1) + np.eye(n, k=-1)
    groups = column_groups(pattern)
    assert len(groups) == 3
    sparse = numjac(chain, 0, y, fy, 1e-6, pattern=pattern, groups=groups)
    assert sparse.nfevals == 3 and hasattr(sparse.dfdy, "toarray")
    np.testing.assert_allclose(sparse.dfdy.toarray(), dense.dfdy, rtol=1e-12, atol=1e-12)
    both = numjac(chain, 0, y, fy, 1e-6, vectorized=True, pattern=pattern)
    assert both.nfcalls == 1 and both.nfevals == 3
    np.testing.assert_allclose(both.dfdy.toarray(), sparse.dfdy.toarray(), rtol=0, atol=0)
