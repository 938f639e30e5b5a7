"""Methods carry their capabilities: a method added in a test is picked up by the loader, the messages,
``odelab explain`` and ``odelab solvers``; nothing else names it."""

import numpy as np
import pytest
from typer.testing import CliRunner

import odelab
from odelab.cli import app
from odelab.exceptions import ExperimentError, InputError
from odelab.experiment.keyref import explain
from odelab.run.runner import run_experiment
from odelab.solvers import registry
from odelab.solvers.options import normalize_options
from odelab.solvers.registry import METHODS, Method, get_method, methods_with, register_method

DECAY = """
[system]
states = ["x"]
[system.equations]
x = "-x"
[time]
stop = 2
[initial]
x = 1
[exact]
x = "exp(-t)"
[solver]
method = "{method}"
"""
EVENTS = """
[events.half]
when = "x - 0.5"
"""


def _toy(**changes) -> Method:
    """Bogacki-Shampine 3(2) under another name, with fewer capabilities than ode23."""
    base = dict(name="toy23", kind="adaptive", order=3, description="A toy: ode23's pair, without events",
                tableau=METHODS["ode23"].tableau, power=1 / 3, shrink_min=0.5, refine=1,
                options=tuple(o for o in registry.EXPLICIT_OPTIONS if o not in ("events", "mass",
                                                                                 "mstate_dependence")),
                dense_output=True, dense="a toy's cubic", matlab_defaults=True)
    return Method(**{**base, **changes})


@pytest.fixture
def toy(request):
    method = register_method(_toy(**getattr(request, "param", {})))
    yield method
    del METHODS[method.name]


def _run(tmp_path, text):
    path = tmp_path / "toy.toml"
    path.write_text(text)
    return run_experiment(path)


def test_a_registered_method_runs_from_toml_with_its_drivers_numbers(toy, tmp_path):
    (toy_result,) = _run(tmp_path, DECAY.format(method="TOY23"))  # case-insensitive, as every method name
    (ode23_result,) = _run(tmp_path, DECAY.format(method="ode23"))
    assert toy_result.method == "toy23" and toy_result.status == "success"
    # the same pair and controller as ode23: the same steps, bit for bit
    np.testing.assert_array_equal(toy_result.t, ode23_result.t)
    np.testing.assert_array_equal(toy_result.x, ode23_result.x)
    assert toy_result.stats == ode23_result.stats
    assert toy_result.errors["x"].max_abs < 10 * 1e-3  # within ten rtol of exp(-t)


def test_what_it_cannot_do_is_refused_with_the_methods_that_can(toy, tmp_path):
    with pytest.raises(ExperimentError) as info:
        _run(tmp_path, DECAY.format(method="toy23") + EVENTS)
    assert info.value.key == "solver.method" and info.value.message.startswith(
        "[events] are located by ode23, ode45, ode78, ode89, ode113, ode15s, ode23s, ode23t and ode23tb")
    with pytest.raises(InputError, match=r"`Mass` \(M y' = f\): toy23 solves y' = f only, with no mass matrix; "
                                         r"the solvers that take a mass are ode23, ode45, ode78, ode89, ode113, "
                                         r"ode15s, ode23s, ode23t, ode23tb\.$"):
        normalize_options({"Mass": [[1.0]]}, toy)
    with pytest.raises(InputError, match=r"a complex `y0` is integrated by ode23/ode45/ode78/ode89/ode113 \(as "
                                         r"MATLAB's\); toy23 takes real y0"):
        odelab.solve(lambda t, y: -y, [0, 1], 1j, method="toy23")


@pytest.mark.parametrize("toy", [{"options": registry.EXPLICIT_OPTIONS, "events": True, "mass": "moving",
                                  "complex_y0": True}], indirect=True)
def test_a_capability_added_joins_every_list(toy, tmp_path):
    assert "toy23" in methods_with(lambda m: m.events) and "toy23" in methods_with(lambda m: m.complex_y0)
    (result,) = _run(tmp_path, DECAY.format(method="toy23") + EVENTS)
    (half,) = result.events
    assert abs(half["t"] - np.log(2)) < 1e-3  # x = 0.5 at t = ln 2, within rtol
    with pytest.raises(ExperimentError, match=r"\[events\] are located by ode23, ode45, ode78, ode89, ode113, "
                                              r"toy23, ode15s, ode23s, ode23t and ode23tb"):
        _run(tmp_path, DECAY.format(method="RK45") + EVENTS)
    sol = odelab.solve(lambda t, y: -1j * y, [0, 1], 1.0 + 0j, method="toy23", rtol=1e-6, atol=1e-9)
    assert abs(sol.y[-1, 0] - np.exp(-1j)) < 100 * 1e-6


def test_deval_lists_it_among_the_methods_with_dense_output(toy):
    sol = odelab.solve(lambda t, y: -y, [0, 1], 1.0, method="rk4", h=0.1)
    with pytest.raises(InputError) as info:
        odelab.deval(sol, 0.5)
    assert str(info.value).endswith(
        "rk4 does not provide one. Solve with ode23, ode45 (their ntrp23/ntrp45 interpolants), ode78 or ode89 "
        "(Verner's), ode113 (Adams), toy23 (a toy's cubic), ode23t or ode23tb (their quadratics), or with a "
        "vector tspan of the times you need.")


def test_explain_and_solvers_show_it(toy):
    text = " ".join(explain("solver.method.toy23").split())  # unwrapped
    assert "A toy: ode23's pair, without events" in text and "Can do: dense output (deval)" in text
    assert "toy23" in explain("solver.method")  # among the choices
    result = CliRunner().invoke(app, ["solvers"])
    assert result.exit_code == 0 and "toy23" in result.output
    assert get_method("Toy23") is toy


def test_the_registry_refuses_an_inconsistent_method():
    with pytest.raises(ValueError, match="`events` and the option `events` disagree"):
        _toy(events=True)
    with pytest.raises(ValueError, match="kind 'warp' is not a driver"):
        _toy(kind="warp")
    with pytest.raises(ValueError, match="would shadow 'ode23'"):
        register_method(_toy(name="ODE23"))
    with pytest.raises(ValueError, match="takes a DAE, so it takes a mass matrix"):
        _toy(dae=True)


def test_the_suite_capabilities_are_matlabs():
    # what MATLAB's documentation says of each solver (odeset: Events, Mass, MStateDependence; deval)
    assert methods_with(lambda m: m.dae) == ["ode15s", "ode23t"]
    assert methods_with(lambda m: m.mass == "moving") == ["ode23", "ode45", "ode78", "ode89", "ode113"]
    assert methods_with(lambda m: m.compiled_events) == ["ode23", "ode45"]
    assert methods_with(lambda m: m.delays, delays=True) == ["dde23"]
    assert not any(m.stiff for m in METHODS.values() if m.complex_y0)
