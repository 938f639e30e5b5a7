"""Forward sensitivities against closed forms and against finite differences of the solution."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from odelab.analysis.sensitivity import ParametricModel, observe, solve_sensitivities
from odelab.expressions import compile_vector

ROOT = Path(__file__).resolve().parents[2]


def misra_model():
    F = compile_vector(["b2*(b1 - y)"], args=["t", "y", "b1", "b2"], complex_step=True)
    return ParametricModel(("y",), ("b1", "b2"), rhs=lambda t, X, P, piece: F(t, X[0], P[0], P[1]),
                           initial=lambda P: np.zeros((1, P.shape[1]), complex))


def test_sensitivities_equal_the_closed_form():
    # y = b1 (1 - exp(-b2 x)): dy/db1 = 1 - exp(-b2 x), dy/db2 = b1 x exp(-b2 x)
    b1, b2 = 238.94, 5.5e-4
    x = np.linspace(50, 760, 15)
    rtol = 1e-10
    sol = solve_sensitivities(misra_model(), [b1, b2], x, t0=0.0, tf=760.0, rtol=rtol, atol=1e-10)
    e = np.exp(-b2 * x)
    assert sol.status == "success"
    np.testing.assert_allclose(sol.x[:, 0], b1 * (1 - e), rtol=100 * rtol)
    np.testing.assert_allclose(sol.S[:, 0, 0], 1 - e, rtol=100 * rtol)
    np.testing.assert_allclose(sol.S[:, 0, 1], b1 * x * e, rtol=100 * rtol)


def test_initial_state_parameters_start_the_sensitivities():
    # T' = -k (T - 21), T(0) = T0: dT/dT0 = exp(-k t), dT/dk = -(T0 - 21) t exp(-k t)
    F = compile_vector(["-k*(T - 21)"], args=["t", "T", "k", "T0"], complex_step=True)
    model = ParametricModel(("T",), ("k", "T0"), rhs=lambda t, X, P, piece: F(t, X[0], P[0], P[1]),
                            initial=lambda P: P[1][None, :])
    k, T0 = 0.045, 88.0
    t = np.arange(0, 61, 2.0)
    sol = solve_sensitivities(model, [k, T0], t, t0=0.0, tf=60.0, rtol=1e-10, atol=1e-9)
    e = np.exp(-k * t)
    np.testing.assert_allclose(sol.S[:, 0, 1], e, rtol=1e-8)
    np.testing.assert_allclose(sol.S[:, 0, 0], -(T0 - 21) * t * e, rtol=1e-8, atol=1e-8)
    assert sol.S[0, 0, 1] == 1.0 and sol.S[0, 0, 0] == 0.0  # S(0) = dx0/dp exactly


def finite_differences(fc, spec, p, rel=1e-5):
    from odelab.experiment.fit import _solve_case

    cols = []
    for k in range(p.size):
        h = rel * abs(p[k])
        up, down = p.copy(), p.copy()
        up[k] += h
        down[k] -= h
        tight = replace(spec, rtol=1e-13)
        fine = replace(fc, atol=1e-15)
        cols.append((_solve_case(fine, up, tight)[0] - _solve_case(fine, down, tight)[0]) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("name", ["msd_fit.toml", "cooling_fit.toml"])
def test_sensitivities_equal_finite_differences_of_the_solution(name):
    """Through the experiment layer: a state-space model's A matrix and a step input (msd), a
    parameter of [initial] (cooling); central differences of solutions at rtol 1e-13."""
    from odelab.experiment.fit import _solve_case
    from odelab.experiment.loader import load_experiment

    exp = load_experiment(ROOT / "experiments" / name)
    spec = exp.fit
    fc = spec.cases[0]
    p = spec.initial * 1.3
    y, dy, sol = _solve_case(fc, p, spec)
    fd = finite_differences(fc, spec, p)
    scale = np.max(np.abs(dy), axis=(0, 1))
    # central differences: error h^2 |y'''| + rtol |y| / h, about 1e-8 of the scale here; the
    # sensitivities' own error is about the fit's rtol (1e-10)
    assert np.max(np.abs(dy - fd) / scale) < 1e-6, np.max(np.abs(dy - fd) / scale)


def test_outputs_observe_with_sensitivities():
    # y = q x for the msd: dy/dp = q dx/dp
    F = compile_vector(["-k*x"], args=["t", "x", "k"], complex_step=True)
    model = ParametricModel(("x",), ("k",), rhs=lambda t, X, P, piece: F(t, X[0], P[0]),
                            initial=lambda P: np.ones((1, P.shape[1]), complex))
    t = np.linspace(0, 2, 5)
    sol = solve_sensitivities(model, [0.7], t, t0=0, tf=2, rtol=1e-11, atol=1e-12)
    y, dy = observe(lambda tt, X, P: (10 * X[0] * P[0] / P[0])[None], t, sol.x, sol.S, [0.7])
    np.testing.assert_allclose(y[:, 0], 10 * np.exp(-0.7 * t), rtol=1e-9)
    np.testing.assert_allclose(dy[:, 0, 0], -10 * t * np.exp(-0.7 * t), rtol=1e-8, atol=1e-12)


def test_never_extrapolated():
    with pytest.raises(ValueError, match="never extrapolated"):
        solve_sensitivities(misra_model(), [1.0, 1.0], [0.5, 2.0], t0=0.0, tf=1.0)


MSD_MATLAB = """
[parameters]
m = 1
k = 3
b = 4
q = 10
F0 = 2

[system]
kind = "state-space"
states = ["x", "v"]
inputs = ["f"]
outputs = ["y"]
A = "[0 1; -k/m -b/m]"
B = [[0], ["1/m"]]
C = [["q", 0]]
D = [[0]]

[initial]
x = 0
v = 0

[time]
stop = 5

[inputs]
f = { type = "expression", expression = "F0*sin(2*t)" }

[data]
file = "y.csv"

[fit]
parameters = { k = {}, b = {}, F0 = {}, q = {} }
"""


def test_parameters_in_an_expression_input_a_matlab_matrix_and_an_output(tmp_path):
    """F0 enters only through [inputs], k and b through a MATLAB matrix string, q only through C."""
    from odelab.experiment.fit import _solve_case
    from odelab.experiment.loader import load_experiment

    t = np.linspace(0, 5, 21)
    (tmp_path / "y.csv").write_text("t,y\n" + "".join(f"{a:g},{np.sin(a):.6f}\n" for a in t))
    path = tmp_path / "msd.toml"
    path.write_text(MSD_MATLAB)
    spec = load_experiment(path).fit
    fc = spec.cases[0]
    assert fc.quantities == ("y",)
    p = np.array([3.0, 4.0, 2.0, 10.0])
    y, dy, _ = _solve_case(fc, p, spec)
    fd = finite_differences(fc, spec, p)
    scale = np.max(np.abs(dy), axis=(0, 1))
    assert np.all(scale > 0)
    assert np.max(np.abs(dy - fd) / scale) < 1e-6
    # y is linear in q and in F0: dy/dq = y / q, dy/dF0 = y / F0, exactly
    np.testing.assert_allclose(dy[:, 0, 3], y[:, 0] / 10, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(dy[:, 0, 2], y[:, 0] / 2, rtol=1e-9, atol=1e-12)
