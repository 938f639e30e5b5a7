"""NIST StRD nonlinear regression problems written as ODEs, fitted from NIST's first starting values.

Certified values from NIST's Statistical Reference Datasets
(https://www.itl.nist.gov/div898/strd/nls/nls_main.shtml): Misra1a (lower difficulty) and
Misra1b (average), both on the data of Misra, D., NIST (1978), embedded in
tests/assets/fit/misra1a.csv. The models are solutions of ODEs, so the fit goes through the
solver and the forward sensitivities, not through the closed form: Misra1a's
y = b1 (1 - exp(-b2 x)) solves y' = b2 (b1 - y), Misra1b's y = b1 (1 - (1 + b2 x/2)^-2)
solves y' = b2 (b1 - y)^(3/2) / sqrt(b1), both from y(0) = 0.
"""

from pathlib import Path

import numpy as np
import pytest

from odelab.experiment.fit import fit_experiment
from odelab.experiment.loader import load_experiment

ASSETS = Path(__file__).parent.parent / "assets" / "fit"

# name: (certified b1, b2), (certified standard errors), certified residual sum of squares
CERTIFIED = {
    "misra1a": ((2.3894212918e02, 5.5015643181e-04), (2.7070075241e00, 7.2668688436e-06), 1.2455138894e-01),
    "misra1b": ((3.3799746163e02, 3.9039091287e-04), (3.1643950207e00, 4.2547321834e-06), 7.5464681533e-02),
}


@pytest.mark.parametrize("name", sorted(CERTIFIED))
def test_certified_estimates_and_standard_errors(name):
    exp = load_experiment(ASSETS / f"{name}.toml")
    assert list(exp.fit.initial) == [500.0, 1e-4]  # NIST's Start 1
    fit = fit_experiment(exp).cases[0].problem.fit
    assert fit["status"] == "converged"
    values, errors, rss = CERTIFIED[name]
    for pname, certified, se in zip(("b1", "b2"), values, errors):
        p = fit["parameters"][pname]
        # at least 6 significant digits of the estimates, 3 of the standard errors
        assert abs(p["estimate"] / certified - 1) < 5e-7, (pname, p["estimate"], certified)
        assert abs(p["standard_error"] / se - 1) < 5e-4, (pname, p["standard_error"], se)
    assert abs(fit["rss"] / rss - 1) < 1e-6
    assert fit["dof"] == 12 and fit["n"] == 14
    assert fit["identifiability"] is None
    # 95 % intervals: estimate +- t(0.975, 12) se; Student's t table: t(0.975, 12) = 2.179
    b1 = fit["parameters"]["b1"]
    assert fit["t_quantile"] == pytest.approx(2.179, abs=5e-4)
    assert b1["ci95"][1] - b1["estimate"] == pytest.approx(fit["t_quantile"] * b1["standard_error"], rel=1e-12)


def test_the_cases_run_at_the_estimates_against_the_data():
    from odelab.experiment.runner import run_case

    fitted = fit_experiment(load_experiment(ASSETS / "misra1a.toml"))
    case = fitted.cases[0]
    assert case.problem.parameters["b1"] == pytest.approx(238.94212918, rel=1e-7)
    result = run_case(case)
    assert result.reference_kind == "data"
    assert result.extra["fit"]["status"] == "converged"
    data = result.extra["data"]
    # the case's own ode45 at its default tolerances, read at the measured times
    model = np.array(data["model"]["y"])
    t = np.array(data["t"])
    exact = 238.94212918 * (1 - np.exp(-5.5015643181e-04 * t))
    assert np.max(np.abs(model - exact)) < 1e-3 * 82  # rtol 1e-3 of the largest value
    assert result.errors["y"].max_abs == pytest.approx(np.max(np.abs(np.array(data["measured"]["y"]) - model)))
