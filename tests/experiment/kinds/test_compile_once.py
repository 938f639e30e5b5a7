"""Each expression text of a built case is compiled once (issue 38 item 6): a nonlinear network's and an
equations system's right-hand side, outputs and Jacobian are the NonlinearSystem's functions, not the same
texts compiled again for each use. Counted at odelab.expressions.compile._define, where every compiled
vector function is defined from its generated source (the same texts over the same names give the same
source, so a source defined twice is a text compiled twice)."""

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import odelab.expressions.compile as compile_module
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case

ROOT = Path(__file__).resolve().parents[3]

PENDULUM = """
[system]
states = ["th", "w"]
outputs = {{ x = "sin(th)", y = "-cos(th)" }}
[system.equations]
th = "w"
w = "-9.81*sin(th) - 0.1*w"
[time]
stop = 2
[initial]
th = 1
w = 0
[solver]
method = "{method}"
{extra}
"""


@pytest.fixture
def defined(monkeypatch):
    """The generated sources of the vector functions defined while the fixture is active."""
    sources: list[str] = []
    define = compile_module._define

    def counted(source_code, name, namespace, error):
        if name == "_odelab_vector":
            sources.append(source_code)
        return define(source_code, name, namespace, error)

    monkeypatch.setattr(compile_module, "_define", counted)
    return sources


def _twice(sources):
    return {source.splitlines()[-1][:60]: k for source, k in Counter(sources).items() if k > 1}


def test_a_nonlinear_network_compiles_each_text_once(defined):
    (case, *_) = load_experiment(ROOT / "experiments/networks/network_tanks.toml").cases
    assert type(case.problem.system.model).__name__ == "NonlinearSystem"
    assert _twice(defined) == {}
    # the equations and the outputs, each real and complex step: four functions
    assert len(defined) == 4, defined


@pytest.mark.parametrize("method", ["ode45", "ode15s"])
def test_an_equations_system_with_linearize_compiles_each_text_once(tmp_path, defined, method):
    path = tmp_path / "pendulum.toml"
    path.write_text(PENDULUM.format(method=method, extra="[linearize]\nstart = \"initial\""))
    (case,) = load_experiment(path).cases
    assert _twice(defined) == {} and len(defined) == 4
    result = run_case(case, estimate=False)  # ode15s: the exact Jacobian is the system's complex-step twin
    assert result.status == "success" and _twice(defined) == {} and len(defined) == 4
    # the outputs come from the system object's G: y = (sin th, -cos th) at every stored row
    np.testing.assert_array_equal(result.y[:, 0], np.sin(result.x[:, 0]))
    np.testing.assert_array_equal(result.y[:, 1], -np.cos(result.x[:, 0]))


def test_without_a_system_object_the_equations_compile_once_for_the_run(tmp_path, defined):
    path = tmp_path / "pendulum.toml"
    path.write_text(PENDULUM.format(method="ode15s", extra=""))
    (case,) = load_experiment(path).cases
    assert case.problem.system.model is None and len(defined) == 2  # F and G, real
    result = run_case(case, estimate=False)  # the Jacobian compiles its complex-step twin on first use
    assert result.status == "success" and _twice(defined) == {} and len(defined) == 3
