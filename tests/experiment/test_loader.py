"""Loading experiment files: merging, naming, aliases, time specs, resolved configuration."""

from pathlib import Path

import numpy as np
import pytest

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment.loader import load_experiment, merge, slug

ROOT = Path(__file__).resolve().parents[2]


def write(tmp_path, text, name="exp.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


BASE = '''
[system]
states = ["x", "v"]
[system.equations]
x = "v"
v = "-k*x"
[parameters]
k = 4
[initial]
x = 1
v = 0
[time]
stop = "2*pi"
'''


def test_merge_is_deep_and_lists_replace():
    base = {"solver": {"method": "ode23", "atol": [1, 2]}, "time": {"stop": 1}}
    out = merge(base, {"solver": {"atol": [3]}, "title": "t"})
    assert out == {"solver": {"method": "ode23", "atol": [3]}, "time": {"stop": 1}, "title": "t"}
    assert base["solver"]["atol"] == [1, 2]  # the base is not modified


def test_one_case_named_after_the_method_and_experiment_named_after_the_file(tmp_path):
    exp = load_experiment(write(tmp_path, BASE, "spring.toml"))
    assert exp.name == "spring" and [c.name for c in exp.cases] == ["ode45"]
    p = exp.cases[0].problem
    assert p.states == ("x", "v") and p.tspan.tolist() == [0, 2 * np.pi]
    np.testing.assert_allclose(p.system.fun(0.0, np.array([1.0, 0.0])), [0.0, -4.0])


def test_cases_merge_over_the_base_and_name_overrides(tmp_path):
    text = 'name = "osc"\n' + BASE + '''
[[case]]
name = "loose"
solver.rtol = 1e-2
[[case]]
name = "fixed"
solver = { method = "rk4", h = 0.01 }
'''
    exp = load_experiment(write(tmp_path, text))
    assert exp.name == "osc"
    loose, fixed = exp.cases
    assert loose.problem.options == {"rtol": 1e-2} and loose.problem.method == "ode45"
    assert fixed.problem.method == "rk4" and fixed.problem.options == {"h": 0.01}
    assert loose.config["solver"] == {"method": "ode45", "rtol": 0.01, "atol": 1e-6}
    assert loose.config["case"] == [{"name": "loose"}]


def test_matlab_option_names_are_accepted(tmp_path):
    text = BASE + '[solver]\nmethod = "ode45"\nRelTol = 1e-4\nAbsTol = [1e-6, 1e-7]\nMaxStep = 0.5\n'
    p = load_experiment(write(tmp_path, text)).cases[0].problem
    assert p.options == {"rtol": 1e-4, "atol": [1e-6, 1e-7], "max_step": 0.5}


def test_output_times_and_points(tmp_path):
    p = load_experiment(write(tmp_path, BASE.replace('stop = "2*pi"', 'stop = 2\noutput = [0, 0.5, "1", 2]'))).cases[0].problem
    assert p.tspan.tolist() == [0, 0.5, 1, 2]
    p = load_experiment(write(tmp_path, BASE.replace('stop = "2*pi"', 'stop = 1\npoints = 11'))).cases[0].problem
    np.testing.assert_allclose(p.tspan, np.linspace(0, 1, 11))
    with pytest.raises(ExperimentError, match=r"must run from time.start \(0\) to time.stop \(2\)"):
        load_experiment(write(tmp_path, BASE.replace('stop = "2*pi"', 'stop = 2\noutput = [0, 1]')))


def test_parameters_may_be_expressions_of_parameters(tmp_path):
    text = BASE.replace("k = 4", 'k = "w^2"\nw = 3')
    p = load_experiment(write(tmp_path, text)).cases[0].problem
    assert p.parameters == {"k": 9.0, "w": 3.0}
    np.testing.assert_allclose(p.system.fun(0.0, np.array([1.0, 0.0])), [0.0, -9.0])


def test_errors_carry_file_and_key(tmp_path):
    path = write(tmp_path, BASE.replace('x = 1', 'x = "1/"'))
    with pytest.raises(InputError) as info:
        load_experiment(path)
    assert info.value.source == str(path) and info.value.key == "initial.x"
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize("name", ["../../x", "/etc/passwd", "a\x00b", "..", "", "ok name/../../y"])
def test_slug_cannot_escape(name):
    s = slug(name)
    assert s and "/" not in s and "\x00" not in s and s not in (".", "..")
    assert (Path("/runs") / s).resolve().parent == Path("/runs")


def test_shipped_experiments_load():
    from odelab.experiment.loader import load_experiments

    for path in sorted((ROOT / "experiments").rglob("*.toml")):  # networks/ too
        for exp in load_experiments(path):
            assert exp.cases, path
