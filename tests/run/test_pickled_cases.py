"""A built case pickles (issue 38 item 2): it travels to a Dask worker as it is, and a case unpickled there
runs to the same bits as the one built here."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

from odelab.experiment.loader import load_experiments
from odelab.run.runner import run_case

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted((ROOT / "experiments").rglob("*.toml"))


def _same(a, b) -> None:
    assert a.status == b.status and a.message == b.message
    assert a.stats == b.stats
    for name in ("t", "x", "u", "y"):
        left, right = getattr(a, name), getattr(b, name)
        assert (left is None) == (right is None), name
        if left is not None:
            np.testing.assert_array_equal(left, right, err_msg=name)  # bit for bit (NaN where NaN)
    assert a.events == b.events
    assert {k: v.max_abs for k, v in a.errors.items()} == {k: v.max_abs for k, v in b.errors.items()}


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT / "experiments")))
def test_every_shipped_case_pickles_and_runs_to_the_same_bits(path):
    experiments = load_experiments(path)
    for case in [exp.cases[0] for exp in experiments]:  # a sweep's cases are built alike
        copy = pickle.loads(pickle.dumps(case))
        assert copy.problem is not case.problem
        _same(run_case(case, max_steps=200_000, estimate=False), run_case(copy, max_steps=200_000, estimate=False))


def test_a_compiled_expression_pickles_as_its_text():
    from odelab.expressions import compile_expression, compile_vector
    from odelab.systems.fields import ExpressionField

    f = compile_expression("sin(t) + a*x", names=["t", "x", "a"])
    g = pickle.loads(pickle.dumps(f))
    assert g.text == "sin(t) + a*x" and g.names == f.names
    assert g(t=0.5, x=2.0, a=3.0) == f(t=0.5, x=2.0, a=3.0)
    field = ExpressionField(compile_vector(["-k*y", "y*t"], args=["t", "y", "z"], constants={"k": 2.5}))
    data = pickle.dumps(field)
    assert b"-k*y" in data and b"_odelab_vector" not in data  # the texts travel, not code
    copy = pickle.loads(data)
    np.testing.assert_array_equal(copy(0.25, np.array([1.5, -2.0])), field(0.25, np.array([1.5, -2.0])))


def test_what_travels_to_a_dask_worker(tmp_path):
    """Built cases travel; a case whose system is a user's Python function goes by reference (a worker cannot
    import the function's file by name), as does one that does not pickle."""
    from odelab.run.executors import travels

    case = load_experiments(ROOT / "experiments" / "exercise1.toml")[0].cases[0]
    assert travels(case)
    (tmp_path / "rhs.py").write_text("def f(t, y):\n    return -y\n")
    (tmp_path / "user.toml").write_text('[system]\nfunction = "rhs.py:f"\nstates = ["y"]\n[initial]\ny = 1\n'
                                        '[time]\nstop = 1\n')
    (user,) = load_experiments(tmp_path / "user.toml")[0].cases
    pickle.dumps(user)  # it pickles here, where the function's module is loaded...
    assert not travels(user)  # ...but names a module no worker can import


ASSETS = ROOT / "tests" / "assets"
IMPLICIT = """
[system]
kind = "implicit"
states = ["y"]
[system.residuals]
r = "t*y^2*der(y)^3 - y^3*der(y)^2 + t*(t^2 + 1)*der(y) - t^2*y"
[initial]
y = 1.224744871391589
[time]
start = 1
stop = 10
[solver]
rtol = 1e-5
atol = 1e-8
"""


@pytest.mark.parametrize("name", ["simulink/fcn_math.mdl", "simulink/pendulum.mdl", "simulink/switching.mdl",
                                  "matlab/corpus/ballode/bounce.m", "matlab/corpus/mass_matrix/two_masses.m",
                                  "implicit.toml"])
def test_imported_and_implicit_cases_pickle_and_run_to_the_same_bits(tmp_path, name):
    """Blocks with expressions (Fcn), diagrams with switching, MATLAB's event restarts and mass matrices, and an
    implicit system (ode15i: its residuals, its partials compiled on first use, its start copied)."""
    path = tmp_path / name if name == "implicit.toml" else ASSETS / name
    if name == "implicit.toml":
        path.write_text(IMPLICIT)
    case = load_experiments(path)[0].cases[0]
    copy = pickle.loads(pickle.dumps(case))
    here = run_case(case, max_steps=200_000, estimate=False)
    assert here.status == "success", here.message
    _same(here, run_case(copy, max_steps=200_000, estimate=False))
