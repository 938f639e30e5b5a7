"""The lab's networks against their hand-written twins in experiments/: the same matrices entry
for entry and the same trajectories to round-off."""

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("sympy")  # a dependency of odelab; a venv made before it was added lacks it

from odelab.experiment.loader import load_experiment  # noqa: E402
from odelab.run.runner import run_case  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
EXPERIMENTS = ROOT / "experiments"
NETWORKS = EXPERIMENTS / "networks"


def test_msd_network_has_exercise2s_states_and_matrices_entry_for_entry():
    net = load_experiment(NETWORKS / "network_msd.toml").cases[0].problem
    ex2 = load_experiment(EXPERIMENTS / "exercise2.toml").cases[0].problem
    assert net.states == ("mass.x", "mass.v") and net.inputs == ("f",) and net.outputs == ("y",)
    assert type(net.system.model).__name__ == "StateSpace" and net.reference == "lti"
    for name in "ABCD":
        np.testing.assert_array_equal(getattr(net.system.model, name), getattr(ex2.system.model, name))
    eq = net.system.network.equations()
    assert eq == {"mass.x": "mass.v", "mass.v": "(f - b*mass.v - k*mass.x)/m"}


@pytest.mark.parametrize("case", ["step-ode45", "step-ode23", "sine-ode45", "sine-ode23", "ramp-ode45",
                                  "ramp-ode23", "step-rk4"])
def test_msd_network_runs_equal_exercise2s_to_round_off(case):
    a = run_case({c.name: c for c in load_experiment(NETWORKS / "network_msd.toml").cases}[case])
    b = run_case({c.name: c for c in load_experiment(EXPERIMENTS / "exercise2.toml").cases}[case])
    assert a.status == b.status == "success"
    assert a.stats == b.stats and np.array_equal(a.t, b.t)
    eps = np.finfo(float).eps
    assert np.max(np.abs(a.x - b.x)) <= 4 * eps * np.max(np.abs(b.x))
    assert np.max(np.abs(a.y - b.y)) <= 4 * eps * np.max(np.abs(b.y))
    assert a.errors["y"].max_abs == pytest.approx(b.errors["y"].max_abs, rel=1e-9)


def _renamed(value, names):
    """The reference's results with its state names as the network's (in tables keyed by state)."""
    if isinstance(value, dict):
        by_state = set(names) <= set(value)
        return {(names.get(k, k) if by_state else k): _renamed(v, names) for k, v in value.items()}
    if isinstance(value, list):
        return [_renamed(v, names) for v in value]
    return value


def _assert_close(a, b, path="linearization"):
    if isinstance(b, dict):
        assert set(a) == set(b), path
        for k in b:
            _assert_close(a[k], b[k], f"{path}.{k}")
    elif isinstance(b, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _assert_close(x, y, f"{path}[{i}]")
    elif isinstance(b, float):
        assert abs(a - b) <= 8 * np.finfo(float).eps * max(1.0, abs(b)), (path, a, b)
    else:
        assert a == b, path


@pytest.mark.parametrize("case", ["about-0", "about-f1"])
def test_nonlinear_spring_network_linearises_as_linearisation_toml(case):
    net = {c.name: c for c in load_experiment(NETWORKS / "network_nonlinear_spring.toml").cases}[case]
    ref = {c.name: c for c in load_experiment(EXPERIMENTS / "linearisation.toml").cases}[case]
    assert net.problem.system.network.equations()["mass.v"] == "(f - b*mass.v - k1*mass.x - k3*mass.x^3)/m"
    a, b = run_case(net), run_case(ref)
    assert a.status == b.status == "success" and a.stats == b.stats and np.array_equal(a.t, b.t)
    assert np.max(np.abs(a.x - b.x)) <= 8 * np.finfo(float).eps * np.max(np.abs(b.x))
    names = {"x": "mass.x", "v": "mass.v"}
    la = a.extra["linearization"]
    lb = _renamed(b.extra["linearization"], names)
    lb["states"] = [names[s] for s in b.extra["linearization"]["states"]]
    _assert_close(la, lb)
    k = 3 + 3 * 2 * la["operating_point"]["x"]["mass.x"] ** 2  # the tangent stiffness k1 + 3 k3 x^2
    assert la["A"][1][0] == pytest.approx(-k, rel=1e-12)


SHIPPED = ["network_msd", "network_nonlinear_spring", "network_rlc", "network_dc_motor", "network_quarter_car",
           "network_thermal", "network_tanks"]


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_network_runs(name):
    exp = load_experiment(NETWORKS / f"{name}.toml")
    for case in exp.cases[:2]:
        r = run_case(case)
        assert r.status == "success", r.message
        assert np.all(np.isfinite(r.x))


def test_the_quarter_car_climbs_a_5_cm_bump():
    # its comment says a 5 cm bump climbed in 0.1 s: a pulse's width is a fraction of its period (as Simulink's
    # percentage), so 0.1 s of a 100 s period is 0.001 (until 2026-12 the file said 0.1: a 10 s climb at 0.5 m/s
    # and a body 1.25 m up at t = 3)
    case = load_experiment(NETWORKS / "network_quarter_car.toml").cases[0]
    u = case.problem.system.input_fn
    t = np.linspace(0, 3, 300_001)
    vr = u(t)[:, 0]
    assert vr.max() == 0.5 and np.count_nonzero(vr) * (t[1] - t[0]) == pytest.approx(0.1, abs=2e-5)
    r = run_case(case)
    outputs = list(case.problem.outputs)
    body, travel = r.y[:, outputs.index("body")], r.y[:, outputs.index("travel")]
    # the suspension (damping ratio bs / (2 sqrt(ks ms)) = 0.25) overshoots, then settles on the road's 5 cm
    assert 0.07 < body.max() < 0.08 and body[-1] == pytest.approx(0.05, rel=0.03)
    assert abs(travel[-1]) < 0.002


def test_the_dc_motor_is_stiff_as_its_file_says():
    # "the electrical time constant is far shorter than the mechanical one" (why the file asks for ode15s):
    # La/Ra = 0.5 ms against about 80 ms (until 2026-12 the file said La = 0.5 H: 500 ms, and poles -1.05 +- 4.9j)
    model = load_experiment(NETWORKS / "network_dc_motor.toml").cases[0].problem.system.model
    poles = np.linalg.eigvals(np.asarray(model.A, dtype=float))
    moving = np.sort(np.abs(poles[np.abs(poles) > 1e-9]))  # the rotor's angle: a pole at 0
    assert np.all(poles.imag == 0) and moving[-1] / moving[0] > 100
    assert moving == pytest.approx([12.68, 1987.3], rel=1e-3)


def test_the_python_api_gives_the_system_the_toml_gives():
    from odelab.network import Damper, ForceSource, Mass, Network, Spring

    toml = load_experiment(NETWORKS / "network_msd.toml").cases[0].problem.system.model
    net = Network({"mass": Mass(node="p", m="m"), "spring": Spring(nodes=["p", "ground"], k="k"),
                   "damper": Damper(nodes=["p", "ground"], b="b"),
                   "push": ForceSource(nodes=["p", "ground"], value="f")},
                  outputs={"y": "q*mass.x"}, parameters={"m": 1, "k": 3, "b": 4, "q": 10})
    sys = net.compile()
    assert type(sys) is type(toml) and sys.states == toml.states and sys.inputs == toml.inputs
    for name in "ABCD":
        np.testing.assert_array_equal(getattr(sys, name), getattr(toml, name))


def test_tanks_network_is_nonlinear_and_keeps_the_orifice_law():
    p = load_experiment(NETWORKS / "network_tanks.toml").cases[0].problem
    assert type(p.system.model).__name__ == "NonlinearSystem" and p.states == ("tank1.p", "tank2.p")
    eq = p.system.network.equations()
    assert "sqrt(abs(tank1.p - tank2.p))*sign(tank1.p - tank2.p)" in eq["tank1.p"]
    r = run_case(load_experiment(NETWORKS / "network_tanks.toml").cases[0])
    # the steady state: all of the pump's flow leaves through the outlet, q = p2/Rout, and the
    # orifice carries it: q = cd sqrt(p1 - p2)
    qin, Rout, cd = 0.005, 2e6, 2e-4
    p2 = qin * Rout
    p1 = p2 + (qin / cd) ** 2
    assert r.x[-1, 1] == pytest.approx(p2, rel=0.02) and r.x[-1, 0] == pytest.approx(p1, rel=0.02)
