"""The shared per-step output collector (odelab.solvers.output), driven by a toy driver."""

import numpy as np

import odelab
from odelab.solvers.output import FIRST_CAPACITY, DriverResult, NonNegative, StepOutput, StepStore


FIELDS = [((1, 2), float)]  # one record a step (a stand-in for the stages)


def _line(t0, y0, slope):
    """The exact solution y = y0 + slope (t - t0) of y' = slope, as a step's interpolant."""
    return lambda tq: y0 + slope * (np.asarray(tq, dtype=float)[..., None] - t0)


def _drive(out, t_ends, slope=np.array([1.0, -2.0])):
    """Feed ``out`` the steps of y' = slope from y(0) = 0 ending at ``t_ends``; the stop index."""
    t, y = 0.0, np.zeros(2)
    for k, tnew in enumerate(t_ends):
        ynew = slope * tnew
        line = _line(0.0, np.zeros(2), slope)
        stop = False
        if out.events is not None:
            cut = out.locate(lambda tq: line(tq), t, y, tnew, ynew)
            if cut is not None:
                tnew, ynew = cut
                stop = True
        out.store.add(tnew, ynew, np.full((1, 2), float(k)))

        def values(times, rows):
            rows[...] = line(times)

        if out.per_step and out.emit(t, tnew, ynew, stop, values, lambda times: line(times)):
            return k
        if stop:
            return k
        t, y = tnew, ynew
    return None


def test_the_store_grows_in_place_and_keeps_every_record():
    store = StepStore(0.0, np.zeros(3), [((2, 3), float), ((), bool)])
    steps = 3 * FIRST_CAPACITY + 5
    for k in range(steps):
        store.add(k + 1.0, np.full(3, k + 1.0), np.full((2, 3), float(k)), k % 2 == 0)
    store.trim()
    assert store.count == steps and store.t.shape == (steps + 1,) and store.y.shape == (steps + 1, 3)
    np.testing.assert_array_equal(store.t, np.arange(steps + 1.0))
    np.testing.assert_array_equal(store.fields[0][:, 0, 0], np.arange(float(steps)))
    np.testing.assert_array_equal(store.fields[1], np.arange(steps) % 2 == 0)


def test_tspan_output_interpolates_inside_steps_and_takes_an_end_as_it_is():
    tspan = np.array([0.0, 0.25, 1.0, 1.5, 3.0])
    out = StepOutput(tspan, np.zeros(2), 1, FIELDS)
    assert out.per_step
    _drive(out, [1.0, 2.0, 3.0])
    t_out, y_out = out.finish()
    np.testing.assert_array_equal(t_out, tspan)
    np.testing.assert_array_equal(y_out, np.outer(tspan, [1.0, -2.0]))
    assert out.store.count == 3 and out.store.t[-1] == 3.0


def test_a_terminal_event_cuts_the_step_and_is_output_as_matlab_does():
    # y1 = t crosses 1.2 inside the second step: the output gets the tspan entries before it
    # and then the event's point (MATLAB's ode45/ode113 with a vector tspan).
    def events(t, y):
        return np.array([y[0] - 1.2]), np.array([True]), np.array([0])

    tspan = np.array([0.0, 0.5, 1.0, 1.5, 2.0])
    out = StepOutput(tspan, np.zeros(2), 1, FIELDS, events=events, v0=np.array([-1.2]))
    assert _drive(out, [1.0, 2.0]) == 1
    t_out, y_out = out.finish()
    te, ye, ie = out.found
    assert ie == [0] and abs(te[0] - 1.2) < 1e-12
    np.testing.assert_array_equal(t_out, [0.0, 0.5, 1.0, te[0]])
    np.testing.assert_array_equal(y_out[-1], ye[0])


def test_refine_rows_and_the_output_function_stop():
    seen = []

    def output_fcn(t_new, y_new):
        seen.append(t_new)
        return len(seen) == 2  # stop after the second step

    out = StepOutput(np.array([0.0, 4.0]), np.zeros(2), 4, FIELDS, output_fcn=output_fcn)
    assert _drive(out, [1.0, 2.0, 3.0, 4.0]) == 1
    t_out, y_out = out.finish()
    np.testing.assert_array_equal(t_out, np.arange(9) / 4)
    np.testing.assert_array_equal(y_out, np.outer(t_out, [1.0, -2.0]))
    np.testing.assert_array_equal(seen[1], [1.25, 1.5, 1.75, 2.0])


def test_nonnegative_error_and_clip():
    nn = NonNegative(np.array([1]), np.array([1.0, 0.5]), norm_control=False)
    y = np.array([-1.0, -0.25])
    assert nn.negative(y) and nn.error(y) == 0.5  # 0.25 / 0.5; the free component does not count
    assert nn.clip(y) and y.tolist() == [-1.0, 0.0] and not nn.clip(y)


def test_the_drivers_return_a_typed_result_that_unpacks_in_order():
    for method in ("ode45", "ode113"):
        sol = odelab.solve(lambda t, y: -y, [0, 1], [1.0], method=method)
        assert sol.status == "success"
    from odelab.solvers import adams

    f = lambda t, y: -y  # noqa: E731
    res = adams.integrate_ode113(f, np.array([0.0, 1.0]), np.array([1.0]), np.array([-1.0]), 1e-3,
                                 np.array([1e-3]), 0.1, float("nan"), 1, False, 0)
    assert isinstance(res, DriverResult)
    t, y, nsteps, nfailed, nfevals, status, t_stop, h_stop, exc, found, steps = res
    assert (nsteps, nfevals, t_stop, exc, found) == (res.nsteps, res.nfevals, 1.0, None, ([], [], []))
    assert t is res.t and steps is res.steps and abs(y[-1, 0] - np.exp(-1)) < 1e-3
