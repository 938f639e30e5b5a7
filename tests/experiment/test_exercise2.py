"""Exercise 2 end to end: a state-space experiment with step, sine and ramp inputs."""

from pathlib import Path

import numpy as np
import pytest

from odelab.exceptions import InputError
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case, run_experiment

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def results():
    return {r.case.name: r for r in run_experiment(ROOT / "experiments" / "exercise2.toml")}


def test_every_input_and_solver_has_y_errors_against_the_exact_response(results):
    assert {"step-ode45", "step-ode23", "sine-ode45", "sine-ode23", "ramp-ode45", "ramp-ode23", "step-rk4"} <= set(results)
    for name, r in results.items():
        assert r.status == "success" and r.reference_kind == "lti", name
        assert set(r.errors) == {"x", "v", "y"}
        assert r.y.shape == (r.t.size, 1) and r.u.shape == (r.t.size, 1)


def test_exact_step_response_is_the_closed_form(results):
    r = results["step-ode45"]
    t = r.t
    closed = 10 * (1 / 3 - np.exp(-t) / 2 + np.exp(-3 * t) / 6)  # y = q x for a unit step
    np.testing.assert_allclose(r.reference["y"], closed, rtol=0, atol=1e-13)
    # ode45 at rtol 1e-3: the error in y stays below one tolerance unit of its size (y <= 10/3).
    assert r.errors["y"].max_abs < 1e-3 * 10 / 3
    assert r.stats.nsteps == 22


def test_ode45_beats_ode23_and_rk4_is_fourth_order_accurate(results):
    for kind in ("step", "sine", "ramp"):
        assert results[f"{kind}-ode45"].errors["y"].max_abs < results[f"{kind}-ode23"].errors["y"].max_abs
    assert results["step-rk4"].errors["y"].max_abs < 1e-5  # h = 0.05: error ~ h^4


def test_inputs_are_stored_beside_states_and_outputs(results):
    r = results["ramp-ode45"]
    np.testing.assert_allclose(r.u[:, 0], r.t)  # u = t
    np.testing.assert_allclose(r.y[:, 0], 10 * r.x[:, 0])


def test_a_step_at_t1_is_not_smeared(tmp_path):
    text = (ROOT / "experiments" / "exercise2.toml").read_text().split("[[case]]")[0]
    path = tmp_path / "late.toml"
    path.write_text(text + '[inputs.f]\ntype = "step"\ntime = 1\n')
    r = run_case(load_experiment(path).cases[0])
    before = r.t < 1
    assert np.all(r.y[before, 0] == 0)  # nothing moves before the step
    assert r.errors["y"].max_abs < 1e-3 * 10 / 3


@pytest.mark.parametrize(
    "change, message",
    [
        (("B = [[0], [\"1/m\"]]", "B = [[0, 1], [1, 0]]"), "`system.B` is 2x2 but A is 2x2 and there is 1 input: B must be 2x1"),
        (("C = [[\"q\", 0]]", "C = [[\"q\", 0, 0]]"), "`system.C` is 1x3"),
        (("A = [[0, 1], [\"-k/m\", \"-b/m\"]]", "A = [[0, 1], [\"-k/m\"]]"), "`system.A` has rows of different lengths"),
        (("type = \"step\", time = 0", "type = \"step\", slope = 2, time = 0"), "`inputs.f.slope` does not apply to a step input"),
        (("name = \"step-ode45\"\n", "name = \"step-ode45\"\ninputs.g = { type = \"step\" }\n"), "`inputs.g`: 'g' is not an input of the system (f)"),
    ],
)
def test_state_space_errors(tmp_path, change, message):
    text = (ROOT / "experiments" / "exercise2.toml").read_text()
    assert change[0] in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(change[0], change[1], 1))
    with pytest.raises(InputError) as info:
        load_experiment(path)
    assert message in str(info.value)
