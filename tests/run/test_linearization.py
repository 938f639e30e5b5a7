"""The lab's linearisation comparison from experiments/linearisation.toml."""

from pathlib import Path

import numpy as np
import pytest

from odelab.exceptions import InputError
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case, run_experiment

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def results():
    return {r.case.name: r for r in run_experiment(ROOT / "experiments" / "linearisation.toml")}


def test_about_zero_the_linear_model_is_exercise2s_plant(results):
    info = results["about-0"].extra["linearization"]
    np.testing.assert_allclose(info["A"], [[0, 1], [-3, -4]], atol=1e-15)
    np.testing.assert_allclose(info["B"], [[0], [1]], atol=1e-15)
    np.testing.assert_allclose(info["C"], [[10, 0]], atol=1e-15)
    assert info["operating_point"]["x"] == {"x": 0.0, "v": 0.0}


def test_nonzero_operating_point(results):
    info = results["about-f1"].extra["linearization"]
    xbar = info["operating_point"]["x"]["x"]
    assert abs(3 * xbar + 2 * xbar**3 - 1) < 1e-14  # k1 x + k3 x^3 = f
    assert info["A"][1][0] == pytest.approx(-(3 + 3 * 2 * xbar**2), rel=1e-13)  # tangent stiffness
    assert info["operating_point"]["residual"] < 1e-12


def test_error_shrinks_at_the_expected_rate(results):
    for case, rate in (("about-0", 2.0), ("about-f1", 1.0)):
        info = results[case].extra["linearization"]
        a = np.array(info["amplitudes"])
        e = np.array(info["errors"]["y"])
        small = a <= 0.2
        slope = np.polyfit(np.log(a[small]), np.log(e[small]), 1)[0]
        assert abs(slope - rate) < 0.2, (case, slope)


def test_largest_amplitude_within_the_threshold(results):
    assert results["about-0"].extra["linearization"]["max_amplitude_within"] == 0.5
    assert results["about-f1"].extra["linearization"]["max_amplitude_within"] == 0.2
    for r in results.values():
        e = r.extra["linearization"]["errors"]["y"]
        assert all(np.diff(e) > 0)  # a bigger step, a worse linear model


def test_comparison_is_the_error_table(results):
    r = results["about-0"]
    assert r.reference_kind == "linearization"
    # y(t) of the nonlinear model minus the linear one, on the same times, x̄ added back
    np.testing.assert_allclose(r.reference["y"] + (r.y[:, 0] - r.reference["y"]), r.y[:, 0])
    assert 0.1 < r.errors["y"].max_abs < 0.3  # a unit step is well past the 5 % threshold here
    assert np.all(r.y[r.t < 1, 0] == 0)  # at rest at x̄ = 0 until the step at t = 1


def test_no_equilibrium_is_a_clear_error(tmp_path):
    path = tmp_path / "noeq.toml"
    path.write_text('[system]\nstates = ["x"]\ninputs = ["u"]\n[system.equations]\nx = "1 + x^2 + u^2"\n'
                    '[initial]\nx = 0\n[inputs.u]\ntype = "constant"\nvalue = 0\n[time]\nstop = 1\n'
                    '[linearize]\ninput = { u = 0 }\n')
    case = load_experiment(path).cases[0]
    with pytest.raises(InputError, match="no equilibrium found"):
        run_case(case)


def test_linearize_keys_are_checked_when_loading(tmp_path):
    text = (ROOT / "experiments" / "linearisation.toml").read_text()
    path = tmp_path / "bad.toml"
    path.write_text(text.replace('quantity = "y"', 'quantity = "z"'))
    with pytest.raises(InputError, match=r"`linearize.quantity` is 'z', not a state or output \(x, v, y\)"):
        load_experiment(path)


def test_a_linearised_network_keeps_its_drawing_and_derivation():
    # a [linearize] case runs apart from the others (run/linearization.py); its network's drawing and
    # derivation were missing from its result, so the report drew no network for it
    exp = load_experiment(ROOT / "experiments" / "networks" / "network_nonlinear_spring.toml")
    result = run_case(exp.cases[0])
    assert "linearization" in result.extra
    network = result.extra["network"]
    for element in exp.cases[0].problem.system.network.elements:
        assert element in network["dot"], element
    assert network["sections"] and not network["linear"]


def test_a_system_without_inputs_is_linearised_and_compared(tmp_path):
    """A pendulum with no inputs: linearised about its rest point and the free responses from [initial]
    compared (the run failed with "`u` must be None; got []" before: the inputs were an empty list)."""
    path = tmp_path / "pendulum.toml"
    path.write_text('[system]\nstates = ["th", "w"]\n[system.equations]\nth = "w"\nw = "-9.81*sin(th) - 0.1*w"\n'
                    '[time]\nstop = 2\n[initial]\nth = 0.01\nw = 0\n[linearize]\nstart = "initial"\n')
    (result,) = run_experiment(path)
    assert result.status == "success", result.message
    info = result.extra["linearization"]
    np.testing.assert_allclose(info["A"], [[0, 1], [-9.81, -0.1]], rtol=0, atol=1e-15)
    assert info["B"] == [[], []] and info["operating_point"]["x"] == {"th": 0.0, "w": 0.0}
    # from th = 0.01 rad the two models differ by the cubic term, th^3/6 against th, a relative 1.7e-5 of the
    # swing, and by their solves' errors (ode45 at RelTol 1e-3 each): within 1e-3 of the 0.01 rad peak
    assert result.errors["th"].max_abs < 1e-3 * 0.01
    assert result.errors["th"].scale == pytest.approx(0.01, rel=1e-12)
