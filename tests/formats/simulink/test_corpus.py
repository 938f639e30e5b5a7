"""The Simulink corpus (tests/assets/simulink): every model imported, run, and checked against an independent
solution (closed form, the matrix exponential, SciPy at tight tolerances) at the model's own tolerances.

The errors are measured in units of the model's tolerance: ``err / (RelTol * peak + AbsTol)``; a variable-step
solver's global error is a small multiple of its local tolerance on these smooth, short runs.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from odelab import formats
from odelab.formats.base import GAP
from odelab.run.runner import run_experiment

CORPUS = Path(__file__).resolve().parents[2] / "assets" / "simulink"
EPS = np.finfo(float).eps


def _run(name):
    (result,) = run_experiment(CORPUS / name)
    assert result.status == "success", result.message
    return result


def _out(result, name):
    return result.y[:, list(result.case.problem.outputs).index(name)]


def _units(err, exact, rtol, atol):
    """The error in units of the tolerance: max |err| / (rtol * max |exact| + atol)."""
    return float(np.max(np.abs(err)) / (rtol * np.max(np.abs(exact)) + atol))


def _step_lti(A, B, C, t, x0=None):
    """y(t) of x' = A x + B (a unit step from 0), x(0) = x0: the matrix exponential of [[A, B], [0, 0]]."""
    A, B, C = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (A, B, C))
    n = A.shape[0]
    x0 = np.zeros(n) if x0 is None else np.asarray(x0, dtype=float)
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n:] = A, B
    out = []
    for tt in np.asarray(t, dtype=float):
        E = expm(M * max(tt, 0.0))
        out.append(C @ (E[:n, :n] @ x0 + E[:n, n]))
    return np.array(out)


def _msd(t, m, b, k, t_step=1.0):
    A = [[0, 1], [-k / m, -b / m]]
    return _step_lti(A, [[0], [1 / m]], [[1, 0]], np.asarray(t) - t_step)[:, 0] * (np.asarray(t) >= t_step)


def test_msd_classic_mdl_with_its_parameter_script():
    r = _run("msd/msd.mdl")  # m, b, k from msd_params.m beside it; the Step at Simulink's default time 1
    exact = _msd(r.t, 1.0, 0.5, 4.0)
    assert _units(_out(r, "x") - exact, exact, 1e-6, 1e-8) < 5
    assert r.t[0] == 0 and r.t[-1] == 10 and np.max(np.diff(r.t)) <= 0.2 * (1 + 1e-12)  # MaxStep auto: span/50


def test_msd_as_a_masked_subsystem_in_the_newer_slx_layout():
    r = _run("msd_masked.slx")  # mask m = mass (PreLoadFcn: 2), b = b (PreLoadFcn: 0.8), k = 4
    exact = _msd(r.t, 2.0, 0.8, 4.0)
    assert _units(_out(r, "position") - exact, exact, 1e-6, 1e-8) < 5


def test_first_order_in_the_older_slx_layout_with_simulinks_defaults():
    r = _run("first_order.slx")  # RelTol 1e-3, AbsTol auto (1e-6), the Step's time 1, tau from PreLoadFcn
    exact = np.where(r.t >= 1, 1 - np.exp(-(r.t - 1) / 0.5), 0.0)
    assert _units(_out(r, "y") - exact, exact, 1e-3, 1e-6) < 2
    assert r.case.problem.method == "ode45" and r.t[-1] == 10


def test_pid_loop_text_package_mdl_against_python_control():
    import control

    r = _run("pid_loop.mdl")
    s = control.tf("s")
    pid = 4 + 2 / s + 0.5 * 100 * s / (s + 100)
    loop = control.ss(control.feedback(pid / (s * s + 3 * s + 2), 1))
    exact = _step_lti(loop.A, loop.B, loop.C, r.t)[:, 0]
    assert _units(_out(r, "y") - exact, exact, 1e-5, 1e-7) < 10


def test_a_model_without_state_is_evaluated_at_its_output_times():
    r = _run("sine_gain.slx")
    assert r.x.shape[1] == 0 and r.t.size == 51
    assert np.max(np.abs(_out(r, "y") - (np.sin(3 * r.t) + 0.5))) <= 4 * EPS * 1.5


def test_pendulum_against_scipy_at_tight_tolerances():
    from scipy.integrate import solve_ivp

    r = _run("pendulum.mdl")  # g, L, c, theta0 from InitFcn

    def rhs(t, y):
        return [y[1], -9.81 / 0.5 * math.sin(y[0]) - 0.2 * y[1]]

    ref = solve_ivp(rhs, (0, 10), [1.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-13, t_eval=r.t)
    assert _units(_out(r, "theta") - ref.y[0], ref.y[0], 1e-8, 1e-10) < 50
    assert _units(_out(r, "omega") - ref.y[1], ref.y[1], 1e-8, 1e-10) < 50


def test_saturation_limited_integrator_and_dead_zone_with_their_defaults():
    r = _run("limits.slx")
    x = np.minimum(r.t, 1.5)  # the step's 2 saturated to 1, integrated up to the limit 1.5
    assert np.max(np.abs(_out(r, "Limited") - x)) <= 1e-6 * 1.5 + 1e-9
    assert np.max(np.abs(_out(r, "Dead_Zone") - np.maximum(x - 0.5, 0))) <= 1e-6 * 1.5 + 1e-9


def test_state_space_block_with_initial_state_against_the_matrix_exponential():
    r = _run("state_space.mdl")
    exact = _step_lti([[0, 1], [-2, -3]], [[0], [1]], np.eye(2), r.t, x0=[1, 0])
    for i, name in enumerate(("x1", "x2")):
        assert _units(_out(r, name) - exact[:, i], exact[:, i], 1e-8, 1e-10) < 10


def test_discrete_blocks_and_an_inherited_sample_time():
    r = _run("discrete.slx")
    f, d = _out(r, "f"), _out(r, "d")
    for k in range(0, 31):  # the row after each hit k: y[k] = 1 - 0.9^k, the delay's y[k-1]
        i = np.flatnonzero(np.isclose(r.t, 0.1 * k, rtol=0, atol=1e-12))[-1]
        assert f[i] == pytest.approx(1 - 0.9 ** k, abs=4 * EPS)
        assert d[i] == pytest.approx(1 - 0.9 ** (k - 1) if k else 0.0, abs=4 * EPS)


def test_goto_from_bus_subsystem_mux_demux_routing():
    r = _run("routing.slx")
    assert np.max(np.abs(_out(r, "p") - 6 * r.t)) <= 4 * EPS * 12


def test_fcn_math_sqrt_abs_minmax_product():
    r = _run("fcn_math.mdl")
    t = r.t
    assert np.max(np.abs(_out(r, "f") - (t ** 2 + 0.5 * np.sin(t)))) <= 8 * EPS * 10
    assert np.max(np.abs(_out(r, "e") - np.exp(t))) <= 4 * EPS * 21
    assert np.max(np.abs(_out(r, "m") - np.maximum(np.sqrt(t), 2.0))) <= 4 * EPS * 2
    assert np.max(np.abs(_out(r, "r") - t / np.exp(t))) <= 8 * EPS


def test_lookup_table_with_simulinks_linear_extrapolation():
    from scipy.integrate import quad

    r = _run("lookup.mdl")
    bp, table = np.array([0, 1, 2, 3.0]), np.array([0, 1, 4, 9.0])

    def g(x):
        return float(np.interp(x, bp, table)) if x <= 3 else 9 + 5 * (x - 3)  # the last segment continued

    assert np.max(np.abs(_out(r, "g") - [g(x) for x in r.t])) <= 8 * EPS * 14
    area = np.array([quad(g, 0, x, points=[1, 2, 3], epsabs=1e-14)[0] for x in r.t])
    assert _units(_out(r, "area") - area, area, 1e-8, 1e-10) < 10


def test_transport_delay_runs_as_delay_equations():
    r = _run("delay.slx")
    assert r.case.problem.method == "dde23"
    exact = np.maximum(r.t - 0.5, 0)
    assert _units(_out(r, "y") - exact, exact, 1e-6, 1e-8) < 5


def test_stop_and_random_sources():
    from odelab.systems.diagram.noise import draw

    r = _run("stop_random.mdl")
    assert 2.5 <= r.t[-1] <= 2.6 + 1e-12 and "stop block `Stop`" in r.message  # MaxStep 0.1
    for k in range(6):  # the last row at each hit (0, 0.5, ... 2.5) holds that hit's number
        i = np.flatnonzero(np.abs(r.t - 0.5 * k) <= 1e-12)[-1]
        assert _out(r, "noise")[i] == 2 * draw(7, k)
    assert np.all((_out(r, "dither") >= 0) & (_out(r, "dither") < 10))
    assert np.max(np.abs(_out(r, "ramp") - r.t)) <= 64 * EPS * 3


def test_nested_masks_shadow_outer_ones_and_the_workspace():
    r = _run("masks.slx")  # workspace k = 5, outer mask k = 2, inner mask k = 3
    for name, k in (("k3", 3), ("k2", 2), ("k5", 5)):
        assert np.max(np.abs(_out(r, name) - k * r.t)) <= 4 * EPS * 10
    params = formats.read(CORPUS / "masks.slx").data["parameters"]
    assert sorted(params.values()) == [2.0, 3.0, 5.0]


def test_pulse_generator_and_derivative():
    r = _run("pulse_derivative.mdl")
    t = r.t
    charge = 3 * (np.floor(t / 2) + np.minimum(np.mod(t, 2), 1))
    assert _units(_out(r, "q") - charge, charge, 1e-8, 1e-10) < 10
    c = 1e-3  # odelab's derivative: s/(c s + 1) of sin t from rest
    dsin = (np.cos(t) + c * np.sin(t) - np.exp(-t / c)) / (1 + c * c)
    # y = (u - z)/c: the solver's tolerance on z (the size of u) reaches y divided by c
    assert np.max(np.abs(_out(r, "dsin") - dsin)) / ((1e-8 * 1 + 1e-10) / c) < 1


def test_fixed_step_ode4_is_rk4():
    r = _run("fixed_step.slx")
    assert r.case.problem.method == "rk4" and np.allclose(np.diff(r.t), 0.01, rtol=0, atol=1e-12)
    exact = 0.5 * (1 - np.exp(-2 * r.t))
    assert np.max(np.abs(_out(r, "x_out") - exact)) < 1e-9  # rk4's global error, O(h^4) = 1e-8 at most


def test_relay_and_switch():
    r = _run("switching.mdl")
    t = r.t
    relay = _out(r, "relay")
    assert np.all(relay[t < 2 - 1e-9] == -1) and np.all(relay[t > 2 + 1e-9] == 5)  # switched at t = 2 (located)
    switch = _out(r, "switch")
    assert np.all(switch[t > 3 + 1e-9] == 10) and np.all(switch[t < 3 - 1e-9] == -10)


# --- the import table: what each model imports as (docs/tutorials/coming-from-matlab.md) ------------------

#: model -> (exit code of `odelab import`, translated, ignored, gaps); 2: refused with one message
TABLE = {
    "delay.slx": (0, 5, 0, 0), "discrete.slx": (0, 5, 0, 0), "fcn_math.mdl": (0, 9, 0, 0),
    "first_order.slx": (0, 3, 0, 0), "fixed_step.slx": (0, 5, 0, 0), "limits.slx": (0, 5, 0, 0),
    "lookup.mdl": (0, 4, 0, 0), "masks.slx": (0, 14, 0, 0), "msd/msd.mdl": (0, 9, 0, 0),
    "msd_masked.slx": (0, 11, 0, 0), "pendulum.mdl": (0, 7, 0, 0), "physical.slx": (2, 0, 0, 0),
    "pid_loop.mdl": (0, 5, 0, 0), "pulse_derivative.mdl": (0, 5, 0, 0), "routing.slx": (0, 13, 1, 0),
    "sine_gain.slx": (0, 4, 0, 0), "state_space.mdl": (0, 4, 0, 0), "stop_random.mdl": (0, 8, 0, 0),
    "switching.mdl": (0, 6, 0, 0), "with_gaps.slx": (1, 3, 0, 2),
}


@pytest.mark.parametrize("name", sorted(TABLE))
def test_the_import_table(name):
    from odelab.exceptions import ExperimentError

    code, translated, ignored, gaps = TABLE[name]
    if code == 2:
        with pytest.raises(ExperimentError):
            formats.read(CORPUS / name)
        return
    doc = formats.read(CORPUS / name)
    outcomes = [n.outcome for n in doc.notes]
    assert (outcomes.count("translated"), outcomes.count("ignored"), outcomes.count(GAP)) == (translated, ignored, gaps)
    assert (1 if doc.gaps else 0) == code


def test_the_corpus_holds_fifteen_models_in_every_format():
    models = [p for p in CORPUS.rglob("*") if p.suffix in (".slx", ".mdl")]
    assert len(models) >= 15
    heads = " ".join(formats.read(p).text.splitlines()[0] for p in models if p.name != "physical.slx")
    for layout in ("(mdl)", "(mdl (text package) (systems/system_*.xml))", "(slx (systems/system_*.xml))",
                   "(slx (blockdiagram.xml))"):
        assert layout in heads


def test_running_the_written_toml_gives_the_same_bits(tmp_path):
    for name in ("msd_masked.slx", "discrete.slx", "pid_loop.mdl"):
        doc = formats.read(CORPUS / name)
        written = tmp_path / (Path(name).stem + ".toml")
        written.write_text(doc.text)
        (a,) = run_experiment(CORPUS / name)
        (b,) = run_experiment(written)
        assert np.array_equal(a.t, b.t) and np.array_equal(a.x, b.x) and np.array_equal(a.y, b.y)
