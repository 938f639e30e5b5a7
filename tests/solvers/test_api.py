"""odelab.solve: every method by name, fixed-step orders, SciPy stats, failures and bad arguments."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import odelab
from odelab.solvers.api import fixed_grid


def growth(t, y):
    return y * np.cos(t)  # exact: y0 * exp(sin t)


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


@pytest.mark.parametrize(
    "method, order",
    [("euler", 1), ("heun", 2), ("midpoint", 2), ("ralston", 2), ("rk3", 3), ("rk4", 4)],
)
def test_fixed_step_observed_order(method, order):
    hs = 0.2 / 2.0 ** np.arange(5)
    errors = []
    for h in hs:
        sol = odelab.solve(growth, [0, 2], 1.0, method=method, h=h)
        assert sol.t[-1] == 2 and sol.stats.nsteps == round(2 / h)
        errors.append(abs(sol.y[-1, 0] - np.exp(np.sin(2.0))))
    slope = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert abs(slope - order) < 0.2, slope


def test_fixed_step_counts_and_grid():
    sol = odelab.solve(growth, [0, 1], 1.0, method="rk4", h=0.1)
    assert (sol.stats.nsteps, sol.stats.nfailed, sol.stats.nfevals) == (10, 0, 40)
    np.testing.assert_allclose(sol.t, np.linspace(0, 1, 11), atol=1e-15)
    # A step that does not divide the span: steps of exactly h, the last one shortened.
    grid, keep = fixed_grid(np.array([0.0, 1.0]), 0.3)
    np.testing.assert_allclose(grid, [0, 0.3, 0.6, 0.9, 1.0])
    assert keep.all()
    # A vector tspan: steps of h inside each interval, output only at tspan.
    sol = odelab.solve(growth, [0, 0.25, 1], 1.0, method="heun", h=0.1)
    np.testing.assert_array_equal(sol.t, [0, 0.25, 1])
    assert sol.stats.nsteps == 3 + 8
    back = odelab.solve(growth, [1, 0], 1.0, method="rk4", h=0.25)
    np.testing.assert_allclose(back.t, [1, 0.75, 0.5, 0.25, 0])


def test_scipy_methods_match_solve_ivp_exactly():
    for method in ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA"):
        ours = odelab.solve(rigid, [0, 12], [0, 1, 1], method=method, rtol=1e-6, atol=1e-8)
        ref = solve_ivp(rigid, [0, 12], [0, 1, 1], method=method, rtol=1e-6, atol=1e-8)
        np.testing.assert_array_equal(ours.t, ref.t)
        np.testing.assert_array_equal(ours.y, ref.y.T)
        assert ours.stats.nsteps == ref.t.size - 1
        assert ours.stats.nfevals == ref.nfev


@pytest.mark.parametrize("method, per_attempt", [("RK23", 3), ("RK45", 6), ("DOP853", 12)])
def test_scipy_rejected_steps_are_counted(method, per_attempt):
    sol = odelab.solve(rigid, [0, 50], [0, 1, 1], method=method, rtol=1e-3)
    s = sol.stats
    assert s.nfailed > 0
    assert s.nfevals == 2 + per_attempt * (s.nsteps + s.nfailed)  # 2: SciPy's initial-step probe


def test_scipy_implicit_methods_report_unknown_rejections():
    sol = odelab.solve(rigid, [0, 1], [0, 1, 1], method="Radau")
    assert sol.stats.nfailed is None and sol.success


def test_scipy_vector_tspan_matches_t_eval():
    times = np.linspace(0, 12, 7)
    ours = odelab.solve(rigid, times, [0, 1, 1], method="RK45")
    ref = solve_ivp(rigid, [0, 12], [0, 1, 1], method="RK45", t_eval=times)
    np.testing.assert_array_equal(ours.t, times)
    np.testing.assert_allclose(ours.y, ref.y.T, rtol=1e-14, atol=1e-14)


def test_methods_are_case_insensitive_and_listed():
    assert odelab.solve(growth, [0, 1], 1.0, method="Ode45").method == "ode45"
    assert set(odelab.METHODS) >= {"ode23", "ode45", "euler", "rk4", "RK45", "LSODA"}


# --- failures: status and message, never an exception -----------------------------------------


def test_finite_time_blow_up_fails_with_a_message():
    with pytest.warns(odelab.SolverWarning, match="step size fell below"):
        sol = odelab.ode45(lambda t, y: y**2, [0, 2], 1.0)
    assert sol.status == "failed" and not sol.success
    assert 0.9999 < sol.t[-1] < 1.0  # the exact solution 1/(1-t) blows up at t = 1
    assert "step size fell below 1.8e-15" in sol.message
    assert "unbounded" in sol.message and "t = 0.9999" in sol.message


def test_nan_derivative_stops_with_the_solution_so_far():
    with pytest.warns(odelab.SolverWarning, match="NaN or infinite"):
        sol = odelab.ode45(lambda t, y: np.nan if t > 1 else -y, [0, 2], 1.0)
    assert sol.status == "failed" and "NaN or infinite" in sol.message
    assert sol.t[-1] <= 1 and np.all(np.isfinite(sol.y))
    np.testing.assert_allclose(sol.y[-1, 0], np.exp(-sol.t[-1]), rtol=1e-3)


def test_nan_at_the_start():
    with np.errstate(invalid="ignore"), pytest.warns(odelab.SolverWarning, match="could not start"):
        sol = odelab.ode23(lambda t, y: np.log(y), [0, 1], -1.0)
    assert sol.status == "failed" and "could not start" in sol.message and sol.t.size == 1


def test_a_raising_right_hand_side_is_reported():
    def fun(t, y):
        if t > 0.5:
            raise ZeroDivisionError("division by zero")
        return -y

    for method, extra in (("ode45", {}), ("RK45", {}), ("rk4", {"h": 0.1})):
        with pytest.warns(odelab.SolverWarning, match="ZeroDivisionError"):
            sol = odelab.solve(fun, [0, 1], 1.0, method=method, **extra)
        assert sol.status == "failed", method
        assert "raised ZeroDivisionError: division by zero" in sol.message
        assert sol.t[-1] <= 0.5


def test_max_steps_guard():
    vdp = lambda t, y: [y[1], 1000 * (1 - y[0] ** 2) * y[1] - y[0]]  # stiff
    with pytest.warns(odelab.SolverWarning, match="max_steps = 500"):
        sol = odelab.ode45(vdp, [0, 3000], [2, 0], max_steps=500)
    assert sol.status == "failed" and sol.stats.nsteps == 500
    assert "max_steps = 500" in sol.message and "use method 'ode15s'" in sol.message


def test_fixed_step_overflow_is_reported():
    with np.errstate(over="ignore"), pytest.warns(odelab.SolverWarning, match="NaN or infinite"):
        sol = odelab.solve(lambda t, y: y**2, [0, 3], 1.0, method="euler", h=0.1)  # overflows at t = 2.2
    assert sol.status == "failed" and "NaN or infinite" in sol.message


# --- bad arguments: one ValueError naming the argument, the value and the fix ------------------


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"tspan": [0]}, "`tspan` must be [t0, tf]"),
        ({"tspan": [1, 1]}, "starts and ends at the same time"),
        ({"tspan": [0, 2, 1]}, "entries must strictly increase; entry 2 (1) follows 2"),
        ({"tspan": [0, np.inf]}, "`tspan` entries must be finite"),
        ({"y0": [np.nan]}, "`y0` must be finite; entry 0 is nan"),
        ({"y0": "abc"}, "`y0` must be a number"),
        ({"rtol": -1e-3}, "`rtol` must be a positive, finite number; got -0.001"),
        ({"rtol": np.nan}, "`rtol` must be a positive, finite number"),
        ({"atol": [1e-6, 1e-6]}, "`atol` has 2 values but there is 1 state"),
        ({"atol": 0}, "`atol` values must be positive"),
        ({"RelTol": 1e-4, "rtol": 1e-5}, "set the same option"),
        ({"RelTl": 1e-4}, "unknown solver option `RelTl`. Did you mean `RelTol`?"),
        ({"h": 0.1}, "`h` (a fixed step) is for the fixed-step methods"),
        ({"refine": 0}, "`refine` must be a whole number >= 1"),
        ({"max_step": -1}, "`max_step` must be a positive"),
        ({"norm_control": "maybe"}, "`norm_control` must be true/false"),
    ],
)
def test_bad_arguments(kwargs, message):
    args = {"tspan": [0, 1], "y0": [1.0]}
    args.update(kwargs)
    with pytest.raises(odelab.InputError) as info:
        odelab.ode45(lambda t, y: -y, args.pop("tspan"), args.pop("y0"), **args)
    assert message in str(info.value)
    assert isinstance(info.value, ValueError)


def test_wrong_shapes_and_types_from_fun():
    with pytest.raises(ValueError, match=r"`fun` returned 2 values \(shape \(2,\)\) but the state has 1"):
        odelab.ode45(lambda t, y: [1, 2], [0, 1], [1.0])
    with pytest.raises(ValueError, match="returned complex values"):
        odelab.ode45(lambda t, y: y * 1j, [0, 1], [1.0])
    # MATLAB-style column vectors are accepted.
    sol = odelab.ode45(lambda t, y: -y.reshape(2, 1), [0, 1], [1.0, 2.0])
    np.testing.assert_allclose(sol.y[-1], np.exp(-1) * np.array([1, 2]), rtol=1e-3)


def test_method_errors():
    with pytest.raises(ValueError, match="'rk5', which is not a method odelab knows. Did you mean 'RK45'"):
        odelab.solve(growth, [0, 1], 1.0, method="rk5")
    with pytest.raises(ValueError, match="rk4 is a fixed-step method: give the step `h`"):
        odelab.solve(growth, [0, 1], 1.0, method="rk4")
    with pytest.raises(ValueError, match="`rtol` does not apply to rk4"):
        odelab.solve(growth, [0, 1], 1.0, method="rk4", h=0.1, rtol=1e-3)
    with pytest.raises(ValueError, match="`fun` must be a callable"):
        odelab.solve(None, [0, 1], 1.0)


def test_an_exception_in_the_users_function_names_its_file_and_line(tmp_path):
    import importlib.util

    src = tmp_path / "eq1.py"
    src.write_text("import numpy as np\n\ndef eq1(t, y):\n    return np.cos(t) + undefined_name\n")
    spec = importlib.util.spec_from_file_location("eq1_under_test", src)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    sol = odelab.ode23(module.eq1, [0, 1], 2.0)
    assert sol.status == "failed"
    assert "NameError: name 'undefined_name' is not defined (eq1.py, line 4)" in sol.message


def test_every_driver_reports_why_it_stopped_as_one_status():
    """One Status for every driver: the Solution carries it, and status is its label."""
    from odelab.solvers.status import Status

    decay = lambda t, y: -y  # noqa: E731
    for method in ("ode45", "ode113", "ode15s", "ode23t", "rk4"):
        options = {"h": 0.1} if method == "rk4" else {}
        sol = odelab.solve(decay, [0, 1], [1.0], method=method, **options)
        assert sol.reason is Status.SUCCESS and sol.status == "success", method
    with pytest.warns(odelab.SolverWarning):
        sol = odelab.solve(decay, [0, 10], [1.0], method="ode45", max_steps=3)
    assert sol.reason is Status.MAX_STEPS and sol.status == "failed"
    event = lambda t, y: (y[0] - 0.5, True, 0)  # noqa: E731
    for method in ("ode45", "ode113", "ode23s"):
        sol = odelab.solve(decay, [0, 10], [1.0], method=method, events=event)
        assert sol.reason is Status.TERMINAL_EVENT and sol.status == "success", method
    assert abs(sol.te[0] - np.log(2.0)) / 1e-3 < 5  # ode23s at rtol = 1e-3
    assert [s.failed for s in Status] == [False, True, True, True, True, False, False]
