"""Issue 41's diagrams (no state: evaluated at the output times; the loop gain through a solved algebraic
loop) and the blocks issue 36 adds for imported Simulink models (derivative, stop, the random sources)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odelab.run.runner import run_experiment

EPS = np.finfo(float).eps


def _run(tmp_path, text, name="d.toml"):
    path = tmp_path / name
    path.write_text(text)
    (result,) = run_experiment(path)
    return result


def _out(result, name):
    return result.y[:, list(result.case.problem.outputs).index(name)]


STATELESS = """
[system]
kind = "diagram"
outputs = { y = "g2" }
[blocks]
src = { type = "sine", frequency = 2 }
step = { type = "step", time = 0.5, final = 3 }
add = { type = "sum", signs = "++", inputs = ["src", "step"] }
g1 = { type = "gain", gain = 3, input = "add" }
g2 = { type = "gain", gain = 0.5, input = "g1" }
[time]
stop = 2
"""


def test_a_diagram_without_state_is_evaluated_at_simulinks_output_times(tmp_path):
    r = _run(tmp_path, STATELESS)
    assert r.status == "success" and r.x.shape == (r.t.size, 0) and r.stats.nsteps == 0
    # every max_step (Simulink's auto: the span over 50) and the step's time twice: before and after the jump
    grid = [2 * k / 50 for k in range(51)]
    assert r.t.size == 53 and sorted(set(r.t.tolist())) == sorted(set(grid) | {0.5})
    i = np.flatnonzero(r.t == 0.5)
    assert i.size == 2
    y = _out(r, "y")
    exact = 1.5 * (np.sin(2 * r.t) + np.where(r.t >= 0.5, 3.0, 0.0))
    exact[i[0]] = 1.5 * np.sin(1.0)  # the row before the jump holds the step's initial value
    assert np.max(np.abs(y - exact)) <= 4 * EPS * 6.0
    assert "evaluated at 53 times" in r.warnings[0]


def test_an_algebraic_loop_without_state_is_solved_at_each_output_time(tmp_path):
    r = _run(tmp_path, """
[system]
kind = "diagram"
outputs = { y = "sum" }
[blocks]
src = { type = "ramp", slope = 2 }
sum = { type = "sum", signs = "+-", inputs = ["src", "fb"] }
fb = { type = "gain", gain = 3, input = "sum" }
[time]
stop = 1
""")
    y = _out(r, "y")  # y = u - 3 y: y = u / 4 = t / 2
    assert r.status == "success" and np.max(np.abs(y - r.t / 2)) <= 8 * EPS
    assert any("algebraic loop sum -> fb -> sum solved" in w for w in r.warnings)


LOOP = """
[system]
kind = "diagram"
outputs = { y = "plant" }
[blocks]
ref = { type = "step", time = 0 }
err = { type = "sum", signs = "+-", inputs = ["ref", "plant"] }
{inner}
plant = { type = "integrator", input = "k" }
[time]
stop = 2
[analysis]
loop = "plant"
"""


@pytest.mark.parametrize("inner", [
    'inner = { type = "sum", signs = "++", inputs = ["err", "fb"] }\nfb = { type = "gain", gain = 0.5, input = '
    '"inner" }\nk = { type = "gain", gain = 2, input = "inner" }',  # inner = 2 err through a solved loop
    'k = { type = "gain", gain = 4, input = "err" }'])
def test_the_loop_gain_through_a_solved_algebraic_loop(tmp_path, inner):
    r = _run(tmp_path, LOOP.replace("{inner}", inner))
    loop = r.extra["analysis"]["loop"]
    num, den = np.array(loop["num"]), np.array(loop["den"])  # L(s) = 4/s either way (before the fix: 0)
    assert num[-1] / den[0] == pytest.approx(4.0, rel=1e-12) and den[-1] == 0.0
    assert np.allclose(num[:-1], 0.0, atol=1e-12)


def test_the_stop_block_ends_the_run_at_the_end_of_the_step_that_crossed(tmp_path):
    r = _run(tmp_path, """
[system]
kind = "diagram"
outputs = { x = "x" }
[blocks]
one = { type = "constant", value = 1 }
x = { type = "integrator", input = "one" }
cond = { type = "fcn", expression = "u >= 1.5", input = "x" }
halt = { type = "stop", input = "cond" }
[time]
stop = 5
[solver]
max_step = 0.1
refine = 1
""")
    x = _out(r, "x")
    assert r.status == "success"
    assert x[-1] >= 1.5 and x[-2] < 1.5 and r.t[-1] - r.t[-2] <= 0.1 * (1 + 1e-12)  # the step that crossed
    assert np.max(np.abs(x - r.t)) <= 64 * EPS * 5  # x = t
    assert r.message == (f"stopped at t = {r.t[-1]:.10g} by the stop block `halt` (its input became nonzero in the "
                         "step that ended there, as Simulink's Stop Simulation block)")


def test_the_derivative_block_is_s_over_cs_plus_1(tmp_path):
    r = _run(tmp_path, """
[system]
kind = "diagram"
outputs = { d = "d" }
[blocks]
src = { type = "sine" }
d = { type = "derivative", coefficient = 0.01, input = "src" }
[time]
stop = 3
[solver]
rtol = 1e-10
atol = 1e-12
""")
    c, t = 0.01, r.t
    exact = (np.cos(t) + c * np.sin(t) - np.exp(-t / c)) / (1 + c * c)  # s/(cs + 1) of sin t from rest
    assert np.max(np.abs(_out(r, "d") - exact)) <= 1e3 * 1e-10  # within a thousand RelTol of a unit signal


def test_random_sources_are_seeded_reproducible_and_distributed_as_simulinks(tmp_path):
    from odelab.systems.diagram.noise import draw

    text = """
[system]
kind = "diagram"
outputs = { n = "n", u = "u", w = "w" }
[blocks]
n = { type = "random-number", mean = 1, variance = 4, seed = 3, sample_time = 0.01 }
u = { type = "uniform-random-number", minimum = 2, maximum = 5, seed = 5, sample_time = 0.01 }
w = { type = "band-limited-white-noise", power = 0.1, sample_time = 0.01 }
[time]
stop = 20
"""
    a = _run(tmp_path, text, "a.toml")
    b = _run(tmp_path, text, "b.toml")
    assert np.array_equal(a.y, b.y)
    at_hits = np.isclose(a.t / 0.01, np.round(a.t / 0.01), atol=1e-9)
    k = np.round(a.t[at_hits] / 0.01).astype(int)
    n = _out(a, "n")[at_hits]
    # the row after each hit holds that hit's number: the first draw of PCG64 seeded with [seed, k]
    last = {kk: v for kk, v in zip(k, n)}
    for kk in (0, 1, 1000, 1999):
        assert last[kk] == 1 + 2 * draw(3, kk)
    values = np.array([last[kk] for kk in sorted(last)])
    assert values.size == 2001
    assert abs(values.mean() - 1) < 4 * 2 / math.sqrt(values.size)  # 4 standard errors
    uni = np.array([2 + 3 * draw(5, kk, "uniform") for kk in range(2001)])
    assert uni.min() >= 2 and uni.max() < 5
    w = np.array([math.sqrt(0.1 / 0.01) * draw(23341, kk) for kk in range(2001)])
    assert abs(w.var() / 10.0 - 1) < 4 * math.sqrt(2 / w.size)  # variance power/Ts = 10
