"""[analysis] in experiment files: Exercise 2's plant and the PI loop with a saturating actuator."""

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case

ROOT = Path(__file__).resolve().parents[2]
EXERCISE2 = ROOT / "experiments" / "exercise2.toml"
FEEDBACK = ROOT / "experiments" / "feedback_pi.toml"


def test_exercise2_ships_with_analysis_and_json_carries_it(tmp_path):
    result = CliRunner().invoke(app, ["run", str(EXERCISE2), "--runs", str(tmp_path), "--json"])
    assert result.exit_code == 0, result.output
    cases = json.loads(result.output)["experiments"][0]["cases"]
    info = cases[0]["extra"]["analysis"]
    assert info["transfer_functions"][0]["text"] == ["10", "s^2 + 4 s + 3"]
    assert [(p["re"], p["wn"], p["zeta"]) for p in info["poles"]] == [(-1.0, 1.0, 1.0), (-3.0, 3.0, 1.0)]
    s = info["step_info"][0]
    assert (s["output"], s["input"]) == ("y", "f")
    assert s["RiseTime"] == pytest.approx(2.390892, abs=1e-6) and s["SettlingTime"] == pytest.approx(4.317429, abs=1e-6)
    assert s["Overshoot"] == 0 and s["PeakTime"] is None  # inf in strict JSON is null
    assert len(info["bode"]["w"]) == 200 and info["bode"]["w"][0] == 0.01
    assert info["margins"][0]["phase_margin"] == pytest.approx(73.9168, abs=1e-4)
    stored = json.loads((tmp_path / "exercise2" / "step-ode45" / "result.json").read_text())
    assert stored["extra"]["analysis"]["step_info"] == cases[0]["extra"]["analysis"]["step_info"]
    assert all(c["extra"]["analysis"]["A"] == info["A"] for c in cases)


def test_run_prints_the_analysis_once(tmp_path):
    text = EXERCISE2.read_text()
    path = tmp_path / "ex2.toml"
    path.write_text("[[case]]".join(text.split("[[case]]")[:3]))  # the base and its first two cases
    result = CliRunner().invoke(app, ["run", str(path), "--no-store"])
    assert result.exit_code == 0, result.output
    assert "step-ode23" in result.output  # two cases, one analysis
    assert result.output.count("G(s) = (10) / (s^2 + 4 s + 3), DC gain 3.33333") == 1
    assert "phase margin 73.92 deg at 2.402 rad/s" in result.output


def test_pi_loop_linear_model_matches_the_closed_loop_formula():
    import control

    cases = {c.name: c for c in load_experiment(FEEDBACK).cases}
    r = run_case(cases["step-3-saturating"])
    info = r.extra["analysis"]
    assert info["operating_point"]["x"] == {"PI": 0.0, "plant.x": 0.0, "plant.v": 0.0}
    Kp, Ki, q = 2.0, 1.5, 10.0
    G = control.tf([q], [1, 4, 3])
    C = control.tf([Kp, Ki], [1, 0])
    T = control.minreal(control.feedback(C * G, 1), verbose=False)  # q (Kp s + Ki) / (s^3 + 4s^2 + (3 + q Kp) s + q Ki)
    y = next(g for g in info["transfer_functions"] if g["output"] == "y")
    np.testing.assert_allclose(y["num"], np.asarray(T.num[0][0]).ravel(), rtol=1e-12)
    np.testing.assert_allclose(y["den"], np.asarray(T.den[0][0]).ravel(), rtol=1e-12)
    np.testing.assert_allclose(y["den"], [1, 4, 3 + q * Kp, q * Ki], rtol=1e-13)
    assert y["dc_gain"] == pytest.approx(1.0, rel=1e-13)  # integral action: no steady-state error
    # The loop opened at the actuator's input is L = C G, with its margins.
    loop = info["loop"]
    L = control.minreal(C * G, verbose=False)
    np.testing.assert_allclose(loop["num"], np.asarray(L.num[0][0]).ravel(), rtol=1e-12)
    np.testing.assert_allclose(loop["den"], np.asarray(L.den[0][0]).ravel(), rtol=1e-12, atol=1e-12)
    gm, pm, _, _, wcp, _ = control.stability_margins(L)
    assert loop["phase_margin"] == pytest.approx(pm, rel=1e-9) and loop["gain_crossover"] == pytest.approx(wcp)
    assert loop["gain_margin"] == float("inf")  # the phase only tends to -180 degrees
    # The saturating run: the actuator sits at its limit at first, and the loop still settles at r.
    u = r.series()["u"]
    assert u.max() == 5.0 and r.series()["y"][-1] == pytest.approx(3.0, rel=2e-3)


def test_pi_loop_inside_the_limits_equals_its_linear_model():
    from odelab.analysis.linearize import linearize
    from odelab.analysis.lti import lti_response
    from odelab.signals import Step

    case = {c.name: c for c in load_experiment(FEEDBACK).cases}["small-step"]
    r = run_case(case)
    assert np.max(np.abs(r.series()["u"])) < 5  # never saturates
    lin = linearize(case.problem.system.model, u0=[0.0])
    _, y = lti_response(lin, r.t, np.zeros(3), u=[Step(time=0, final=0.5)])
    err = np.abs(r.series()["y"] - y[:, 0])
    assert err.max() <= 10 * (1e-6 * np.abs(y[:, 0]).max() + 1e-9) * 10  # rtol 1e-6, atol 1e-9 (x q)
