"""[sweep] expansion: product, zip, ranges, names, with [[case]], and [[problem]] files."""

import pytest

from odelab.exceptions import ExperimentError
from odelab.experiment.loader import load_experiment, load_experiments
from odelab.experiment.sweep import expand_sweep, format_value

BASE = """
title = "Exercise 1"
[parameters]
k = 1
[system]
states = ["y"]
[system.equations]
y = "k*cos(t)"
[initial]
y = 2
[time]
stop = "pi"
[exact]
y = "k*sin(t) + 2"
[solver]
method = "ode45"
"""


def load(tmp_path, extra, name="exp.toml"):
    path = tmp_path / name
    path.write_text(BASE + extra)
    return load_experiment(path)


def test_product_names_values_and_order(tmp_path):
    exp = load(tmp_path, '[sweep]\n"solver.rtol" = [1e-3, 1e-4]\n"solver.method" = ["ode23", "ode45"]\n')
    assert [c.name for c in exp.cases] == ["rtol=0.001, method=ode23", "rtol=0.001, method=ode45",
                                           "rtol=1e-4, method=ode23", "rtol=1e-4, method=ode45"]
    assert [c.index for c in exp.cases] == [0, 1, 2, 3]
    assert exp.cases[3].swept == {"solver.rtol": 1e-4, "solver.method": "ode45"}
    assert exp.cases[2].problem.method == "ode23" and exp.cases[2].problem.options["rtol"] == 1e-4
    assert exp.cases[2].config["solver"]["rtol"] == 1e-4  # resolved.toml reproduces the case
    assert exp.sweep.store == "summary" and exp.sweep.mode == "product"


def test_zip_pairs_the_lists(tmp_path):
    exp = load(tmp_path, '[sweep]\nmode = "zip"\n"solver.rtol" = [1e-3, 1e-6]\n"parameters.k" = [1, 2]\n')
    assert [c.name for c in exp.cases] == ["rtol=0.001, k=1", "rtol=1e-6, k=2"]
    assert exp.cases[1].problem.parameters["k"] == 2


def test_ranges_as_matlab_users_write_them(tmp_path):
    exp = load(tmp_path, '[sweep]\n"parameters.k" = { from = 1, to = 10, count = 10 }\n')
    assert [c.swept["parameters.k"] for c in exp.cases] == [float(i) for i in range(1, 11)]
    sweep = expand_sweep({"solver.rtol": {"from": 1e-2, "to": 1e-6, "count": 5, "log": True}}, {})
    assert sweep.values[0] == (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)  # exact decades, not 9.999999999999999e-05
    assert [p.name for p in sweep.points()] == ["rtol=0.01", "rtol=0.001", "rtol=1e-4", "rtol=1e-5", "rtol=1e-6"]
    sweep = expand_sweep({"parameters.k": {"from": 1, "to": 2, "step": 0.25}}, {"parameters": {"k": 1}})
    assert sweep.values[0] == (1.0, 1.25, 1.5, 1.75, 2.0)
    sweep = expand_sweep({"parameters.k": {"from": 1, "to": 10, "step": 3}}, {"parameters": {"k": 1}})
    assert sweep.values[0] == (1, 4, 7, 10)  # 1:3:10, whole numbers stay whole


def test_tables_and_inputs_fields_and_clashing_labels(tmp_path):
    sweep = expand_sweep({"solver": {"h": [0.1, 0.05]}, "inputs": {"f": {"amplitude": [1, 2]}},
                          "initial.f": [0, 1]},
                         {"inputs": {"f": {"type": "sine"}}, "initial": {"f": 0}})
    assert sweep.keys == ("solver.h", "inputs.f.amplitude", "initial.f")
    point = sweep.points()[-1]
    assert point.name == "h=0.05, amplitude=2, f=1"
    assert point.override == {"solver": {"h": 0.05}, "inputs": {"f": {"amplitude": 2}}, "initial": {"f": 1}}
    sweep = expand_sweep({"initial.k": [1], "parameters.k": [2]}, {"initial": {"k": 0}, "parameters": {"k": 1}})
    assert sweep.points()[0].name == "initial.k=1, parameters.k=2"


def test_sweep_over_cases_names_both(tmp_path):
    exp = load(tmp_path, '[sweep]\n"solver.rtol" = [1e-3, 1e-4]\n[[case]]\nname = "a"\n[[case]]\nname = "b"\n'
                         'solver.method = "ode23"\n')
    assert [c.name for c in exp.cases] == ["a, rtol=0.001", "a, rtol=1e-4", "b, rtol=0.001", "b, rtol=1e-4"]
    assert exp.cases[3].problem.method == "ode23"


def test_format_value():
    assert [format_value(v) for v in (0.05, 1e-4, 2.5e-6, 3, True, "ode45", 1e6, 0.0)] == [
        "0.05", "1e-4", "2.5e-6", "3", "true", "ode45", "1e6", "0"]


def test_problems_share_the_sweep(tmp_path):
    path = tmp_path / "two.toml"
    path.write_text(BASE + '[sweep]\n"solver.rtol" = [1e-3, 1e-4]\n'
                    '[[problem]]\nname = "one"\n'
                    '[[problem]]\nname = "two"\nexact = { y = "2*sin(t) + 2" }\nparameters = { k = 2 }\n')
    exps = load_experiments(path)
    assert [e.name for e in exps] == ["two_one", "two_two"]
    assert [len(e.cases) for e in exps] == [2, 2] and exps[1].cases[0].problem.parameters == {"k": 2.0}
    with pytest.raises(ExperimentError, match="load_experiments"):
        load_experiment(path)


def test_bad_value_names_the_case(tmp_path):
    with pytest.raises(ExperimentError) as info:
        load(tmp_path, '[sweep]\n"solver.rtol" = [1e-3, -1]\n')
    assert "(set in case 'rtol=-1')" in str(info.value) and info.value.key == "solver.rtol"
