"""odelab.solvers.lu: the stiff solvers' fixed-order LU for small systems, and its compiled twin."""

import numpy as np
import pytest

from odelab.solvers import lu

EPS = np.finfo(float).eps


def unpack(factors, n):
    rows, pivots = factors
    F = np.array(rows)
    L = np.tril(F, -1) + np.eye(n)
    U = np.triu(F)
    P = np.eye(n)
    for j, p in enumerate(pivots):
        P[[j, p]] = P[[p, j]]
    return L, U, P


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 12])
def test_factors_reconstruct_the_matrix_and_solve_it(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        A = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-3, 3, (n, n))
        b = rng.standard_normal(n)
        factors = lu.factor(A)
        L, U, P = unpack(factors, n)
        # P A = L U to round-off: each entry is a sum of at most n products (Higham, Thm 9.3)
        bound = 2 * n * EPS * (np.abs(L) @ np.abs(U))
        assert np.all(np.abs(P @ A - L @ U) <= bound + 1e-300)
        assert np.all(np.abs(np.tril(L, -1)) <= 1.0)  # partial pivoting: multipliers at most 1
        x = lu.solve(factors, b)
        # backward stable: (A + dA) x = b with |dA| <= 3n eps P^T |L| |U| (Higham, Thm 9.4), plus
        # the rounding of the check's own product A x
        residual = np.abs(A @ x - b)
        assert np.all(residual <= 4 * n * EPS * (P.T @ (np.abs(L) @ (np.abs(U) @ np.abs(x))) + np.abs(A) @ np.abs(x)))


def test_the_pivot_is_the_first_largest_and_the_input_is_untouched():
    A = np.array([[1.0, 2.0], [-3.0, 4.0]])
    before = A.copy()
    rows, pivots = lu.factor(A)
    assert pivots == [1, 1] and rows[0] == [-3.0, 4.0] and rows[1][0] == 1.0 * (1.0 / -3.0)
    assert np.array_equal(A, before)
    _, tie = lu.factor(np.array([[2.0, 1.0], [-2.0, 1.0]]))
    assert tie == [0, 1]  # |2| = |-2|: the first one stays, as idamax


def test_a_singular_matrix_gives_non_finite_values_not_an_exception():
    x = lu.solve(lu.factor(np.array([[1.0, 2.0], [2.0, 4.0]])), np.array([1.0, 1.0]))
    assert not np.all(np.isfinite(x))


def test_complex_systems_solve():
    rng = np.random.default_rng(5)
    A = rng.standard_normal((4, 4)) + 1j * rng.standard_normal((4, 4))
    b = rng.standard_normal(4) + 1j * rng.standard_normal(4)
    x = lu.solve(lu.factor(A), b)
    assert x.dtype == complex
    assert np.max(np.abs(A @ x - b)) <= 64 * EPS * np.max(np.abs(A) @ np.abs(x))
    # a real factorisation solves a complex right-hand side (complex y with a real Jacobian)
    R = A.real
    z = lu.solve(lu.factor(R), b)
    assert np.max(np.abs(R @ z - b)) <= 64 * EPS * np.max(np.abs(R) @ np.abs(z))


def test_the_compiled_loops_are_the_same_arithmetic_bit_for_bit():
    from odelab.solvers.compiled.cache import load_kernels

    kernels = load_kernels()
    rng = np.random.default_rng(11)
    for n in (1, 2, 3, 6, 12):
        for _ in range(10):
            A = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-6, 6, (n, n))
            A[rng.random((n, n)) < 0.2] = 0.0  # zeros take the skipped updates
            b = rng.standard_normal(n)
            rows, pivots = lu.factor(A)
            W, piv = A.copy(), np.empty(n, dtype=np.int32)
            kernels._ordered_lu(W, piv)
            assert np.array_equal(W, np.array(rows)) and list(piv) == pivots
            x = b.copy()
            kernels._ordered_solve(W, piv, x)
            assert np.array_equal(x, lu.solve((rows, pivots), b), equal_nan=True)
