"""The lab's networks against their hand-written twins in experiments/: the same matrices entry
for entry and the same trajectories to round-off."""

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("sympy")  # a dependency of odelab; a venv made before it was added lacks it

from odelab.experiment.loader import load_experiment  # noqa: E402
from odelab.experiment.runner import run_case  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
EXPERIMENTS = ROOT / "experiments"


def test_msd_network_has_exercise2s_states_and_matrices_entry_for_entry():
    net = load_experiment(EXPERIMENTS / "network_msd.toml").cases[0].problem
    ex2 = load_experiment(EXPERIMENTS / "exercise2.toml").cases[0].problem
    assert net.states == ("mass.x", "mass.v") and net.inputs == ("f",) and net.outputs == ("y",)
    assert type(net.system).__name__ == "StateSpace" and net.reference == "lti"
    for name in "ABCD":
        np.testing.assert_array_equal(getattr(net.system, name), getattr(ex2.system, name))
    eq = net.network.equations()
    assert eq == {"mass.x": "mass.v", "mass.v": "(f - b*mass.v - k*mass.x)/m"}


@pytest.mark.parametrize("case", ["step-ode45", "step-ode23", "sine-ode45", "ramp-ode23", "step-rk4"])
def test_msd_network_runs_equal_exercise2s_to_round_off(case):
    a = run_case({c.name: c for c in load_experiment(EXPERIMENTS / "network_msd.toml").cases}[case])
    b = run_case({c.name: c for c in load_experiment(EXPERIMENTS / "exercise2.toml").cases}[case])
    assert a.status == b.status == "success"
    assert a.stats == b.stats and np.array_equal(a.t, b.t)
    eps = np.finfo(float).eps
    assert np.max(np.abs(a.x - b.x)) <= 4 * eps * np.max(np.abs(b.x))
    assert np.max(np.abs(a.y - b.y)) <= 4 * eps * np.max(np.abs(b.y))
    assert a.errors["y"].max_abs == pytest.approx(b.errors["y"].max_abs, rel=1e-9)
