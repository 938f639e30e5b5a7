"""Exact Jacobians of expression systems: complex step on the equations, and the file's own."""

import numpy as np

from odelab.systems.jacobian import complex_step_jacobian, expression_jacobian


def test_complex_step_is_exact_to_rounding():
    J = complex_step_jacobian(["-0.04*a + 1e4*b*c", "0.04*a - 1e4*b*c - 3e7*b^2", "3e7*b^2"], ["a", "b", "c"], {})
    y = np.array([0.7, 3e-5, 0.3])
    exact = [[-0.04, 1e4 * y[2], 1e4 * y[1]], [0.04, -1e4 * y[2] - 6e7 * y[1], -1e4 * y[1]], [0, 6e7 * y[1], 0]]
    np.testing.assert_allclose(J(0.0, y), exact, rtol=1e-15, atol=0)


def test_functions_time_and_parameters():
    J = complex_step_jacobian(["v", "-k*sin(x) + cos(t)*exp(-v^2)"], ["x", "v"], {"k": 9.81})
    x, v, t = 0.4, -1.3, 2.0
    np.testing.assert_allclose(J(t, [x, v]), [[0, 1], [-9.81 * np.cos(x), -2 * v * np.cos(t) * np.exp(-v * v)]],
                               rtol=1e-14)


def test_the_files_matrix_of_expressions():
    J = expression_jacobian([["0", 1], ["-2*mu*x*v - 1", "mu*(1 - x^2)"]], ["x", "v"], {"mu": 1000.0})
    np.testing.assert_array_equal(J(0.0, [2.0, 0.5]), [[0, 1], [-2001, -3000]])
