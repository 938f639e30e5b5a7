"""Events (MATLAB's odeset Events) located by the native stiff solvers ode15s, ode23s, ode23t, ode23tb.

The stiff test problem ``y' = -1000 (y - cos t)``, ``y(0) = 0`` has the closed form
``y = A cos t + B sin t - A exp(-1000 t)`` with ``A = 1e6/(1e6+1)``, ``B = 1e3/(1e6+1)``, so the
time it falls through 0.5 is known to round-off (a root of the closed form). Errors are in
units of the tolerance the solver works to at the event, ``rtol * |y| = 0.5 rtol``, as the error
in ``y`` that the error in the time stands for (``|y'(te)| |te - exact|``).
"""

import math
from pathlib import Path

import numpy as np
import pytest

import odelab
from odelab.run.runner import run_experiment

STIFF = ("ode15s", "ode23s", "ode23t", "ode23tb")
A, B = 1e6 / (1e6 + 1), 1e3 / (1e6 + 1)


def stiff(t, y):
    return [-1000.0 * (y[0] - math.cos(t))]


def exact(t):
    return A * math.cos(t) + B * math.sin(t) - A * math.exp(-1000.0 * t)


def exact_crossing(lo, hi, level=0.5):
    """The root of ``exact(t) = level`` in [lo, hi] by bisection to round-off."""
    flo = exact(lo) - level
    while hi - lo > 4 * math.ulp(hi):
        mid = 0.5 * (lo + hi)
        fmid = exact(mid) - level
        if (fmid > 0) == (flo > 0):
            lo, flo = mid, fmid
        else:
            hi = mid
    return 0.5 * (lo + hi)


TE = exact_crossing(0.5, 1.5)  # 1.0481972621881...
SLOPE = abs(-A * math.sin(TE) + B * math.cos(TE))  # |y'(te)| = 0.866...


def falling_half(t, y):
    return [y[0] - 0.5], [1], [-1]


def units(sol, rtol):
    return abs(sol.te[0] - TE) * SLOPE / (0.5 * rtol)


def test_the_exact_crossing():
    assert TE == pytest.approx(1.0481972621881, abs=1e-12)
    assert abs(exact(TE) - 0.5) < 1e-15


# Measured: at rtol 1e-3 ode15s 0.12, ode23s 0.18, ode23t 0.13, ode23tb 0.49 units; at 1e-5
# ode15s 0.05, ode23s 0.25, ode23t 0.59 units.
@pytest.mark.parametrize("method, rtol, bound", [
    ("ode15s", 1e-3, 0.5), ("ode23s", 1e-3, 0.5), ("ode23t", 1e-3, 1.0), ("ode23tb", 1e-3, 1.0),
    ("ode15s", 1e-5, 0.5), ("ode23s", 1e-5, 1.0), ("ode23t", 1e-5, 1.0),
])
def test_a_terminal_event_is_located_within_the_tolerance_and_stops_the_run(method, rtol, bound):
    sol = odelab.solve(stiff, [0, 3], 0.0, method=method, rtol=rtol, atol=rtol * 1e-3, events=falling_half)
    assert units(sol, rtol) < bound
    assert sol.status == "success"
    assert sol.message == f"{method} stopped at t = {sol.te[0]:.10g}: terminal event 0 occurred."
    assert sol.ie.tolist() == [0] and sol.ye.shape == (1, 1)
    # the run ends exactly at the event, on the level (the interpolant's zero, to round-off)
    assert sol.t[-1] == sol.te[0] and sol.y[-1, 0] == sol.ye[0, 0]
    assert abs(sol.ye[0, 0] - 0.5) < 1e-12
    assert np.all(np.diff(sol.t) > 0) and sol.t[-2] < sol.te[0]


def test_ode23tb_locates_on_its_interpolant_at_tight_tolerances():
    # ode23tb's interpolant is MATLAB's ntrp23tb, the quadratic through y_n, the TR stage y_g
    # and y_n+1; at rtol 1e-5 on this stiff problem it is off by ~26 tolerances at te while the
    # step ends are within 1: the event is where that interpolant crosses, as in MATLAB.
    sol = odelab.solve(stiff, [0, 3], 0.0, method="ode23tb", rtol=1e-5, atol=1e-8, events=falling_half)
    assert abs(odelab.deval(sol, sol.te[0])[0] - 0.5) < 1e-12
    assert 10 < units(sol, 1e-5) < 40


@pytest.mark.parametrize("method", STIFF)
@pytest.mark.parametrize("direction, crossings", [
    (0, [None, TE, 5.23, 7.33]), (-1, [TE, 7.33]), (1, [None, 5.23]),
])
def test_direction_filters_crossings_of_a_non_terminal_event(method, direction, crossings):
    # y rises through 0.5 in the initial transient (t = 6.9e-4), then follows cos t + sin(t)/1000:
    # down through 0.5 near pi/3, up near 5 pi/3, down near 7 pi/3.
    sol = odelab.solve(stiff, [0, 10], 0.0, method=method, events=lambda t, y: ([y[0] - 0.5], [0], [direction]))
    assert sol.status == "success" and sol.t[-1] == 10.0
    assert sol.ie.tolist() == [0] * len(crossings)
    expected = [exact_crossing(0, 0.01) if c is None else (TE if c == TE else exact_crossing(c - 0.05, c + 0.05))
                for c in crossings]
    # MATLAB's default tolerances, in units of 0.5 rtol (the error in y the error in time stands
    # for). Measured, over the four crossings: ode15s <= 0.86, ode23s <= 0.53, ode23t <= 1.19;
    # ode23tb 0.53, 3.2, 10.9, 5.6: it takes steps of MaxStep = 1 here (its step-end errors stay
    # below 0.13 units) and MATLAB's interpolant, the quadratic through y_n, the TR stage and
    # y_n+1, is not error-controlled: over a step of 1 it misses cos t by up to 1e-2.
    bound = 15.0 if method == "ode23tb" else 2.0
    for te, ex in zip(sol.te, expected):
        slope = abs(1000 * (0.5 - math.cos(ex))) if ex < 0.01 else abs(math.sin(ex))
        assert abs(te - ex) * slope < bound * 0.5e-3, (te, ex)
    if method == "ode23tb":  # with a smaller MaxStep the interpolant follows: back within the tolerance
        sol = odelab.solve(stiff, [0, 10], 0.0, method=method, max_step=0.2,
                           events=lambda t, y: ([y[0] - 0.5], [0], [direction]))
        for te, ex in zip(sol.te, expected):
            slope = abs(1000 * (0.5 - math.cos(ex))) if ex < 0.01 else abs(math.sin(ex))
            assert abs(te - ex) * slope < 2.0 * 0.5e-3, (te, ex)
    np.testing.assert_allclose(sol.ye[:, 0], 0.5, atol=1e-12)


@pytest.mark.parametrize("method", STIFF)
def test_a_terminal_event_with_output_times_ends_the_output_at_the_event(method):
    sol = odelab.solve(stiff, [0, 0.5, 1, 2, 3], 0.0, method=method, events=falling_half)
    assert sol.t[:3].tolist() == [0, 0.5, 1] and sol.t.size == 4 and sol.t[-1] == sol.te[0]
    assert sol.y[-1, 0] == sol.ye[0, 0]


@pytest.mark.parametrize("method", ["ode23t", "ode23tb"])
def test_the_dense_output_ends_at_a_terminal_event(method):
    sol = odelab.solve(stiff, [0, 3], 0.0, method=method, refine=4, events=falling_half)
    te = sol.te[0]
    assert sol.interpolant.t_end == pytest.approx(te, abs=1e-15)
    assert abs(odelab.deval(sol, te)[0] - 0.5) < 1e-12
    # the Refine points of the cut step lie on the same quadratic as before the cut
    np.testing.assert_allclose(odelab.deval(sol, sol.t[-4:]), sol.y[-4:], rtol=0, atol=1e-15)
    with pytest.raises(odelab.InputError, match="it covers"):
        odelab.deval(sol, te + 1e-3)


@pytest.mark.parametrize("method", STIFF)
def test_scipy_style_event_functions_work_too(method):
    def half(t, y):
        return y[0] - 0.5

    half.terminal, half.direction = True, -1
    sol = odelab.solve(stiff, [0, 3], 0.0, method=method, events=[half])
    assert sol.t[-1] == sol.te[0] and abs(sol.te[0] - TE) * SLOPE < 0.5e-3


@pytest.mark.parametrize("method", STIFF)
def test_an_event_at_the_initial_point_does_not_stop_the_run(method):
    # y(0) = 0 is a zero of the terminal event y: not an event at all (MATLAB's odezero ignores
    # the initial point), so the run goes on to the end
    sol = odelab.solve(stiff, [0, 1], 0.0, method=method, events=lambda t, y: ([y[0]], [1], [0]))
    assert sol.te.size == 0 and sol.ie.tolist() == []
    assert sol.t[-1] == 1.0 and sol.status == "success" and sol.message == f"{method} reached t = 1."


def test_the_bouncing_ball_file_with_ode15s(tmp_path):
    ball = Path(__file__).resolve().parents[3] / "experiments" / "bouncing_ball.toml"
    text = ball.read_text()
    assert 'method = "ode45"' in text
    path = tmp_path / "ball.toml"
    path.write_text(text.replace('method = "ode45"', 'method = "ode15s"'))
    (r,) = run_experiment(path)
    assert r.status == "success" and r.message == "ode15s reached t = 10 after 7 restarts."
    times = np.array([e["t"] for e in r.events])
    exact_t = np.array([e["exact_t"] for e in r.events])
    assert times.size == 7
    # the eight flights' statistics add up, a stiff solver's too: one Jacobian per flight (f is linear)
    assert r.stats.nsteps == 124 and r.stats.npds == 8 and r.stats.ndecomps > 8 and r.stats.nsolves > 124
    # Free fall scales with each bounce: every flight (drop, then bounce to bounce) is located
    # to within 1.2 rtol (MATLAB's default 1e-3) of its length; measured 1.07 rtol for each.
    flights, exact_flights = np.diff(times, prepend=0.0), np.diff(exact_t, prepend=0.0)
    assert np.all(np.abs(flights - exact_flights) / exact_flights < 1.2e-3)
    assert np.all(np.abs(flights - exact_flights) / exact_flights > 0.5e-3)  # ode15s is not exact on a quadratic
    for e in r.events:
        assert abs(e["state"]["h"]) < 1e-11 and e["state"]["v"] < 0


def test_deval_names_the_methods_with_dense_output():
    sol = odelab.solve(stiff, [0, 1], 0.0, method="ode15s")
    with pytest.raises(odelab.InputError) as info:
        odelab.deval(sol, 0.5)
    assert str(info.value).endswith(
        "this solution has no dense output: ode15s does not provide one. Solve with ode23, ode45 (their "
        "ntrp23/ntrp45 interpolants), ode78 or ode89 (Verner's), ode113 (Adams), ode23t or ode23tb (their "
        "quadratics), or with a vector tspan of the times you need.")


def at_half(t, y):
    return [t - 0.5], [1], [0]


@pytest.mark.parametrize("method", STIFF)
def test_a_terminal_event_on_a_tspan_entry_is_output_once(method):
    # the stiff solvers' rule (output.STIFF_RULES): the event's point is not repeated after the
    # entry it falls on; MATLAB's (the explicit engine's) outputs that time twice
    sol = odelab.solve(stiff, np.linspace(0, 2, 9), [0.0], method, events=at_half)
    assert sol.te.tolist() == [0.5]
    assert sol.t.tolist() == [0.0, 0.25, 0.5]
    assert sol.y[-1, 0] == sol.ye[0, 0]


def test_the_collector_rules_for_a_terminal_event_and_refine_times():
    from odelab.solvers.output import MATLAB_RULES, STIFF_RULES, StepOutput

    def run(rules, tspan, refine=1):
        out = StepOutput(np.array(tspan), np.zeros(1), refine, rules=rules)
        out.emit(0.0, 0.5, np.ones(1), True, lambda times, rows: rows.fill(2.0),
                 lambda times: np.zeros((times.size, 1)))
        return out.finish()[0].tolist()

    assert run(MATLAB_RULES, [0.0, 0.25, 0.5, 1.0]) == [0.0, 0.25, 0.5, 0.5]
    assert run(STIFF_RULES, [0.0, 0.25, 0.5, 1.0]) == [0.0, 0.25, 0.5]
    assert run(STIFF_RULES, [0.0, 0.25, 0.75, 1.0]) == [0.0, 0.25, 0.5]  # a point between entries: both
    assert run(MATLAB_RULES, [0.0, 0.25, 0.75, 1.0]) == [0.0, 0.25, 0.5]
    # Refine times: MATLAB's t + h*(j/refine) against the stiff solvers' t + (h*j)/refine, a step of 0.3 from 0.1
    out = {}
    for name, rules in (("matlab", MATLAB_RULES), ("stiff", STIFF_RULES)):
        o = StepOutput(np.array([0.1, 1.0]), np.zeros(1), 10, rules=rules)
        o.emit(0.1, 0.4, np.ones(1), False, None, lambda times: np.zeros((times.size, 1)))
        out[name] = o.finish()[0][1:-1]
    j = np.arange(1, 10)
    assert out["matlab"].tolist() == (0.1 + 0.30000000000000004 * (j / 10)).tolist()
    assert out["stiff"].tolist() == (0.1 + (0.30000000000000004 * j) / 10).tolist()
    assert (out["matlab"] != out["stiff"]).any()  # the two differ in the last bit somewhere
