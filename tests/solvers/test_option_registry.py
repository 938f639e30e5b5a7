"""Solver options are declared once (odelab.solvers.optionset): a toy option registered in the test is
taken from TOML (its MATLAB spelling too), checked with its key path, explained, and reaches the solve."""

import pytest

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.keyref import explain
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_experiment
from odelab.solvers.optionset import OPTIONS, SolverOption, canonical, positive, register_option
from odelab.solvers.options import method_options, normalize_options, resolve_options
from odelab.solvers.registry import METHODS

DECAY = """
[system]
states = ["x"]
[system.equations]
x = "-x"
[time]
stop = 1
[initial]
x = 1
[solver]
method = "{method}"
{option}
"""


@pytest.fixture
def safety():
    """A toy option: a safety factor (a number in (0, 1)) that ode45 takes."""
    def check(value, ctx):
        value = positive("safety", value)
        if value >= 1:
            raise InputError(f"`safety` must be below 1 (a fraction of the step); got {value!r}.", key="safety")
        return value

    option = register_option(SolverOption("safety", "A toy: the fraction of the optimal step to take.",
                                          matlab=("SafetyFactor",), default="0.9", toml="number", check=check,
                                          takes=lambda m: m.name == "ode45"))
    yield option
    del OPTIONS["safety"]


def _file(tmp_path, method, option):
    path = tmp_path / "toy.toml"
    path.write_text(DECAY.format(method=method, option=option))
    return path


def test_a_registered_option_is_a_solver_key_with_its_sentence(safety):
    assert "safety" in schema.SOLVER_KEYS and canonical("safetyfactor") == "safety"
    text = explain("solver.SafetyFactor")  # found by its MATLAB spelling
    assert text.startswith("solver.safety  (number)") and "A toy: the fraction" in text and "SafetyFactor" in text
    assert method_options(METHODS["ode45"])[-1] == "safety" and "safety" not in method_options(METHODS["ode23"])


def test_it_is_read_from_toml_checked_and_reaches_the_solver(safety, tmp_path):
    exp = load_experiment(_file(tmp_path, "ode45", "SafetyFactor = 0.8"))
    (case,) = exp.cases
    assert case.problem.options["safety"] == 0.8
    opts = resolve_options(METHODS["ode45"], normalize_options(case.problem.options, METHODS["ode45"]),
                           case.problem.tspan, 1)
    assert opts.more == {"safety": 0.8}  # what a driver taking it reads
    (result,) = run_experiment(_file(tmp_path, "ode45", "safety = 0.8"))
    assert result.status == "success"
    with pytest.raises(ExperimentError) as info:
        load_experiment(_file(tmp_path, "ode45", "safety = 1.5"))
    assert info.value.key == "solver.safety"
    assert "`solver.safety` must be below 1 (a fraction of the step); got 1.5." in info.value.message
    with pytest.raises(ExperimentError) as info:
        load_experiment(_file(tmp_path, "ode45", 'safety = "high"'))
    assert info.value.key == "solver.safety" and "must be a number" in info.value.message


def test_a_method_that_does_not_take_it_says_which_do(safety, tmp_path):
    with pytest.raises(ExperimentError) as info:
        load_experiment(_file(tmp_path, "ode23", "safety = 0.8"))
    assert info.value.key == "solver.safety"
    assert info.value.message.startswith("`solver.safety` does not apply to ode23; it accepts: rtol, atol, ")


def test_without_the_option_the_key_is_unknown(tmp_path):
    with pytest.raises(ExperimentError) as info:
        load_experiment(_file(tmp_path, "ode45", "safety = 0.8"))
    assert info.value.message.startswith("unknown key `solver.safety`.")


def test_spellings_may_not_clash():
    with pytest.raises(ValueError, match="clashes with option 'rtol'"):
        register_option(SolverOption("tolerance", "A clash.", matlab=("RelTol",)))
    with pytest.raises(ValueError, match="is not one of"):
        SolverOption("odd", "A bad TOML type.", toml="complex")
