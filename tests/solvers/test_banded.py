"""Banded LU of the stiff solvers' iteration matrices (odelab.solvers.banded) on the Python path.

When the Jacobian is an expression system's exact one, its structure is known from the
equations, and a system whose structure permutes to a narrow band factors ``I - c J`` with
LAPACK's banded LU; small systems and systems that are not banded stay dense.
"""

import numpy as np
import pytest
import scipy.linalg

import odelab
from odelab.expressions import compile_vector
from odelab.solvers.banded import MIN_STATES, plan_band, structural_pattern
from odelab.solvers.implicit.common import Work
from odelab.systems.jacobian import complex_step_jacobian

from .test_compiled_stiff import _chain

EPS = np.finfo(float).eps


def chain(masses, k=1e4, c=1e3):
    """A chain of masses between a wall and a free end (springs k, dampers c), a unit force on the last."""
    return (*_chain(masses), {"k": k, "c": c})


def chain_matrix(masses, k=1e4, c=1e3):
    """The chain as y' = A y + force."""
    L = np.diag(-2.0 * np.ones(masses)) + np.diag(np.ones(masses - 1), 1) + np.diag(np.ones(masses - 1), -1)
    L[-1, -1] = -1.0
    A = np.block([[np.zeros((masses, masses)), np.eye(masses)], [k * L, c * L]])
    force = np.zeros(2 * masses)
    force[-1] = 1.0
    return A, force


def test_the_pattern_is_which_equation_names_which_state():
    states, equations, _ = chain(10)
    J = complex_step_jacobian(equations, states, {"k": 1e4, "c": 1e3})
    A, _ = chain_matrix(10)
    np.testing.assert_array_equal(J.pattern(), A != 0)
    assert J.pattern() is J.pattern()  # parsed once
    np.testing.assert_array_equal(structural_pattern([{"a", "t"}, {"b", "k"}], ["a", "b"]), [[1, 0], [0, 1]])


def test_a_chain_permutes_to_a_narrow_band():
    states, equations, parameters = chain(100)
    pattern = complex_step_jacobian(equations, states, parameters).pattern()
    rows, cols = np.nonzero(pattern)
    assert (rows - cols).max() == 101  # x before v: the natural order's band is the whole matrix
    band = plan_band(pattern)
    assert (band.kl, band.ku, band.ldab) == (3, 3, 10)
    np.testing.assert_array_equal(np.sort(band.perm), np.arange(200))
    inverse = np.argsort(band.perm)
    offsets = inverse[rows] - inverse[cols]
    assert offsets.max() == band.kl and -offsets.min() == band.ku


def test_small_or_unbanded_systems_stay_dense():
    assert plan_band(np.ones((MIN_STATES - 1, MIN_STATES - 1), dtype=bool) & np.eye(MIN_STATES - 1, dtype=bool)) is None
    n = 40  # each state feels the mean of all: no permutation makes that banded
    states = [f"x{i}" for i in range(n)]
    mean = " + ".join(states)
    pattern = structural_pattern([{f"x{i}", *states} for i in range(n)], states)
    assert pattern.all() and plan_band(pattern) is None
    pattern = np.eye(n, dtype=bool) | np.eye(n, k=n // 2, dtype=bool) | np.eye(n, k=-(n // 2 - 1), dtype=bool)
    assert plan_band(pattern) is not None  # a ring: folded into a band
    equations = [f"-x{i} + 0.01*({mean})" for i in range(n)]
    work = Work(lambda t, y: y, n, jacobian=complex_step_jacobian(equations, states, {}))
    assert work.band is None


def test_the_banded_solve_is_a_solve():
    rng = np.random.default_rng(5)
    n = 60
    pattern = np.zeros((n, n), dtype=bool)
    for k in range(-2, 4):
        pattern |= np.eye(n, k=k, dtype=bool)
    shuffle = rng.permutation(n)  # hide the band: the plan must find it again
    pattern = pattern[np.ix_(shuffle, shuffle)]
    band = plan_band(pattern)
    assert band.kl + band.ku <= 6
    A = np.where(pattern, rng.standard_normal((n, n)), 0.0) + 4.0 * np.eye(n)
    b = rng.standard_normal(n)
    x = band.solve(band.factor(A), b)
    exact = np.linalg.solve(A, b)
    # backward stable: the residual is a few eps of |A| |x|
    assert np.max(np.abs(A @ x - b) / (np.abs(A) @ np.abs(x))) < 50 * EPS
    assert np.max(np.abs(x - exact)) < 1e3 * EPS * np.linalg.cond(A) * np.max(np.abs(exact))


def test_work_factors_banded_for_an_exact_jacobian_only():
    states, equations, parameters = chain(10)
    J = complex_step_jacobian(equations, states, parameters)
    assert Work(lambda t, y: y, 20, jacobian=J).band is not None
    assert Work(lambda t, y: y, 20, jacobian=J, jpattern=J.pattern()).band is None  # a given JPattern: SuperLU
    assert Work(lambda t, y: y, 20, jacobian=J, mass=np.eye(20)).band is None
    assert Work(lambda t, y: y, 20, jacobian=chain_matrix(10)[0]).band is None  # a matrix: dense
    small = chain(4)
    assert Work(lambda t, y: y, 8, jacobian=complex_step_jacobian(small[1], small[0], small[2])).band is None


@pytest.mark.parametrize("method", ["ode23s", "ode15s", "ode23t", "ode23tb"])
def test_the_chain_against_its_closed_form(method):
    """y(t) = e^{At} y0 + A^{-1} (e^{At} - I) force, at the tspan times, in units of the tolerance."""
    states, equations, parameters = chain(10)
    F = compile_vector(equations, args=["t", *states], constants=parameters)
    J = complex_step_jacobian(equations, states, parameters)
    A, force = chain_matrix(10)
    tspan = np.linspace(0.0, 10.0, 21)
    rtol, atol = 1e-5, 1e-8
    sol = odelab.solve(lambda t, x: F(t, *x), tspan, np.zeros(20), method=method, jacobian=J, rtol=rtol, atol=atol)
    exact = np.array([np.linalg.solve(A, (scipy.linalg.expm(A * t) - np.eye(20)) @ force) for t in tspan])
    scale = np.max(np.abs(exact), axis=0)
    err = np.max(np.abs(sol.y - exact) / (rtol * scale + atol))
    assert err < 10, err  # global error a few tolerances (3.6-4.6 measured)
    dense = odelab.solve(lambda t, x: F(t, *x), tspan, np.zeros(20), method=method, jacobian=lambda t, y: J(t, y),
                         rtol=rtol, atol=atol)
    # the dense LU's run (a plain callable has no pattern): the same solution to round-off (1e-9 to 2e-8
    # tolerances measured; ode23tb takes other steps from one rounding on)
    assert np.max(np.abs(sol.y - dense.y) / (rtol * scale + atol)) < 1e-5
