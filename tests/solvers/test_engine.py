"""The adaptive driver's storage and output: what the speed work keeps exactly as it was."""

import tracemalloc

import numpy as np
import pytest

import odelab
from odelab.solvers import engine
from odelab.solvers.dense import refine_weights
from odelab.solvers.ordered import backwards
from odelab.solvers.output import grow_rows
from odelab.solvers.registry import get_method


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


@pytest.mark.parametrize("refine", [2, 4, 7])
def test_refine_rows_interpolated_after_the_loop_are_the_per_step_products(refine):
    # 1,900+ steps: the step arrays grow many times; every interior row equals, bit for bit,
    # MATLAB's per-step formula y + h * W K evaluated on that step's stored stages.
    sol = odelab.ode45(rigid, [0, 400], [0, 1, 1], rtol=1e-6, atol=1e-9, refine=refine)
    d = sol.interpolant
    n_steps = sol.stats.nsteps
    assert n_steps > 1900 and sol.t.size == refine * n_steps + 1 and d.K.shape == (n_steps, 7, 3)
    fractions = np.arange(1, refine) / refine
    weights = refine_weights(fractions, d.coefficients)
    weights_T = [backwards(w) for w in weights]
    np.testing.assert_allclose(weights, (d.coefficients @ np.cumprod(np.broadcast_to(fractions, (4, refine - 1)),
                                                                      axis=0)).T, rtol=0, atol=1e-15)
    rows = sol.y[1:].reshape(n_steps, refine, 3)
    times = sol.t[1:].reshape(n_steps, refine)
    for k in range(n_steps):
        np.testing.assert_array_equal(rows[k, :-1], engine._refine_rows(weights_T, d.h[k], d.K[k], d.y[k], None))
        np.testing.assert_array_equal(times[k, :-1], d.t[k] + d.h[k] * fractions)
    np.testing.assert_array_equal(d.t[1:], sol.t[refine:-1:refine])  # step starts are output rows
    np.testing.assert_array_equal(d.h, np.diff(sol.t[::refine]))


def test_an_output_function_sees_exactly_the_rows_stored():
    seen = []

    def watch(t, y, flag):
        if flag == "":
            seen.append((t.copy(), y.copy()))
        return False

    sol = odelab.ode45(rigid, [0, 300], [0, 1, 1], rtol=1e-6, atol=1e-9, OutputFcn=watch)
    assert len(seen) == sol.stats.nsteps > 1000 and all(t.shape == (4,) for t, _ in seen)
    np.testing.assert_array_equal(np.concatenate([t for t, _ in seen]), sol.t[1:])
    np.testing.assert_array_equal(np.concatenate([y for _, y in seen]), sol.y[1:])


@pytest.mark.parametrize("bad", [1, 2])
def test_a_nan_in_any_component_stops_as_not_finite(bad):
    # The error norm takes its maximum over a Python list for small systems, where max() would
    # skip a NaN after the first entry: the driver must still stop, as numpy's max does.
    def rhs(t, y):
        out = [1.0, 1.0, 1.0]
        if t > 0.5:
            out[bad] = np.nan
        return out

    with pytest.warns(odelab.SolverWarning, match="NaN or infinite"):
        sol = odelab.ode45(rhs, [0, 1], [0, 0, 0])
    assert sol.status == "failed"
    assert "the derivative became NaN or infinite" in sol.message
    assert 0.4 < sol.t[-1] <= 0.5 and np.isfinite(sol.y).all()


def test_the_error_norm_is_the_same_above_the_small_system_size():
    # 40 components take numpy's reduction; their first three components are the rigid body,
    # the rest do not move: the steps are the same as the rigid body's alone.
    def padded(t, y):
        return np.concatenate([rigid(t, y[:3]), np.zeros(y.size - 3)])

    y0 = np.concatenate([[0, 1, 1], np.ones(engine._SMALL + 24)])
    big = odelab.ode45(padded, [0, 30], y0, rtol=1e-6, atol=1e-9)
    small = odelab.ode45(rigid, [0, 30], [0, 1, 1], rtol=1e-6, atol=1e-9)
    assert big.stats == small.stats and big.stats.nsteps > 100
    # (BLAS sums a 40-column stage product in another order than a 3-column one: round-off,
    # which the controller's power of the error moves the step sizes by ~1e-10 relative)
    np.testing.assert_allclose(big.t, small.t, rtol=1e-9)
    np.testing.assert_allclose(big.y[:, :3], small.y, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(big.y[:, 3:], 1.0)


def test_grow_keeps_the_rows_it_has():
    a = np.empty((4, 2, 3))
    a.ravel()[:] = np.arange(24.0)
    grow_rows(a, 9)
    assert a.shape == (9, 2, 3)
    np.testing.assert_array_equal(a[:4].ravel(), np.arange(24.0))
    grow_rows(a, 2)
    np.testing.assert_array_equal(a.ravel(), np.arange(12.0))


def test_a_long_run_stores_about_its_own_bytes():
    # One output row per step: each stored step is its 7 stages, its end state and time
    # ((7*3 + 3 + 1) * 8 = 200 bytes), and the arrays grow by a quarter when full. Lists of
    # small arrays (the earlier engine's output) cost over 400 bytes a step. (tracemalloc
    # slows the loop 15-fold: a short run.)
    m = get_method("ode45")
    tab = m.tableau
    y0 = np.array([0.0, 1.0, 1.0])
    threshold = np.full(3, 1e-3)
    tracemalloc.start()
    try:
        out = engine.integrate_adaptive(rigid, np.array([0.0, 300.0]), y0, rigid(0.0, y0), tab.A, tab.c,
                                        tab.error_weights, tab.dense, m.power, m.shrink_min, 1e-6, threshold,
                                        30.0, float("nan"), 1, False, 0)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    nsteps = out.nsteps
    assert nsteps > 1400 and out.t.size == nsteps + 1
    assert peak / nsteps < 1.3 * 200
