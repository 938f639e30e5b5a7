"""[events] in experiment files: the bouncing ball's exact bounce times, resets, terminal stops, Zeno."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from odelab.exceptions import InputError
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case, run_experiment
from odelab.store.results import read_run, write_case

ROOT = Path(__file__).resolve().parents[2]
BALL = ROOT / "experiments" / "bouncing_ball.toml"
G, CR, H0 = 9.81, 0.8, 10.0
T1 = math.sqrt(2 * H0 / G)


def exact_bounce(k):
    return T1 * (1 + 2 * CR * (1 - CR**k) / (1 - CR))


def variant(tmp_path, old, new, name="ball.toml"):
    text = BALL.read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return path


def test_bouncing_ball_bounces_at_the_exact_times(tmp_path):
    (r,) = run_experiment(BALL)
    assert r.status == "success" and r.message == "ode45 reached t = 10 after 7 restarts."
    times = np.array([e["t"] for e in r.events])
    np.testing.assert_allclose(times, [exact_bounce(k) for k in range(7)], rtol=0, atol=1e-12)
    assert [e["exact_t"] for e in r.events] == pytest.approx([exact_bounce(k) for k in range(7)], abs=1e-15)
    for e in r.events:  # on the floor, falling; the reset turns the velocity around, times e
        assert abs(e["state"]["h"]) < 1e-11 and e["state"]["v"] < 0
        assert e["reset"]["v"] == -CR * e["state"]["v"] and e["reset"]["h"] == e["state"]["h"]
    # the trajectory: the jump at each bounce appears as two rows at te, marked on the first
    for number, e in enumerate(r.events, start=1):
        rows = np.flatnonzero(r.t == e["t"])
        assert rows.size == 2 and r.x[rows[0], 1] == e["state"]["v"] and r.x[rows[1], 1] == e["reset"]["v"]
        assert r.event_marks[rows[0]] == number and r.event_marks[rows[1]] == 0
    assert np.count_nonzero(r.event_marks) == 7
    # between bounces the ball is in free fall: h >= 0 up to round-off
    assert r.x[:, 0].min() > -1e-11
    folder = write_case(r, tmp_path / "runs")
    record = read_run(folder)
    assert [e["name"] for e in record["events"]] == ["floor"] * 7
    assert record["events"][3]["t"] == r.events[3]["t"] and record["events"][3]["state"]["v"] < 0
    np.testing.assert_array_equal(record["trajectory"]["event"], r.event_marks)


def test_a_terminal_event_without_reset_stops_the_case(tmp_path):
    path = variant(tmp_path, 'reset = { v = "-e*v" }        # restart with these states changed (hybrid systems)\n', "")
    (r,) = run_experiment(path)
    assert r.status == "success" and len(r.events) == 1
    assert r.t[-1] == r.events[0]["t"] and abs(r.t[-1] - T1) < 1e-12
    assert r.message == f"ode45 stopped at t = {r.t[-1]:.10g}: terminal event 'floor'."


def test_a_non_terminal_event_is_listed_and_the_case_goes_on(tmp_path):
    path = variant(tmp_path, "[events.floor]", '[events.half]\nwhen = "h - h0/2"\n\n[events.floor]')
    (r,) = run_experiment(path)
    names = [e["name"] for e in r.events]
    assert names[:2] == ["half", "floor"] and r.t[-1] == 10
    # h = 5 is reached at sqrt(h0/g), then rising and falling around each bounce's apex above 5
    assert abs(r.events[0]["t"] - math.sqrt(H0 / G)) < 1e-12


def test_a_zeno_cascade_ends_cleanly_at_max_events(tmp_path):
    path = variant(tmp_path, "stop = 10", "stop = 20")
    path.write_text(path.read_text().replace("[events.floor]", "[events]\nmax_events = 12\n\n[events.floor]"))
    (r,) = run_experiment(path)
    assert r.status == "success" and len(r.events) == 12
    assert r.message.startswith("ode45 stopped at t = ") and "after max_events = 12 events (11 restarts)" in r.message
    assert r.t[-1] == r.events[-1]["t"] and any("raise `events.max_events`" in w for w in r.warnings)


def test_a_zeno_cascade_beyond_the_steps_is_caught(tmp_path):
    # With the default max_events the bounces pile up until the first step after a restart
    # spans a whole bounce; the case ends there instead of letting the ball fall through.
    (r,) = run_experiment(variant(tmp_path, "stop = 10", "stop = 20"))
    assert r.status == "success" and "Zeno" in r.message
    assert r.t[-1] < (1 + CR) / (1 - CR) * T1 + 1e-3 and r.x[:, 0].min() > -1e-9
    assert len(r.events) < 100 and any("Zeno cascade" in w for w in r.warnings)


def test_events_with_a_vector_tspan(tmp_path):
    (r,) = run_experiment(variant(tmp_path, "stop = 10", "stop = 10\npoints = 11"))
    requested = np.linspace(0, 10, 11)
    assert set(requested) <= set(r.t.tolist())
    assert set(r.t.tolist()) - set(requested) == {e["t"] for e in r.events}
    np.testing.assert_allclose([e["t"] for e in r.events], [exact_bounce(k) for k in range(7)], atol=1e-12)


def test_nonnegative_and_mass_in_the_solver_table(tmp_path):
    base = ('[system]\nstates = ["x", "v"]\n[system.equations]\nx = "v"\nv = "-4*x - x^3"\n'
            '[initial]\nx = 1\nv = 0\n[time]\nstop = 5\n')
    plain = tmp_path / "plain.toml"
    plain.write_text(base.replace('v = "-4*x - x^3"', 'v = "(-4*x - x^3)/2"'))
    massive = tmp_path / "mass.toml"
    massive.write_text(base + '[solver]\nmass = [[1, 0], [0, "m"]]\nrtol = 1e-3\n[parameters]\nm = 2\n')
    (a,) = run_experiment(plain)
    (b,) = run_experiment(massive)
    assert a.stats.nsteps == b.stats.nsteps
    np.testing.assert_allclose(b.x, a.x, atol=1e-12)
    moving = tmp_path / "moving.toml"
    moving.write_text(base + '[solver]\nmass = [[1, 0], [0, "2 + 0*t"]]\n')
    (c,) = run_experiment(moving)
    np.testing.assert_allclose(c.x, a.x, atol=1e-12)
    tank = tmp_path / "tank.toml"
    tank.write_text('[system]\nstates = ["h"]\n[system.equations]\nh = "-abs(h)"\n[initial]\nh = 1\n[time]\nstop = 40\n'
                    '[solver]\nnonnegative = ["h"]\n')
    (d,) = run_experiment(tank)
    assert d.x.min() == 0.0
    assert load_experiment(tank).cases[0].config["solver"]["nonnegative"] == ["h"]


@pytest.mark.parametrize("change, message", [
    (("direction = \"falling\"", "direction = \"down\""), "`events.floor.direction` is 'down'; use \"rising\""),
    (("terminal = true ", "terminal = false"), "`events.floor.reset` restarts the integration, so the event must be "
                                               "terminal"),
    (("reset = { v = ", "reset = { w = "), "`events.floor.reset.w`: 'w' is not one of the states (h, v)"),
    (("when = \"h\"", "whenn = \"h\""), "`events.floor.whenn` is not an event key (when, direction, terminal, reset, "
                                        "exact). Did you mean `when`?"),
    (("method = \"ode45\"", "method = \"rk4\"\nh = 0.01"),
     "[events] are located by ode23, ode45, ode78, ode89, ode113, ode15s, ode23s, ode23t and ode23tb"),
    (("[events.floor]", "[events]\nmax_events = 0\n[events.floor]"), "`events.max_events` must be a whole number >= 1"),
    (("when = \"h\"", "when = \"hh\""), "unknown name `hh`"),
])
def test_bad_events_sections(tmp_path, change, message):
    path = variant(tmp_path, *change)
    with pytest.raises(InputError) as info:  # ExperimentError, or ExpressionError for an expression
        load_experiment(path)
    assert message in str(info.value)


def test_odelab_run_lists_the_events(tmp_path):
    from typer.testing import CliRunner

    from odelab.cli import app

    result = CliRunner().invoke(app, ["run", str(BALL), "--runs", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    assert "ode45: 7 events" in result.output
    row = next(line for line in result.output.splitlines() if line.lstrip().startswith("1  floor"))
    assert row.split()[:4] == ["1", "floor", "1.427843123", "1.427843123"] and "v = 11.2057" in row
    out = CliRunner().invoke(app, ["run", str(BALL), "--json", "--no-store"])
    case = json.loads(out.output)["experiments"][0]["cases"][0]
    assert len(case["events"]) == 7 and case["events"][6]["name"] == "floor"
    assert abs(case["events"][6]["t"] - exact_bounce(6)) < 1e-12


def test_bouncing_ball_with_ode113(tmp_path):
    # ode113's interpolant (order k+1 >= 2) is exact on free fall, so the bounces are exact too.
    (r,) = run_experiment(variant(tmp_path, 'method = "ode45"', 'method = "ode113"'))
    assert r.status == "success" and r.message == "ode113 reached t = 10 after 7 restarts."
    times = np.array([e["t"] for e in r.events])
    np.testing.assert_allclose(times, [exact_bounce(k) for k in range(7)], rtol=0, atol=1e-12)


def test_a_restart_where_the_event_function_is_zero_does_not_fire_again(tmp_path):
    # The reset puts the ball exactly on the floor (h = 0) and the event watches both directions:
    # the restart is a new t0 of MATLAB's loop, where a zero is not an event, so each bounce is
    # reported once and the times are still the geometric series.
    path = variant(tmp_path, 'reset = { v = "-e*v" }', 'reset = { h = "0", v = "-e*v" }')
    path.write_text(path.read_text().replace('direction = "falling"', 'direction = "both"'))
    (r,) = run_experiment(path)
    assert r.status == "success" and len(r.events) == 7
    # each bounce is located to odezero's 128 ulp of t (< 10) and the next flight starts from it
    located = 7 * 128 * math.ulp(10.0)
    np.testing.assert_allclose([e["t"] for e in r.events], [exact_bounce(k) for k in range(7)], rtol=0, atol=located)
    assert all(e["reset"]["h"] == 0.0 for e in r.events)


BALLODE = """
[system]
states = ["h", "v"]
[system.equations]
h = "v"
v = "-9.8"
[initial]
h = 0
v = 20
[time]
stop = 30
[events]
max_events = {max_events}
[events.floor]
when = "h"
direction = "falling"
reset = {{ h = "0", v = "-{e}*v" }}
[solver]
method = "{method}"
"""


def ballode_bounce(k, e=0.9, v0=20.0, g=9.8):
    """Closed form of MATLAB's ballode: the k-th impact (k = 0, 1, ...), flights of 2 v0 e^j / g."""
    return 2 * v0 / g * sum(e**j for j in range(k + 1))


@pytest.mark.parametrize("method", ["ode45", "ode23", "ode113", "ode78", "ode89", "ode23s", "ode23tb", "ode15s",
                                    "ode23t"])
def test_ballode_restarted_on_the_floor_bounces_ten_times(tmp_path, method):
    # MATLAB's ballode: each restart puts the ball exactly on the floor (h = 0), moving up. An
    # event at a restart's initial point is not an event (MATLAB's odezero), so this is ten
    # bounces, not a Zeno cascade. ode45/ode23 integrate a parabola exactly (errors are
    # round-off, as are ode113's, ode23s's and ode23tb's here); ode15s and ode23t (BDF and
    # trapezoidal with their own predictors) within the tolerance, RelTol 1e-3 of the time.
    path = tmp_path / "ballode.toml"
    path.write_text(BALLODE.format(max_events=10, e=0.9, method=method))
    (r,) = run_experiment(path)
    assert r.status == "success" and len(r.events) == 10
    assert not any("Zeno cascade)" in w for w in r.warnings)
    times = np.array([e["t"] for e in r.events])
    exact = np.array([ballode_bounce(k) for k in range(10)])
    units = np.abs(times - exact) / (1e-3 * exact)  # in units of the tolerance
    assert units.max() < (1e-8 if method not in ("ode15s", "ode23t") else 1e-2)
    # each impact falling onto the floor with the speed the restitution left it
    for k, e in enumerate(r.events):
        assert e["state"]["v"] == pytest.approx(-20 * 0.9**k, rel=1e-3)
    assert r.x[:, 0].min() > -1e-9 * 20.4


def test_a_zeno_ball_restarted_on_the_floor_is_still_stopped(tmp_path):
    # Restitution 0.5: the bounces pile up at 2 v0/g (1 + e/(1 - e)) = 8.1633 s. The case must
    # end there with the note, never let the ball fall through the floor to t = 30.
    path = tmp_path / "zeno.toml"
    path.write_text(BALLODE.format(max_events=100, e=0.5, method="ode45"))
    (r,) = run_experiment(path)
    zeno_time = 2 * 20 / 9.8 * (1 + 0.5 / (1 - 0.5))
    assert r.status == "success" and "Zeno" in r.message and 10 < len(r.events) < 100
    assert any("Zeno cascade" in w for w in r.warnings)
    assert r.t[-1] == pytest.approx(zeno_time, abs=1e-9) and r.x[:, 0].min() > -1e-9
    assert r.t[-1] == r.events[-1]["t"] and r.event_marks[-1] == len(r.events)
