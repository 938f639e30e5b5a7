"""A case's solver options are resolved once, at load (issue 38 item 3): the built case carries them as one
typed, picklable object (Problem.solver_options), and the run takes them to the driver without normalising
or resolving them again; the keyword API normalises a caller's options once."""

import dataclasses
import pickle

import numpy as np
import pytest

import odelab.solvers.api as api
import odelab.solvers.options as options_module
from odelab.exceptions import InputError
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case
from odelab.solvers.options import SolverOptions, normalize_options, resolve_options
from odelab.solvers.registry import METHODS

DECAY = """
[system]
states = ["x", "v"]
[system.equations]
x = "v"
v = "-x"
[time]
stop = 6
[initial]
x = 1
v = 0
[solver]
method = "{method}"
{options}
"""


def _case(tmp_path, method="ode45", options="RelTol = 1e-5\nAbsTol = [1e-7, 1e-8]"):
    path = tmp_path / "osc.toml"
    path.write_text(DECAY.format(method=method, options=options))
    (case,) = load_experiment(path).cases
    return case


@pytest.fixture
def resolutions(monkeypatch):
    """Counts the calls of normalize_options and resolve_options, wherever they are made from."""
    calls = {"normalize": 0, "resolve": 0}
    normalize, resolve = options_module.normalize_options, options_module.resolve_options

    def counted_normalize(*args, **kw):
        calls["normalize"] += 1
        return normalize(*args, **kw)

    def counted_resolve(*args, **kw):
        calls["resolve"] += 1
        return resolve(*args, **kw)

    for module in (options_module, api):
        monkeypatch.setattr(module, "normalize_options", counted_normalize)
        monkeypatch.setattr(module, "resolve_options", counted_resolve)
    return calls


def test_the_case_carries_its_options_resolved_at_load(tmp_path):
    case = _case(tmp_path)
    resolved = case.problem.solver_options
    assert isinstance(resolved, SolverOptions)
    assert resolved.method == "ode45" and resolved.n == 2 and resolved.span == 6.0
    # MATLAB's spellings mapped once, by the option registry; its defaults filled in
    assert resolved.rtol == 1e-5 and resolved.atol.tolist() == [1e-7, 1e-8]
    assert resolved.refine == METHODS["ode45"].refine and resolved.max_step == pytest.approx(0.6, rel=1e-15)
    assert dict(resolved.given) == {"rtol": 1e-5, "atol": [1e-7, 1e-8]}
    assert case.problem.solver_options is resolved
    again = pickle.loads(pickle.dumps(resolved))  # a plain dataclass: it travels with a built case
    assert again.rtol == resolved.rtol and np.array_equal(again.atol, resolved.atol) and again.given == resolved.given


@pytest.mark.parametrize("method", ["ode45", "ode113", "ode15s", "RK45"])
def test_a_run_resolves_nothing_again(tmp_path, resolutions, method):
    case = _case(tmp_path, method)
    resolutions.update(normalize=0, resolve=0)
    result = run_case(case, max_steps=100_000, estimate=False)  # its step budget is checked alone
    assert result.status == "success"
    assert resolutions == {"normalize": 0, "resolve": 0}
    # the error estimate's second solve, at tolerances 10 times tighter, resolves its own options once
    result = run_case(case, max_steps=100_000, estimate=True)
    assert result.estimate["verdict"] == "ok" and resolutions == {"normalize": 0, "resolve": 1}


@pytest.mark.parametrize("method", ["ode45", "ode15s"])
def test_the_compiled_backend_resolves_nothing_again(tmp_path, resolutions, method):
    """The compiled loops (explicit and stiff) take the case's resolved options as they are, and give the
    bits the same options given as keywords give."""
    pytest.importorskip("numba")
    from odelab.solvers.compiled import solve_compiled

    case = _case(tmp_path, method, 'RelTol = 1e-5\nAbsTol = [1e-7, 1e-8]\nbackend = "compiled"')
    resolutions.update(normalize=0, resolve=0)
    result = run_case(case, max_steps=100_000, estimate=False)
    assert result.status == "success" and result.backend == "compiled"
    assert resolutions == {"normalize": 0, "resolve": 0}
    p = case.problem
    keywords = solve_compiled(p.system.compiled, p.tspan, p.x0, method, RelTol=1e-5, AbsTol=[1e-7, 1e-8],
                              max_steps=100_000)
    assert np.array_equal(result.x, keywords.y) and np.array_equal(result.t, keywords.t)
    with pytest.raises(InputError, match="give the options either resolved or as keywords, not both"):
        solve_compiled(p.system.compiled, p.tspan, p.x0, method, resolved=p.solver_options, rtol=1e-3)


def test_the_carried_options_give_the_keyword_apis_bits(tmp_path):
    case = _case(tmp_path)
    p = case.problem
    by_keywords = api.solve(p.system.fun, p.tspan, p.x0, method="ode45", RelTol=1e-5, AbsTol=[1e-7, 1e-8])
    carried = api.solve(p.system.fun, p.tspan, p.x0, method="ode45", resolved=p.solver_options)
    assert np.array_equal(carried.t, by_keywords.t) and np.array_equal(carried.y, by_keywords.y)
    assert carried.stats == by_keywords.stats
    # for another span they are resolved again from the options as given (MaxStep is a tenth of the span)
    half = api.solve(p.system.fun, [0, 3], p.x0, method="ode45", resolved=p.solver_options)
    assert np.array_equal(half.y, api.solve(p.system.fun, [0, 3], p.x0, method="ode45", rtol=1e-5, atol=[1e-7, 1e-8]).y)


def test_resolved_options_and_keywords_together_are_refused(tmp_path):
    case = _case(tmp_path)
    p = case.problem
    with pytest.raises(InputError, match="give the options either resolved or as keywords, not both; got "
                                         "`resolved` and `rtol`"):
        api.solve(p.system.fun, p.tspan, p.x0, resolved=p.solver_options, rtol=1e-3)
    with pytest.raises(InputError, match="`resolved` must be a SolverOptions"):
        api.solve(p.system.fun, p.tspan, p.x0, resolved={"rtol": 1e-3})


def test_a_budget_is_checked_alone_and_other_changes_resolve_again(tmp_path):
    resolved = _case(tmp_path).problem.solver_options
    budget = resolved.updated(max_steps=500)
    assert budget.max_steps == 500 and budget.given["max_steps"] == 500 and budget.atol is resolved.atol
    assert resolved.updated(refine=1).refine == 1 and resolved.updated(refine=None).refine == 4  # ode45's
    with pytest.raises(InputError, match="`max_steps` must be a whole number"):
        resolved.updated(max_steps=-1)
    tighter = resolved.updated(rtol=1e-6)
    fresh = resolve_options(METHODS["ode45"], normalize_options({"RelTol": 1e-6, "AbsTol": [1e-7, 1e-8]},
                                                                METHODS["ode45"]), np.array([0.0, 6.0]), 2)
    assert tighter.rtol == fresh.rtol and np.array_equal(tighter.atol, fresh.atol) and tighter.max_step == fresh.max_step


def test_a_problem_holds_one_copy_of_its_options(tmp_path):
    """Problem.options is the resolved options' given (no second dict to drift); a changed case is made by
    replacing its solver_options, and runs with them."""
    p = _case(tmp_path).problem
    assert p.options is p.solver_options.given and dict(p.options) == {"rtol": 1e-5, "atol": [1e-7, 1e-8]}
    changed = dataclasses.replace(p, solver_options=p.solver_options.updated(rtol=1e-8))
    assert changed.solver_options.rtol == 1e-8 and changed.options["rtol"] == 1e-8 and p.solver_options.rtol == 1e-5
    with pytest.raises(TypeError):
        dataclasses.replace(p, options={"rtol": 1e-8})  # not a field: one place holds the options
