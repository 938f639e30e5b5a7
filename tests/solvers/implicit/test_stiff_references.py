"""Stiff solvers against published numbers: MATLAB's printed statistics, Robertson's reference."""

import numpy as np
import pytest

import odelab

from .test_ode15s_ode23s import ROBERTSON, rober


def test_ode15s_counts_equal_matlabs_printed_statistics():
    # MATLAB's ode15s with Stats on, as printed in SciML/MATLABDiffEq.jl pull request 18:
    # 42 successful steps, 1 failed attempt, 57 function evaluations, 1 partial derivative,
    # 10 LU decompositions, 53 solutions of linear systems. (No decision sits near its
    # threshold: the counts hold with RelTol and AbsTol moved by 1e-7 relative either way.)
    sol = odelab.ode15s(lambda t, y: [-10 * y[0], -0.01 * y[1]], [0, 0.3, 0.6, 0.9, 1], [1.01, 1.01],
                        RelTol=1e-3, AbsTol=1e-6)
    s = sol.stats
    assert (s.nsteps, s.nfailed, s.nfevals, s.npds, s.ndecomps, s.nsolves) == (42, 1, 57, 1, 10, 53)
    np.testing.assert_allclose(sol.y[-1], 1.01 * np.exp([-10.0, -0.01]), rtol=2e-3)


@pytest.mark.parametrize("rtol, atol, units", [(1e-4, 1e-10, 2), (1e-6, 1e-12, 5), (1e-8, 1e-14, 60)])
def test_ode23t_reaches_the_end_of_robertson(rtol, atol, units):
    # It used to thrash (286,956 failed attempts in 200,000 steps at 1e-4, stuck near t = 3.8e9).
    sol = odelab.ode23t(rober, [0, 4e10], [1, 0, 0], RelTol=rtol, AbsTol=atol)
    assert sol.success and sol.t[-1] == 4e10
    assert sol.stats.nfailed < 0.1 * sol.stats.nsteps, sol.stats
    err = np.abs(sol.y[-1] - ROBERTSON[-1]) / (rtol * np.abs(ROBERTSON[-1]) + atol)
    assert err.max() < units, err


def test_ode23t_on_robertson_at_a_crude_rtol_and_a_tiny_atol():
    # RelTol 1e-3 with AbsTol 1e-12 used to report success with y1 = -1.5e7 (y2 ringing, the
    # trapezoidal rule's undamped stiff error, had jumped to a spurious branch with y2 < 0).
    sol = odelab.ode23t(rober, [0, 1e11], [1, 0, 0], RelTol=1e-3, AbsTol=1e-12)
    assert sol.success and sol.stats.nfailed < 0.1 * sol.stats.nsteps, sol.stats
    ref = np.array([0.2083340149701255e-7, 0.8333360770334713e-13, 0.9999999791665050])  # Bari test set
    err = np.abs(sol.y[-1] - ref) / (1e-3 * ref + 1e-12)
    assert err.max() < 5, err
    assert sol.y.min() > -1e-10 and abs(sol.y[-1].sum() - 1) < 1e-10  # y1 + y2 + y3 = 1 to Newton's tolerance
