"""[fit] on an FMU (kind = "fmu"): its parameters estimated from [data] by differencing its runs,
checked against the same data fitted on odelab's own equations (exact sensitivities) and against
the closed form."""

from __future__ import annotations

import numpy as np
import pytest



def run_toml(tmp_path, text: str, name: str = "case.toml"):
    """The experiment loaded, fitted and run, as odelab run does (FMUs allowed)."""
    from odelab.experiment.fit import fit_experiment
    from odelab.experiment.loader import load_experiment
    from odelab.fmi import allow_native
    from odelab.run.runner import run_experiment

    path = tmp_path / name
    path.write_text(text)
    with allow_native(True):
        return run_experiment(fit_experiment(load_experiment(path)))

pytest.importorskip("fmpy")

K_TRUE, SIGMA = 1.5, 0.01


def write_data(folder, k=K_TRUE, sigma=SIGMA, n=41, seed=7):
    t = np.linspace(0, 4, n)
    x = np.exp(-k * t) + np.random.default_rng(seed).normal(0, sigma, n)
    lines = ["t,x"] + [f"{a!r},{b!r}" for a, b in zip(t.tolist(), x.tolist())]
    (folder / "decay.csv").write_text("\n".join(lines) + "\n")
    return t, x


FIT = """[parameters]
k = 1
[data]
file = "decay.csv"
sigma = {{ x = {sigma} }}
[fit]
parameters = {{ k = {{ initial = 1, lower = 0.01, upper = 10 }} }}
""".format(sigma=SIGMA)


def test_the_fmus_parameter_is_estimated_as_from_its_own_equations(test_fmus, tmp_path):
    write_data(tmp_path)
    fmu = test_fmus["Dahlquist"]  # der(x) = -k x, x(0) = 1
    (r_fmu,) = run_toml(tmp_path, f'[system]\nkind = "fmu"\nfile = "{fmu}"\n[time]\nstop = 4\n' + FIT, "fmu.toml")
    (r_ode,) = run_toml(tmp_path, '[system]\nstates = ["x"]\n[system.equations]\nx = "-k*x"\n[initial]\nx = 1\n'
                                  '[time]\nstop = 4\n' + FIT, "ode.toml")
    fit_fmu, fit_ode = r_fmu.case.problem.fit, r_ode.case.problem.fit
    assert fit_fmu["status"] == fit_ode["status"] == "converged"
    k_fmu, k_ode = fit_fmu["parameters"]["k"], fit_ode["parameters"]["k"]
    # the same least-squares problem solved two ways: the estimates agree to the solvers' tolerance (1e-10)
    # relative to their standard error, the standard errors to the differences' error (~rtol**(2/3) = 2e-7)
    assert abs(k_fmu["estimate"] - k_ode["estimate"]) < 1e-4 * k_ode["standard_error"]
    assert k_fmu["standard_error"] == pytest.approx(k_ode["standard_error"], rel=1e-5)
    # and the estimate is the truth within its uncertainty (sigma known: chi-square statistics)
    assert abs(k_fmu["estimate"] - K_TRUE) < 3 * k_fmu["standard_error"]
    # its standard error is the closed form's: sigma / sqrt(sum (dx/dk)^2), dx/dk = -t exp(-k t)
    t = np.linspace(0, 4, 41)
    k = k_fmu["estimate"]
    assert k_fmu["standard_error"] == pytest.approx(SIGMA / np.sqrt(np.sum((t * np.exp(-k * t)) ** 2)), rel=1e-5)
    print(f"k: FMU {k_fmu['estimate']!r} +- {k_fmu['standard_error']!r}, equations {k_ode['estimate']!r} +- "
          f"{k_ode['standard_error']!r}; FMU fit {fit_fmu['evaluations']} evaluations")
    # the case then runs at the estimate: the stored run is exp(-k t) at the fitted k
    assert r_fmu.status == "success"
    assert np.max(np.abs(r_fmu.x[:, 0] - np.exp(-k_fmu["estimate"] * r_fmu.t))) < 1e-2


def test_noise_free_data_give_the_parameter_to_the_solvers_tolerance(test_fmus, tmp_path):
    write_data(tmp_path, sigma=0.0)
    fmu = test_fmus["Dahlquist"]
    text = FIT.replace(f"sigma = {{ x = {SIGMA} }}\n", "")
    (r,) = run_toml(tmp_path, f'[system]\nkind = "fmu"\nfile = "{fmu}"\n[time]\nstop = 4\n' + text)
    k = r.case.problem.fit["parameters"]["k"]["estimate"]
    assert abs(k - K_TRUE) < 1e-6 * K_TRUE


def test_a_fitted_name_that_is_not_the_fmus_parameter_is_refused(test_fmus, tmp_path):
    from odelab.exceptions import ExperimentError

    write_data(tmp_path)
    fmu = test_fmus["Dahlquist"]
    with pytest.raises(ExperimentError) as info:
        run_toml(tmp_path, f'[system]\nkind = "fmu"\nfile = "{fmu}"\n[time]\nstop = 4\n'
                 + FIT.replace("k = 1\n", "k = 1\nc = 2\n").replace("{ k = {", "{ c = {"))
    assert "c" in info.value.message


def test_odelab_run_fits_the_fmu_with_allow_native_and_says_how(test_fmus, tmp_path):
    from typer.testing import CliRunner

    from odelab.cli.app import app

    write_data(tmp_path)
    path = tmp_path / "fit.toml"
    path.write_text(f'[system]\nkind = "fmu"\nfile = "{test_fmus["Dahlquist"]}"\n[time]\nstop = 4\n' + FIT)
    runner = CliRunner()
    refused = runner.invoke(app, ["run", "--no-store", str(path)])
    assert refused.exit_code == 2 and "--allow-native" in refused.output
    # the fit reloads the file with its estimates: that load is inside the user's permission too
    done = runner.invoke(app, ["run", "--no-store", "--allow-native", "--width", "200", str(path)])
    assert done.exit_code == 0, done.output
    assert "fit: 1 parameter from 41 measurements" in done.output
    assert "runs of the FMU (the Jacobian by central differences" in done.output
