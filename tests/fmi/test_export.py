"""Exported FMUs: FMPy validates them, FMPy simulates them (Model Exchange with CVode,
Co-Simulation with odelab's ode45 in C) to odelab's own tight run, a plain C host runs them
without Python, and what cannot be exported is refused with the reason."""

from __future__ import annotations

import re
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest

from .conftest import ROOT, fmi_headers
from odelab.exceptions import InputError

fmpy = pytest.importorskip("fmpy")

NAMES = ("exercise2", "network_msd", "network_nonlinear_spring", "pid_saturation")


def odelab_tight(case, t):
    """The case's states and outputs at ``t`` (repeated times: the value after the jump) by DOP853 at 1e-13."""
    from odelab.run.runner import _integrate

    p = case.problem
    unique = np.unique(t)
    run = _integrate(p, unique, "DOP853", {"rtol": 1e-13, "atol": 1e-15}, "python")
    u = p.system.input_fn(run.t) if p.system.input_fn is not None else None
    y = p.system.output_fn(run.t, run.x, u)
    rows = np.searchsorted(unique, t)
    return {**{s: run.x[rows, i] for i, s in enumerate(p.states)}, **{o: y[rows, i] for i, o in enumerate(p.outputs)}}


def largest_relative(result, reference, t=None) -> float:
    """The largest difference over the largest value, per quantity; at a repeated time (an event: the
    host records before and after it) the row after."""
    after = np.r_[np.diff(t) > 0, True] if t is not None else slice(None)
    return max(float(np.max(np.abs(result[k][after] - v[after])) / np.max(np.abs(v))) for k, v in reference.items())


@pytest.fixture(params=[2, 3], ids=["fmi2", "fmi3"])
def fmus(request, exported, exported3):
    return exported if request.param == 2 else exported3


@pytest.mark.parametrize("name", NAMES)
def test_fmpy_validates_the_exported_fmu(fmus, name):
    from fmpy.validation import validate_fmu

    done, _ = fmus[name]
    assert validate_fmu(str(done.path)) == []


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_fmpy_simulates_it_as_odelab_does(fmus, name, interface):
    done, case = fmus[name]
    p = case.problem
    step, stop = 0.02, float(p.tspan[-1])
    kwargs = {"solver": "CVode"} if interface == "ModelExchange" else {}
    result = fmpy.simulate_fmu(str(done.path), fmi_type=interface, stop_time=stop, output_interval=step,
                               relative_tolerance=1e-12, output=[*p.states, *p.outputs], **kwargs)
    assert result["time"][-1] == pytest.approx(stop)
    assert largest_relative(result, odelab_tight(case, result["time"]), result["time"]) < 1e-6


def test_a_plain_c_host_runs_the_co_simulation_without_python(exported, tmp_path):
    from odelab.fmi.build import find_compiler

    done, case = exported["exercise2"]
    host = tmp_path / "cs_host"
    subprocess.run([find_compiler(), "-O2", "-I", str(fmi_headers()), "-o", str(host),
                    str(ROOT / "tests" / "fmi" / "cs_host.c"), "-ldl"], check=True, capture_output=True, timeout=120)
    with zipfile.ZipFile(done.path) as z:
        z.extractall(tmp_path / "fmu")
    binary = tmp_path / "fmu" / "binaries" / "linux64" / "exercise2.so"
    guid = ET.parse(tmp_path / "fmu" / "modelDescription.xml").getroot().get("guid")
    # value references: x, v (the states), y (the output after the two derivatives)
    ran = subprocess.run([str(host), str(binary), guid, "10", "0.02", "1e-12", "0", "1", "4"], capture_output=True,
                         text=True, timeout=60, env={"PATH": "/usr/bin:/bin"})
    assert ran.returncode == 0, ran.stderr
    rows = np.array([[float(v) for v in line.split()] for line in ran.stdout.splitlines()])
    assert rows.shape == (501, 4)
    t = rows[:, 0]
    reference = odelab_tight(case, t)
    assert largest_relative({"x": rows[:, 1], "v": rows[:, 2], "y": rows[:, 3]}, reference) < 1e-6
    fmpy_cs = fmpy.simulate_fmu(str(done.path), fmi_type="CoSimulation", stop_time=10.0, output_interval=0.02,
                                relative_tolerance=1e-12, output=["x", "v", "y"])
    assert np.max(np.abs(fmpy_cs["x"] - rows[:, 1])) <= 1e-12 * np.max(np.abs(rows[:, 1]))


def test_the_saturations_switching_functions_are_event_indicators(exported, exported3):
    with zipfile.ZipFile(exported3["pid_saturation"][0].path) as z:
        root3 = ET.fromstring(z.read("modelDescription.xml"))
    assert len(root3.find("ModelStructure").findall("EventIndicator")) == 2  # FMI 3.0 names them as variables
    done, case = exported["pid_saturation"]
    with zipfile.ZipFile(done.path) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    assert root.get("numberOfEventIndicators") == "2"  # u - upper, u - lower
    assert case.problem.states == ("control.integral", "control.filter", "plant.x", "plant.v")
    result = fmpy.simulate_fmu(str(done.path), fmi_type="ModelExchange", solver="CVode", stop_time=6.0,
                               output_interval=0.01, relative_tolerance=1e-10, output=["u"])
    assert np.max(result["u"]) == pytest.approx(2.0, abs=1e-12)  # the actuator saturates at umax = 2
    assert 0.01 < np.mean(result["u"] == 2.0) < 0.1  # for a while after the step, then it lets go


def test_the_model_description_carries_the_experiment(exported):
    done, _ = exported["network_nonlinear_spring"]
    with zipfile.ZipFile(done.path) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
        names = set(z.namelist())
    assert {"sources/model.c", "sources/odelab_fmi2.c", "sources/fmi2Functions.h"} <= names
    assert root.find("ModelExchange").get("needsExecutionTool") == "false"
    assert root.find("CoSimulation").get("needsExecutionTool") == "false"
    default = root.find("DefaultExperiment").attrib
    assert (float(default["startTime"]), float(default["stopTime"]), float(default["tolerance"])) == (0.0, 10.0, 1e-8)
    variables = {v.get("name"): v for v in root.iter("ScalarVariable")}
    params = {n: (v.get("variability"), float(v.find("Real").get("start")))
              for n, v in variables.items() if v.get("causality") == "parameter"}
    assert params == {"m": ("tunable", 1.0), "b": ("tunable", 4.0), "k1": ("tunable", 3.0), "k3": ("tunable", 2.0),
                      "q": ("tunable", 10.0)}
    assert variables["mass.x"].find("Real").get("unit") == "m"
    assert variables["y"].get("causality") == "output" and variables["y"].find("Real").get("unit") == "V"
    assert variables["der(mass.v)"].find("Real").get("derivative") == str(list(variables).index("mass.v") + 1)


def test_no_name_or_text_of_the_file_reaches_the_c(exported):
    done, _ = exported["network_nonlinear_spring"]
    with zipfile.ZipFile(done.path) as z:
        source = z.read("sources/model.c").decode()
    code = re.sub(r"/\*.*?\*/", "", source, flags=re.S)
    identifiers = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", code))
    assert not identifiers & {"mass", "k1", "k3", "q", "b", "m", "f", "x", "spring"}
    assert "pow(l3, 3.0)" in code  # k3*mass.x^3, re-emitted from the tree


def test_a_tuned_parameter_changes_the_fmus_answer(exported):
    done, case = exported["network_nonlinear_spring"]
    base = fmpy.simulate_fmu(str(done.path), fmi_type="CoSimulation", stop_time=10.0, output_interval=0.1,
                             relative_tolerance=1e-10, output=["mass.x"])
    stiffer = fmpy.simulate_fmu(str(done.path), fmi_type="CoSimulation", stop_time=10.0, output_interval=0.1,
                                relative_tolerance=1e-10, output=["mass.x"], start_values={"k1": 6.0})
    # the step of f = 1 at t = 1 settles where k1 x + k3 x^3 = 1
    for result, k1 in ((base, 3.0), (stiffer, 6.0)):
        x = result["mass.x"][-1]
        assert k1 * x + 2.0 * x ** 3 == pytest.approx(1.0, rel=1e-3)


def load(path):
    from odelab.experiment.loader import load_experiment

    return load_experiment(path)


@pytest.mark.parametrize("file, reason", [
    ("experiments/bouncing_ball.toml", "its [events] (an FMU's state events with resets) are not exported yet"),
    ("experiments/thermostat.toml", "switches with memory"),
    ("experiments/delayed_feedback.toml", "a delay equation"),
])
def test_what_cannot_go_is_refused_with_the_reason(tmp_path, file, reason):
    from odelab import fmi

    with pytest.raises(InputError, match="cannot be exported as an FMU") as info:
        fmi.export(load(ROOT / file), tmp_path / "x.fmu")
    assert reason in info.value.message
    assert not list(tmp_path.iterdir())


def test_a_python_function_is_refused(tmp_path):
    from odelab import fmi

    (tmp_path / "rhs.py").write_text("def f(t, y):\n    return -y\n")
    toml = tmp_path / "py.toml"
    toml.write_text('[system]\nstates = ["y"]\nfunction = "rhs.py:f"\n[initial]\ny = 1\n[time]\nstop = 1\n')
    with pytest.raises(InputError) as info:
        fmi.export(load(toml), tmp_path / "x.fmu")
    assert "its system is a Python function, whose code odelab cannot write as C" in info.value.message


def test_no_c_compiler_is_one_message_naming_gcc(monkeypatch, tmp_path):
    from odelab import fmi

    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.delenv("CC", raising=False)
    with pytest.raises(InputError) as info:
        fmi.export(load(ROOT / "experiments/exercise2.toml"), tmp_path / "x.fmu")
    assert info.value.message.startswith("no C compiler found (looked for cc, gcc and clang on the PATH)")
    assert "`apt-get install gcc`" in info.value.message


def test_the_cli_exports_and_refuses(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from odelab.cli.app import app

    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    done = runner.invoke(app, ["export", str(ROOT / "experiments/exercise2.toml"), "--case", "sine-ode45"])
    assert done.exit_code == 0, done.output
    assert done.output.startswith("wrote exercise2.fmu: case sine-ode45, FMI 2.0 Model Exchange and Co-Simulation, "
                                  "2 states, 1 output, 0 tunable parameters")
    assert (tmp_path / "exercise2.fmu").is_file()
    three = runner.invoke(app, ["export", str(ROOT / "experiments/exercise2.toml"), "-o", "m.fmu", "--fmi", "3"])
    assert three.exit_code == 0, three.output
    assert "FMI 3.0 Model Exchange and Co-Simulation" in three.output
    with zipfile.ZipFile(tmp_path / "m.fmu") as z:
        assert ET.fromstring(z.read("modelDescription.xml")).get("fmiVersion") == "3.0"
        from odelab.fmi.build import platform_folder

        assert any(n.startswith(f"binaries/{platform_folder(3)}/exercise2.") for n in z.namelist())
    four = runner.invoke(app, ["export", str(ROOT / "experiments/exercise2.toml"), "-o", "n.fmu", "--fmi", "4"])
    assert four.exit_code == 2 and "`fmi` must be 2 or 3; got 4." in four.output
    diagram = runner.invoke(app, ["export", str(ROOT / "experiments/thermostat.toml"), "-o", "d.fmu"])
    assert diagram.exit_code == 2 and "Traceback" not in diagram.output
    assert not (tmp_path / "n.fmu").exists() and not (tmp_path / "d.fmu").exists()
