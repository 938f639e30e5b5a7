"""The MATLAB corpus (tests/assets/matlab/corpus, SOURCES.md): each driver imported, run, and checked against an
independent solution (a closed form, or SciPy at tight tolerances from a hand translation) at the file's own
tolerances.

The error of each state is measured in units of the file's tolerance at the state's scale,
|y - y_ref| / (AbsTol + RelTol max|y_ref|), the largest over the output points; a global error of a few dozen such units is what MATLAB's controllers
give (the local error is what they control). Each case's bound is about twice what was measured on this
machine (0.04 to 108 units: docs/tutorials/coming-from-matlab.md lists them), so a wrong sign, parameter or state
order fails it by orders of magnitude.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from scipy.special import ellipj

from odelab.experiment.loader import load_experiments
from odelab.formats import read
from odelab.formats.base import ImportOptions
from odelab.run.runner import run_experiment

ROOT = Path(__file__).resolve().parents[3]
CORPUS = ROOT / "tests" / "assets" / "matlab" / "corpus"
LAB = ROOT / "tests" / "assets" / "matlab" / "lab"
SDOF_SETS = (("m", "2"), ("k", "8"), ("v0", "0"), ("x0", "1"))


def scipy_ref(f, y0, t, method="DOP853", **kw):
    sol = solve_ivp(f, (t[0], t[-1]), y0, method=method, t_eval=t, rtol=1e-12, atol=1e-14, **kw)
    assert sol.success
    return sol.y.T


def vdp(mu):
    return lambda t, y: [y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]]


def sir(beta, gamma):
    return lambda t, y: [-beta * y[0] * y[1], beta * y[0] * y[1] - gamma * y[1], gamma * y[1]]


def oscillator(m, c, k, x0, v0):
    """The free response of m x'' + c x' + k x = 0 (underdamped): [x, v]."""
    w0, zeta = math.sqrt(k / m), c / (2 * math.sqrt(k * m))
    wd = w0 * math.sqrt(1 - zeta ** 2)

    def ref(t):
        a, b = x0, (v0 + zeta * w0 * x0) / wd
        e = np.exp(-zeta * w0 * t)
        x = e * (a * np.cos(wd * t) + b * np.sin(wd * t))
        v = e * (-zeta * w0 * (a * np.cos(wd * t) + b * np.sin(wd * t)) + wd * (-a * np.sin(wd * t)
                                                                             + b * np.cos(wd * t)))
        return np.column_stack([x, v])
    return ref


def linear_step(A, B, u, t):
    """x(t) of x' = A x + B u from 0: the augmented matrix exponential."""
    n = A.shape[0]
    big = np.zeros((n + 1, n + 1))
    big[:n, :n], big[:n, n] = A, (B * u).ravel()
    return np.array([expm(big * s)[:n, n] for s in t])


def ref_rigid(t):
    sn, cn, dn, _ = ellipj(t, 0.51)
    return np.column_stack([sn, cn, dn])


def ref_sdof(t):  # y = [v, x] with v' = -k/m x, x' = v; k/m = 4, x(0) = 1, v(0) = 0
    return np.column_stack([-2 * np.sin(2 * t), np.cos(2 * t)])


def ref_tanks(t):
    k = 0.8
    return np.column_stack([10 * (k * t) ** i / math.factorial(i) * np.exp(-k * t) for i in range(5)])


def ref_logistic(t):
    r, K, P0 = 0.9, 100.0, 4.0
    return (K / (1 + (K / P0 - 1) * np.exp(-r * t))).reshape(-1, 1)


def ref_decay_chain(t):
    ka, kb = 0.5, 0.2
    a = np.exp(-ka * t)
    b = ka / (kb - ka) * (np.exp(-ka * t) - np.exp(-kb * t))
    return np.column_stack([a, b, 1 - a - b])


def ref_anon(t):
    w = math.sqrt(9.81 / 0.7)
    return np.column_stack([0.4 * np.cos(w * t), -0.4 * w * np.sin(w * t)])


def ref_two_masses(t):
    k1, k2, m1, m2 = 4.0, 2.0, 1.0, 2.0
    A = np.array([[0, 1, 0, 0], [-(k1 + k2) / m1, 0, k2 / m1, 0], [0, 0, 0, 1], [k2 / m2, 0, -k2 / m2, 0]])
    return np.array([expm(A * s) @ np.array([0.5, 0, 0, 0]) for s in t])


def ref_msd_step(t):
    m, c, k = 2.0, 0.8, 8.0
    return linear_step(np.array([[0, 1], [-k / m, -c / m]]), np.array([0, 1 / m]), 1.0, t)


def ref_heating(t):
    data = np.loadtxt(CORPUS / "interp_datafile" / "power.txt")
    f = lambda s, T: [(np.interp(s, data[:, 0], data[:, 1]) - 0.4 * (T[0] - 5)) / 2.5]
    return scipy_ref(f, [15.0], t)


def ref_varcoef(t):
    ft = np.linspace(0, 5, 25)
    gt = np.linspace(1, 6, 25)
    f = lambda s, y: [-np.interp(s, ft, ft ** 2 - ft - 3) * y[0] + np.interp(s, gt, 3 * np.sin(gt - 0.25))]
    return scipy_ref(f, [1.0], t)


def ref_ball_drag(t):
    def f(s, x):
        c = 0.02 if x[1] > 0 else 0.05 if x[1] < 0 else 0.0
        return [x[1], -9.81 - c * x[1] * abs(x[1])]
    apex = lambda s, x: x[1]
    apex.terminal = True
    up = solve_ivp(f, (0, 4), [0, 15], method="DOP853", rtol=1e-12, atol=1e-14, events=apex, dense_output=True)
    down = solve_ivp(f, (up.t[-1], 4), up.y[:, -1], method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True)
    return np.array([up.sol(s) if s <= up.t[-1] else down.sol(s) for s in t])


def ref_forced(t):
    kstiff, mass, zeta, famp = 3.0, 0.8, 0.1, 2.0
    cdamp = zeta * 2 * math.sqrt(kstiff * mass)
    fomega = 0.9 * math.sqrt(kstiff / mass)
    f = lambda s, z: [z[1], (-kstiff * z[0] - cdamp * z[1]) / mass + famp * math.cos(fomega * s) / mass]
    return scipy_ref(f, [0.0, 0.0], t)


def ref_robertson(t):
    k1, k2, k3 = 0.04, 3e7, 1e4
    f = lambda s, y: [-k1 * y[0] + k3 * y[1] * y[2], k1 * y[0] - k3 * y[1] * y[2] - k2 * y[1] ** 2, k2 * y[1] ** 2]
    sol = solve_ivp(f, (0, 40), [1, 0, 0], method="Radau", t_eval=t, rtol=1e-11, atol=1e-16)
    return sol.y.T


def ref_vaccination(t):
    alpha, beta, gamma, N = 0.002, 0.3, 0.1, 1000.0
    f = lambda s, y: [-beta * y[0] * y[1] / N - alpha * y[0], beta * y[0] * y[1] / N - gamma * y[1],
                      gamma * y[1] + alpha * y[0]]
    return scipy_ref(f, [990.0, 10.0, 0.0], t)


def ref_pendulum(y0):
    return lambda t: scipy_ref(lambda s, y: [y[1], -math.sin(y[0])], y0, t)


def ref_projectile(t):
    g, c = 9.81, 0.05

    def f(s, y):
        v = math.hypot(y[2], y[3])
        return [y[2], y[3], -c * v * y[2], -g - c * v * y[3]]
    return scipy_ref(f, [0.0, 0.0, 20.0, 25.0], t)


def ref_lotka(t):
    a, b, c, d = 0.8, 0.01, 0.6, 0.1
    return scipy_ref(lambda s, y: [a * y[0] - b * y[0] * y[1], -c * y[1] + d * y[0] * y[1]], [10.0, 60.0], t)


def ref_struct_sir(t):
    N, I0 = 5000.0, 5.0
    return scipy_ref(sir(12 * 0.03, 1 / 5), [(N - I0) / N, I0 / N, 0.0], t)


def ref_trailing_sir(t):
    a, b = 4.1e-6, 0.6
    return scipy_ref(lambda s, y: [-a * y[0] * y[1], a * y[0] * y[1] - b * y[1], b * y[1]], [2e5, 50.0, 0.0], t)


def ref_vdp(mu, y0=(2.0, 0.0)):
    def ref(t):
        method = "Radau" if mu > 2 else "DOP853"
        return scipy_ref(vdp(mu), list(y0), t, method=method)
    return ref


# folder, driver, options, {case name: reference(t) -> (points, states)}, (RelTol, AbsTol), bound in tolerance units
CASES = [
    ("lab", "run_rigid.m", None, {"ode45": ref_rigid}, (1e-4, [1e-4, 1e-4, 1e-5]), 5),
    ("vdp_local", "ode_45.m", None, {"ode45": ref_vdp(1)}, (1e-3, 1e-6), 160),
    ("sir_struct", "main_outbreak.m", None, {"ode45": ref_struct_sir}, (1e-3, 1e-6), 6),
    ("sir_trailing", "epidemic.m", None, {"ode45": ref_trailing_sir}, (1e-3, 1e-6), 5),
    ("springmass_global", "forced.m", None, {"ode45": ref_forced}, (1e-3, 1e-6), 5),
    ("sdof_input", "sdof.m", ImportOptions(sets=SDOF_SETS), {"ode45": ref_sdof}, (1e-3, 1e-6), 5),
    ("vdp_flag", "run_vdp5.m", None, {"ode23": ref_vdp(2)}, (1e-3, 1e-6), 6),
    ("robertson_odefile", "run_chem.m", None, {"ode15s": ref_robertson}, (1e-4, [1e-6, 1e-10, 1e-6]), 5),
    ("interp_forcing", "varcoef.m", None, {"ode45": ref_varcoef}, (1e-2, 1e-4), 5),
    ("interp_datafile", "heating.m", None, {"ode45": ref_heating}, (1e-3, 1e-6), 5),
    ("nested_msd", "msd_linear.m", None, {"ode45": oscillator(2, 1.2, 18, 0.1, 0)}, (1e-6, 1e-8), 5),
    ("sir_events_nested", "run_vaccination.m", None, {"ode23s": ref_vaccination}, (1e-3, 1e-6), 6),
    ("lotka_driver", "predprey.m", None, {"ode45": ref_lotka}, (1e-3, 1e-6), 10),
    ("mu_sweep", "sweep_mu.m", None, {"ode45 k=1": ref_vdp(0.5), "ode45 k=2": ref_vdp(1), "ode45 k=3": ref_vdp(2)},
     (1e-3, 1e-6), 20),
    ("empty_options", "two_mus.m", None, {"ode45 line 3": ref_vdp(1), "ode45 line 10": ref_vdp(3)},
     (1e-3, 1e-6), 40),
    ("sol_struct", "vdp_sol.m", None, {"ode45": ref_vdp(4), "ode15s": ref_vdp(4)}, (1e-3, 1e-6), 180),
    ("anon_extras", "pend_anon.m", None, {"ode45": ref_anon}, (1e-3, 1e-6), 5),
    ("pendulum_cases", "pend_starts.m", None, {"ode45 line 3": ref_pendulum([0, 0.5]),
                                               "ode45 line 7": ref_pendulum([math.pi / 4, 0]),
                                               "ode45 line 10": ref_pendulum([math.pi / 4, 0.5])},
     (1e-3, 1e-6), 35),
    ("mass_matrix", "two_masses.m", None, {"ode23t": ref_two_masses}, (1e-5, 1e-8), 220),
    ("if_rhs", "ball_drag.m", None, {"ode45": ref_ball_drag}, (1e-6, 1e-9), 55),
    ("matrix_ay", "msd_state_space.m", None, {"ode45": ref_msd_step}, (1e-8, 1e-10), 5),
    ("tank_chain", "tanks.m", None, {"ode45": ref_tanks}, (1e-7, 1e-9), 5),
    ("string_global", "driver.m", None, {"ode23": ref_logistic}, (1e-3, 1e-6), 14),
    ("events_log", "projectile.m", None, {"ode45": ref_projectile}, (1e-8, 1e-10), 5),
    ("octave_style", "decay_octave.m", None, {"ode45": ref_decay_chain}, (1e-6, 1e-9), 5),
]


def _run(folder, driver, options):
    path = (LAB if folder == "lab" else CORPUS / folder) / driver
    return [r for exp in load_experiments(path, options=options) for r in run_experiment(exp)]


def tolerance_units(y, ref, rtol, atol):
    """The largest error in units of the tolerance at each state's scale: |y - y_ref| / (AbsTol + RelTol max|y_ref|)."""
    atol = np.broadcast_to(np.asarray(atol, dtype=float), ref.shape[1:])
    scale = np.max(np.abs(ref), axis=0)
    return float(np.max(np.abs(y - ref) / (atol + rtol * scale)))


@pytest.mark.parametrize("folder, driver, options, refs, tols, bound", CASES, ids=[c[0] for c in CASES])
def test_imported_driver_matches_an_independent_solution(folder, driver, options, refs, tols, bound):
    results = {r.case.name: r for r in _run(folder, driver, options)}
    assert sorted(results) == sorted(refs)
    for name, ref in refs.items():
        result = results[name]
        assert result.status == "success", result.message
        units = tolerance_units(result.x, ref(result.t), *tols)
        assert units < bound, f"{folder}/{name}: {units:.1f} tolerance units"


def test_the_ballode_restart_loop_bounces_at_the_closed_forms_times():
    (result,) = _run("ballode", "bounce.m", None)
    times = [e["t"] for e in result.events]
    flights = 2 * 15 * 0.8 ** np.arange(10) / 9.8  # each flight lasts 2 v_k / g, v_k = 15 (0.8)^k
    np.testing.assert_allclose(times, np.cumsum(flights), rtol=0, atol=1e-9)
    assert len(times) == 10 and result.status == "success"  # for i = 1:10: ten calls, ten bounces


def test_the_while_restart_loop_bounces_until_its_final_time():
    (result,) = _run("ballode_while", "bounce_while.m", None)
    t1 = math.sqrt(2 * 5 / 9.81)
    expected = [t1]
    while True:
        k = len(expected)
        nxt = expected[-1] + 2 * t1 * 0.7 ** k
        if nxt > 4.5:
            break
        expected.append(nxt)
    times = [e["t"] for e in result.events]
    np.testing.assert_allclose(times, expected, rtol=0, atol=1e-7)  # RelTol 1e-8 in the file
    assert result.t[-1] == 4.5


def test_events_with_several_values_locate_each_crossing():
    (result,) = _run("events_log", "projectile.m", None)
    names = [e["name"] for e in result.events]
    assert names == ["event_1", "event_1", "event_2"]  # 10 m going up, coming down, then the ground (terminal)
    g, c = 9.81, 0.05

    def f(s, y):
        v = math.hypot(y[2], y[3])
        return [y[2], y[3], -c * v * y[2], -g - c * v * y[3]]
    up = lambda s, y: y[1] - 10
    ground = lambda s, y: y[1]
    ground.terminal, ground.direction = True, -1
    sol = solve_ivp(f, (0, 10), [0, 0, 20, 25], method="DOP853", rtol=1e-12, atol=1e-14, events=[up, ground])
    expected = sorted(list(sol.t_events[0]) + list(sol.t_events[1]))
    np.testing.assert_allclose([e["t"] for e in result.events], expected, rtol=0, atol=1e-7)


def test_the_sir_run_stops_at_its_terminal_event():
    (result,) = _run("sir_events_nested", "run_vaccination.m", None)
    assert [e["name"] for e in result.events] == ["extinct"]
    assert abs(result.x[-1, 1] - 1.0) < 1e-6 * 1000  # I = 1 where the run stops (AbsTol-scale)


def test_the_function_file_with_input_needs_its_values_then_runs_with_set():
    doc = read(CORPUS / "sdof_input" / "sdof.m")
    assert [g.construct for g in doc.gaps] == ["[tsol,ysol] = ode45('sdof_rhs',[0:dt:4],y0);"]
    assert "`input` asks the user (write the value into the experiment file)" in doc.gaps[0].detail
    doc = read(CORPUS / "sdof_input" / "sdof.m", ImportOptions(sets=SDOF_SETS))
    assert not doc.gaps and doc.data["time"]["output"] == "0:0.01:4"


def test_the_data_file_becomes_a_table_input_relative_to_where_the_toml_is_written(tmp_path):
    doc = read(CORPUS / "interp_datafile" / "heating.m")
    assert doc.data["inputs"]["pdata"] == {"type": "table", "file": "power.txt", "interpolation": "linear",
                                           "extrapolation": "clip"}
    out = tmp_path / "written"
    out.mkdir()
    doc = read(CORPUS / "interp_datafile" / "heating.m", ImportOptions(output=out))
    written = out / "heating.toml"
    written.write_text(doc.text)
    (from_toml,) = run_experiment(written)
    (from_m,) = _run("interp_datafile", "heating.m", None)
    assert np.array_equal(from_toml.t, from_m.t) and np.array_equal(from_toml.x, from_m.x)
