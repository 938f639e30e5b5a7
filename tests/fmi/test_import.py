"""FMUs as odelab systems (kind = "fmu"): Model Exchange stepped by odelab's ode45 gives the
models' exact answers and what FMPy's own simulation gives; an exported FMU comes back as the
experiment it was; loading native code needs the user's word."""

from __future__ import annotations

import math

import numpy as np
import pytest

from .conftest import ROOT

fmpy = pytest.importorskip("fmpy")

RTOL, ATOL = 1e-8, 1e-10


def run_toml(tmp_path, text: str, name: str = "case.toml", allow: bool = True):
    from odelab.fmi import allow_native
    from odelab.run.runner import run_experiment

    path = tmp_path / name
    path.write_text(text)
    with allow_native(allow):
        return run_experiment(path)


def fmu_toml(fmu, stop, extra: str = "") -> str:
    return (f'[system]\nkind = "fmu"\nfile = "{fmu}"\n[time]\nstop = {stop}\n'
            f"[solver]\nmethod = \"ode45\"\nrtol = {RTOL}\natol = {ATOL}\n{extra}")


def fmpy_me(fmu, stop, **kwargs):
    return fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-12,
                             stop_time=stop, output_interval=stop / 1000, **kwargs)


def test_dahlquist_is_the_exponential(test_fmus, tmp_path):
    (r,) = run_toml(tmp_path, fmu_toml(test_fmus["Dahlquist"], 10, '[exact]\nx = "exp(-t)"\n')
                    .replace("stop = 10", "stop = 10\npoints = 1001"))
    assert r.status == "success" and r.case.problem.states == ("x",)
    err = np.abs(r.x[:, 0] - np.exp(-r.t))
    assert np.max(err / (RTOL * np.abs(np.exp(-r.t)) + ATOL)) < 10  # within the tolerance
    assert r.errors["x"].max_abs < 1e-8  # [exact] applies: the error table is the exponential's
    theirs = fmpy_me(test_fmus["Dahlquist"], 10)
    assert np.array_equal(r.t, theirs["time"])
    assert np.max(np.abs(r.x[:, 0] - theirs["x"])) < 1e-7


def bounce_times(g=9.81, e=0.7, h0=1.0, v_min=0.1):
    """The closed form: the fall, then flights of 2 v_k / g with v_k = e^k sqrt(2 g h0), until v_k < v_min."""
    v = math.sqrt(2 * g * h0)
    times = [math.sqrt(2 * h0 / g)]
    while e * v >= v_min:
        v *= e
        times.append(times[-1] + 2 * v / g)
    return np.array(times)


def test_the_bouncing_ball_bounces_at_the_closed_forms_times(test_fmus, tmp_path):
    (r,) = run_toml(tmp_path, fmu_toml(test_fmus["BouncingBall"], 3))
    assert r.status == "success"
    exact = bounce_times()
    events = np.array([e["t"] for e in r.events])
    assert len(events) == len(exact)  # after the last, too slow, bounce the ball rests on the floor
    assert np.max(np.abs(events - exact)) < 100 * RTOL  # in units of the tolerance
    assert r.events[0]["reset"]["v"] == pytest.approx(0.7 * math.sqrt(2 * 9.81), rel=1e-6)
    assert np.max(np.abs(r.x[r.t > events[-1] + 1e-9, 0])) == 0.0  # at rest on the floor
    theirs = fmpy_me(test_fmus["BouncingBall"], 3, output=["h", "v"])
    t = theirs["time"]
    their_bounces = t[1:][np.diff(t) == 0]  # FMPy repeats the time of each event
    assert np.max(np.abs(their_bounces[: len(exact)] - events[: len(exact)])) < 1e-6


def test_a_parameter_of_the_fmu_from_parameters(test_fmus, tmp_path):
    (r,) = run_toml(tmp_path, fmu_toml(test_fmus["BouncingBall"], 3, "[parameters]\ne = 0.5\n"))
    exact = bounce_times(e=0.5)
    events = np.array([e["t"] for e in r.events])
    assert np.max(np.abs(events[: len(exact)] - exact)) < 100 * RTOL


def test_van_der_pol_equals_fmpys_cvode(test_fmus, tmp_path):
    (r,) = run_toml(tmp_path, fmu_toml(test_fmus["VanDerPol"], 20).replace("stop = 20", "stop = 20\npoints = 1001"))
    theirs = fmpy_me(test_fmus["VanDerPol"], 20, output=["x0", "x1"])
    assert np.array_equal(r.t, theirs["time"])
    for i, name in enumerate(("x0", "x1")):  # ode45 at 1e-8 against CVode at 1e-12
        assert np.max(np.abs(r.x[:, i] - theirs[name])) / np.max(np.abs(theirs[name])) < 1e-6


def test_stair_counts_the_seconds_by_time_events(test_fmus, tmp_path):
    (r,) = run_toml(tmp_path, fmu_toml(test_fmus["Stair"], 10))
    assert r.case.problem.states == () and r.case.problem.outputs == ("counter",)
    assert [e["t"] for e in r.events] == [float(k) for k in range(1, 11)]
    before = r.t < 10
    assert np.array_equal(r.y[before, 0][np.diff(np.r_[r.t[before], 10]) > 0],
                          1 + np.floor(r.t[before][np.diff(np.r_[r.t[before], 10]) > 0]))


def test_feedthrough_passes_its_inputs(test_fmus, tmp_path):
    extra = ('[parameters]\ngain = 3\n[inputs.real_in]\ntype = "sine"\nfrequency = 2\n'
             '[inputs.int_in]\ntype = "step"\ntime = 1\nfinal = 4\n')
    (r,) = run_toml(tmp_path, fmu_toml(test_fmus["Feedthrough"], 2, extra))
    p = r.case.problem
    assert p.inputs == ("real_in", "int_in")
    y = dict(zip(p.outputs, r.y.T))
    assert np.allclose(y["real_out"], np.sin(2 * r.t), rtol=0, atol=1e-15)
    assert np.allclose(y["scaled_out"], 3 * np.sin(2 * r.t), rtol=0, atol=1e-14)
    assert np.array_equal(y["int_out"], np.where(r.t >= 1, 4.0, 0.0))
    assert np.array_equal(y["bool_out"], np.zeros_like(r.t))


def test_loading_an_fmu_needs_the_users_word(test_fmus, tmp_path):
    from odelab.exceptions import ExperimentError

    with pytest.raises(ExperimentError) as info:
        run_toml(tmp_path, fmu_toml(test_fmus["Dahlquist"], 1), allow=False)
    assert info.value.message == (
        "Dahlquist.fmu is an FMU: simulating it runs the machine code inside it, with your permissions, as any "
        "program you start. Run it only if you trust where it came from, and then say so: `odelab run "
        "--allow-native` (Python: allow_native=True).")
    assert info.value.key == "system.file"


def test_the_cli_refuses_without_allow_native_and_runs_with_it(test_fmus, tmp_path):
    from typer.testing import CliRunner

    from odelab.cli.app import app

    path = tmp_path / "d.toml"
    path.write_text(fmu_toml(test_fmus["Dahlquist"], 1))
    runner = CliRunner()
    refused = runner.invoke(app, ["run", "--no-store", str(path)])
    assert refused.exit_code == 2
    assert "`system.file`: Dahlquist.fmu is an FMU: simulating it runs the machine code" in refused.output
    assert "Traceback" not in refused.output
    allowed = runner.invoke(app, ["run", "--no-store", "--allow-native", str(path)])
    assert allowed.exit_code == 0, allowed.output


def test_unknown_parameter_or_input_names_the_fmus_own(test_fmus, tmp_path):
    from odelab.exceptions import ExperimentError

    with pytest.raises(ExperimentError) as info:
        run_toml(tmp_path, fmu_toml(test_fmus["BouncingBall"], 1, "[parameters]\nee = 0.5\n"))
    assert info.value.message == ("`parameters.ee`: BouncingBall.fmu has no parameter 'ee' (its parameters: g, e, "
                                  "v_min). Did you mean `e`?")
    with pytest.raises(ExperimentError) as info:
        run_toml(tmp_path, fmu_toml(test_fmus["Feedthrough"], 1, '[inputs.real]\ntype = "sine"\n'))
    assert info.value.key == "inputs.real"


# --- the round trip: an exported odelab FMU loaded back ---------------------------------------

def test_an_exported_fmu_comes_back_as_its_experiment(exported, tmp_path):
    from .test_export import odelab_tight

    done, case = exported["network_nonlinear_spring"]
    for interface in ("model-exchange", "co-simulation"):
        (r,) = run_toml(tmp_path, fmu_toml(done.path, 10, f'[system]\n' if False else "")
                        .replace('kind = "fmu"', f'kind = "fmu"\ninterface = "{interface}"'))
        assert r.status == "success"
        assert r.case.problem.states == ("mass.x", "mass.v") and r.case.problem.outputs == ("y",)
        after = np.r_[np.diff(r.t) > 0, True]  # the row after the input's jump at t = 1
        ref = odelab_tight(case, r.t[after])
        scale = RTOL * np.max(np.abs(ref["mass.x"])) + ATOL
        assert np.max(np.abs(r.x[after, 0] - ref["mass.x"])) / scale < 50  # the experiment's tolerance, 1e-8
        assert np.max(np.abs(r.y[after, 0] - ref["y"])) / (10 * scale) < 50


def test_an_fmi3_export_comes_back_too(exported3, tmp_path):
    from .test_export import odelab_tight

    done, case = exported3["pid_saturation"]
    (r,) = run_toml(tmp_path, fmu_toml(done.path, 6))
    assert r.status == "success" and r.case.config["system"]["fmi_version"] == "3.0"
    after = np.r_[np.diff(r.t) > 0, True]
    ref = odelab_tight(case, r.t[after])
    for i, name in enumerate(r.case.problem.states):
        scale = RTOL * np.max(np.abs(ref[name])) + ATOL
        assert np.max(np.abs(r.x[after, i] - ref[name])) / scale < 50


def test_a_sweep_over_the_fmus_parameter_runs(exported, tmp_path):
    done, _ = exported["network_nonlinear_spring"]
    results = run_toml(tmp_path, fmu_toml(done.path, 10, "[parameters]\nk3 = 2\n[sweep]\nparameters.k3 = [0, 2, 8]\n"))
    assert [r.status for r in results] == ["success"] * 3
    for r, k3 in zip(results, (0.0, 2.0, 8.0)):
        x = r.x[-1, 0]  # settled where k1 x + k3 x^3 = 1 (the step of f at t = 1)
        assert 3 * x + k3 * x ** 3 == pytest.approx(1.0, rel=1e-3)


def test_the_high_accuracy_reference_of_an_fmu_is_its_own_tight_run(exported, tmp_path):
    done, _ = exported["network_nonlinear_spring"]
    (r,) = run_toml(tmp_path, f'[system]\nkind = "fmu"\nfile = "{done.path}"\n[time]\nstop = 10\n'
                              '[reference]\nmethod = "high-accuracy"\n')
    assert r.status == "success" and r.case.problem.reference == "high-accuracy"
    # ode45 at MATLAB's default RelTol 1e-3 against the FMU stepped by DOP853 at 1e-12
    assert 1e-7 < r.errors["mass.x"].max_abs < 1e-4


@pytest.mark.parametrize("name", ["BouncingBall", "Dahlquist", "VanDerPol", "Stair", "Feedthrough"])
def test_each_test_fmu_equals_fmpys_own_simulation(test_fmus, name, tmp_path):
    from .test_fmu_folder import compare  # what ODELAB_FMUS runs on any folder of FMUs

    differences = compare(test_fmus[name], tmp_path, "model-exchange")
    assert max(differences.values(), default=0.0) < 1e-6, differences
