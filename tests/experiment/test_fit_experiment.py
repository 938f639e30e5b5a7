"""[data] and [fit] through the loader, the runner and the CLI; the shipped fitting experiments."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.exceptions import ExperimentError
from odelab.experiment.fit import fit_experiment
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENTS = ROOT / "experiments"
runner = CliRunner()

COOLING = """
[parameters]
k = 0.1
T0 = 80
T_room = 21

[system]
states = ["T"]
equations = { T = "-k*(T - T_room)" }

[initial]
T = "T0"

[time]
stop = 60

[data]
file = "cooling.csv"
time = "minutes"
columns = { T = "temperature" }
"""


def cooling_csv(path: Path, *, k=0.045, T0=88.0, T_room=21.0, seed=5, sigma=0.4, t=None):
    t = np.arange(0, 61, 2.0) if t is None else t
    T = T_room + (T0 - T_room) * np.exp(-k * t) + np.random.default_rng(seed).normal(0, sigma, t.size)
    path.write_text("minutes,temperature\n" + "".join(f"{a:g},{b:.4f}\n" for a, b in zip(t, T)))


def write(tmp_path: Path, text: str, name: str = "exp.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def fitted(path):
    exp = fit_experiment(load_experiment(path))
    return exp, exp.cases[0].problem.fit


# --- shipped experiments --------------------------------------------------------------------------


def test_mass_spring_damper_true_values_inside_the_intervals():
    exp, fit = fitted(EXPERIMENTS / "msd_fit.toml")
    assert fit["status"] == "converged" and fit["identifiability"] is None
    for name, true in (("k", 3.0), ("b", 4.0)):
        lo, hi = fit["parameters"][name]["ci95"]
        assert lo < true < hi, (name, lo, hi)
        assert fit["parameters"][name]["standard_error"] < 0.1 * true
    # the noise was 0.005 m: the residuals' standard deviation estimates it
    assert 0.004 < fit["residual_std"] < 0.006
    result = run_case(exp.cases[0])
    assert result.reference_kind == "data" and result.status == "success"
    assert set(result.errors) == {"x"}


def test_cooling_curve_true_values_inside_the_intervals_with_known_sigma():
    exp, fit = fitted(EXPERIMENTS / "cooling_fit.toml")
    assert fit["sigma_known"] and fit["status"] == "converged"
    for name, true in (("k", 0.045), ("T0", 88.0)):
        lo, hi = fit["parameters"][name]["ci95"]
        assert lo < true < hi, (name, lo, hi)
    # chi-square / dof near 1 when sigma is the noise (29 dof: its sd is about 0.26)
    assert 0.4 < fit["rss"] / fit["dof"] < 1.8


def test_data_generation_scripts_are_deterministic(tmp_path):
    import runpy

    for script, csv in (("make_step_response.py", "step_response.csv"), ("make_cooling_curve.py", "cooling_curve.csv")):
        shutil.copy(EXPERIMENTS / "data" / script, tmp_path / script)
        runpy.run_path(str(tmp_path / script), run_name="__main__")
        assert (tmp_path / csv).read_text() == (EXPERIMENTS / "data" / csv).read_text()


# --- [data] as the reference ----------------------------------------------------------------------


def test_data_alone_is_the_reference_at_the_measured_times(tmp_path):
    cooling_csv(tmp_path / "cooling.csv", sigma=0.0, k=0.1, T0=80)
    path = write(tmp_path, COOLING + '\n[solver]\nrtol = 1e-8\natol = 1e-10\n')
    result = run_case(load_experiment(path).cases[0])
    assert result.reference_kind == "data"
    # exact data of the model itself: the error is the solver's (rtol 1e-8), at the measured times
    assert result.errors["T"].max_abs < 1e-6 * 80
    assert result.extra["data"]["t"] == list(np.arange(0, 61, 2.0))
    assert "fit" not in result.extra


def test_data_outside_the_time_span_is_an_error(tmp_path):
    cooling_csv(tmp_path / "cooling.csv", t=np.arange(0, 71, 2.0))
    with pytest.raises(ExperimentError, match=r"outside the simulated span \[0, 60\].*never extrapolated"):
        load_experiment(write(tmp_path, COOLING))


def test_fixed_step_case_reads_its_own_grid(tmp_path):
    cooling_csv(tmp_path / "cooling.csv", sigma=0.0, k=0.1, T0=80, t=np.arange(0, 60.5, 0.5))
    path = write(tmp_path, COOLING + '\n[solver]\nmethod = "rk4"\nh = 0.5\n')
    result = run_case(load_experiment(path).cases[0])
    assert result.reference_kind == "data" and result.errors["T"].max_abs < 1e-4


# --- joint fits and validation --------------------------------------------------------------------


def test_cases_sharing_one_fit_are_fitted_jointly(tmp_path):
    cooling_csv(tmp_path / "cooling.csv", seed=1)
    cooling_csv(tmp_path / "fridge.csv", seed=2, T_room=5.0)
    text = COOLING + """
[fit]
parameters = { k = { lower = 0 }, T0 = {} }

[[case]]
name = "room"

[[case]]
name = "fridge"
parameters.T_room = 5
data.file = "fridge.csv"
"""
    exp, fit = fitted(write(tmp_path, text))
    assert fit["cases"] == ["room", "fridge"] and fit["n"] == 62 and fit["dof"] == 60
    assert fit["parameters"]["k"]["ci95"][0] < 0.045 < fit["parameters"]["k"]["ci95"][1]
    assert [c.problem.parameters["k"] for c in exp.cases] == [fit["parameters"]["k"]["estimate"]] * 2


def test_validate_with_a_second_data_set(tmp_path):
    cooling_csv(tmp_path / "cooling.csv", seed=1)
    cooling_csv(tmp_path / "again.csv", seed=9, t=np.arange(1, 60, 4.0))
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    cooling_csv(outside / "third.csv", seed=10)
    path = write(tmp_path, COOLING + '\n[fit]\nparameters = { k = {}, T0 = {} }\nvalidate = "again.csv"\n')
    result = runner.invoke(app, ["run", str(path), "--json", "--no-store", "--validate-with", str(outside / "third.csv")])
    assert result.exit_code == 0, result.output
    fit = json.loads(result.stdout)["experiments"][0]["cases"][0]["extra"]["fit"]
    files = [v["file"] for v in fit["validation"]]
    assert files == ["again.csv", str(outside / "third.csv")]
    for v in fit["validation"]:
        # a second draw of the same noise (0.4): its rms is the noise's, like the fit's own
        assert 0.25 < v["rms"]["T"] < 0.6 and 0.25 < v["fit_rms"]["T"] < 0.6


def test_terminal_and_json_show_the_fit(tmp_path):
    cooling_csv(tmp_path / "cooling.csv", seed=1)
    path = write(tmp_path, COOLING + '\n[fit]\nparameters = { k = {}, T0 = {} }\n')
    result = runner.invoke(app, ["run", str(path), "--no-store"], terminal_width=80)
    assert result.exit_code == 0, result.output
    assert "fit: 2 parameters from 31 measurements" in result.output
    assert "95% interval" in result.output and "correlations: k-T0" in result.output
    result = runner.invoke(app, ["run", str(path), "--json", "--no-store"])
    case = json.loads(result.stdout)["experiments"][0]["cases"][0]
    assert case["reference"] == "data"
    fit = case["extra"]["fit"]
    assert set(fit["parameters"]["k"]) >= {"estimate", "standard_error", "ci95"}
    assert fit["solves"] >= 2 and fit["iterations"] >= 1 and len(fit["correlation"]) == 2


def test_non_identifiable_product_gets_the_warning(tmp_path):
    t = np.linspace(0, 3, 25)
    y = 2 * np.exp(-1.2 * t) + np.random.default_rng(4).normal(0, 0.01, t.size)
    (tmp_path / "decay.csv").write_text("t,y\n" + "".join(f"{a:g},{b:.6f}\n" for a, b in zip(t, y)))
    text = """
[parameters]
a = 1
b = 2

[system]
states = ["y"]
equations = { y = "-a*b*y" }

[initial]
y = 2

[time]
stop = 3

[data]
file = "decay.csv"

[fit]
parameters = { a = {}, b = {} }
"""
    path = write(tmp_path, text)
    _, fit = fitted(path)
    assert fit["identifiability"] and "they enter only as a*b" in fit["identifiability"]
    result = runner.invoke(app, ["run", str(path), "--no-store"], terminal_width=80)
    assert "warning: not identifiable" in result.output and "a*b" in result.output


def test_a_fit_that_does_not_converge_fails_with_the_last_iterate(tmp_path):
    cooling_csv(tmp_path / "cooling.csv", seed=1)
    path = write(tmp_path, COOLING + '\n[fit]\nparameters = { k = {}, T0 = {} }\nmax_solves = 2\n')
    result = runner.invoke(app, ["run", str(path), "--no-store"], terminal_width=100)
    assert result.exit_code == 1
    assert "fit FAILED" in result.output and "did not converge within 2 model solves" in result.output
    assert "The last iterate was k = " in result.output.replace("\n", " ")


# --- bad input ----------------------------------------------------------------------------------------

FIT = '\n[fit]\nparameters = { k = {}, T0 = {} }\n'


def _error(tmp_path, text, csv_text=None, csv_name="cooling.csv"):
    if csv_text is not None:
        (tmp_path / csv_name).write_bytes(csv_text if isinstance(csv_text, bytes) else csv_text.encode())
    path = write(tmp_path, text)
    result = runner.invoke(app, ["run", str(path), "--no-store"], terminal_width=200)
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    return " ".join(result.output.split())


@pytest.mark.parametrize("csv_text, expected", [
    (None, "`data.file` 'cooling.csv': no such file"),
    ("minutes,temperature\n0,88\n2,abc\n", "line 3, column 'temperature': not a number ('abc')"),
    ("minutes,temperature\n0,88\n4,80\n2,82\n", "must increase strictly; data row 3 (t = 2) follows t = 4"),
    ("minutes,temperature\n0,88\n2,nan\n", "line 3, column 'temperature': 'nan' is not a finite number"),
    ("minutes,temperature\n0,88\n2\n", "line 3: 1 values, but the header names 2 columns"),
    ("minutes,temperature\n", "has a header but no rows of numbers"),
    ("time,temperature\n0,88\n", "`data.time` is 'minutes', which is not a column of 'cooling.csv'"),
    ("minutes,temp\n0,88\n", "`data.columns.T` is 'temperature', which is not a column of 'cooling.csv' "
                             "(its columns: minutes, temp)."),
    (b"\x89PNG\r\n\x1a\n\x00\x00secret", "is UTF-16 or binary, not a text table"),
])
def test_bad_csv(tmp_path, csv_text, expected):
    assert expected in _error(tmp_path, COOLING, csv_text)


def test_a_file_that_is_not_a_table_is_never_quoted(tmp_path):
    secret = 'password = "hunter2"\n[section]\nkey = 1\n'
    out = _error(tmp_path, COOLING, secret)
    assert "does not look like a data table" in out and "hunter2" not in out and "password" not in out


def test_a_data_file_outside_the_experiment_folder_is_refused(tmp_path):
    (tmp_path / "sub").mkdir()
    cooling_csv(tmp_path / "cooling.csv")
    text = COOLING.replace('file = "cooling.csv"', 'file = "../cooling.csv"')
    path = tmp_path / "sub" / "exp.toml"
    path.write_text(text)
    result = runner.invoke(app, ["run", str(path), "--no-store"], terminal_width=200)
    assert result.exit_code == 2 and "outside the experiment file's folder" in result.output


def test_data_larger_than_the_budgets(tmp_path, monkeypatch):
    import odelab.experiment.data as data

    cooling_csv(tmp_path / "cooling.csv")
    monkeypatch.setattr(data, "MAX_DATA_BYTES", 100)
    assert "bytes; data files are limited to 100 bytes" in _error(tmp_path, COOLING)
    monkeypatch.setattr(data, "MAX_DATA_BYTES", 10**6)
    monkeypatch.setattr(data, "MAX_DATA_ROWS", 5)
    assert "has more than 5 rows" in _error(tmp_path, COOLING)


@pytest.mark.parametrize("fit_text, expected", [
    ('parameters = { kk = {} }', "`fit.parameters.kk`: 'kk' is not a parameter of the experiment (the file's "
                                 "parameters: k, T0, T_room). Did you mean 'k'?"),
    ('parameters = { k = { initial = 5, lower = 0, upper = 1 } }', "the initial 5 is outside the bounds [0, 1]"),
    ('parameters = { k = { lower = 0.2 } }', "the value in [parameters] (0.1), the fit's start, 0.1 is outside"),
    ('parameters = { k = { lower = 1, upper = 1 } }', "lower = 1 must be below upper = 1"),
    ('parameters = { k = { start = 1 } }', "unknown key `fit.parameters.k.start`"),
    ('parameters = { k = {} }\nvalidat = "x.csv"', "unknown key `fit.validat`. Did you mean `validate`?"),
    ('parameters = { k = {} }\nquantities = ["x"]', "`fit.quantities[0]` is 'x', which no case's [data] measures"),
    ('parameters = { k = {} }\nmethod = "ode15s"', "`fit.method` is 'ode15s'"),
    ('parameters = {}', "`fit.parameters` is empty"),
    ('quantities = ["T"]', "`fit.parameters` is required"),
    ('parameters = { k = {} }\nmax_solves = 100000000', "`fit.max_solves` must be between 1 and 10,000"),
    ('parameters = { k = {} }\nrtol = 0.5', "`fit.rtol` must be between 0 and 0.01"),
])
def test_bad_fit(tmp_path, fit_text, expected):
    cooling_csv(tmp_path / "cooling.csv")
    assert expected in _error(tmp_path, COOLING + "\n[fit]\n" + fit_text + "\n")


def test_a_fitted_parameter_the_model_does_not_use(tmp_path):
    cooling_csv(tmp_path / "cooling.csv")
    text = COOLING.replace("T_room = 21", "T_room = 21\nunused = 3") + "\n[fit]\nparameters = { unused = {} }\n"
    assert "'unused' is not used by the model of any case with [data]" in _error(tmp_path, text)


def test_a_fitted_parameter_computed_from_others(tmp_path):
    cooling_csv(tmp_path / "cooling.csv")
    text = COOLING.replace("k = 0.1", 'k = "1/tau"\ntau = 10') + "\n[fit]\nparameters = { k = {} }\n"
    out = _error(tmp_path, text)
    assert "parameters.k = '1/tau' is computed from tau" in out and "fit tau instead" in out
    # fitting tau instead works: k is recomputed from it
    text = COOLING.replace("k = 0.1", 'k = "1/tau"\ntau = 10') + "\n[fit]\nparameters = { tau = {}, T0 = {} }\n"
    _, fit = fitted(write(tmp_path, text))
    assert fit["status"] == "converged" and 1 / 0.07 < fit["parameters"]["tau"]["estimate"] < 1 / 0.03


def test_fit_inside_a_case_and_without_data(tmp_path):
    cooling_csv(tmp_path / "cooling.csv")
    out = _error(tmp_path, COOLING + '\n[[case]]\nname = "a"\nfit.parameters = { k = {} }\n')
    assert "[fit] belongs to the whole file" in out
    out = _error(tmp_path, COOLING.split("[data]")[0] + FIT)
    assert "no case has [data]" in out


def test_sigma_for_some_quantities_only(tmp_path):
    cooling_csv(tmp_path / "cooling.csv")
    text = COOLING + FIT + '\n[[case]]\nname = "a"\ndata.sigma = { T = 0.4 }\n[[case]]\nname = "b"\n'
    assert "`data.sigma` is given for some fitted quantities but not for T in case 'b'" in _error(tmp_path, text)


def test_more_parameters_than_measurements(tmp_path):
    (tmp_path / "cooling.csv").write_text("minutes,temperature\n0,88\n2,83\n")
    assert "estimates 2 parameters from 2 measurements" in _error(tmp_path, COOLING + FIT)


def test_validate_with_without_a_fit(tmp_path):
    cooling_csv(tmp_path / "cooling.csv")
    path = write(tmp_path, COOLING)
    result = runner.invoke(app, ["run", str(path), "--no-store", "--validate-with", str(tmp_path / "cooling.csv")])
    assert result.exit_code == 2 and "no experiment has a [fit]" in result.output


def test_the_report_shows_the_fit_its_failure_and_the_warning(tmp_path):
    from odelab.report import build_report

    cooling_csv(tmp_path / "cooling.csv", seed=1)
    good = write(tmp_path, 'name = "good"\n' + COOLING + FIT, "good.toml")
    failed = write(tmp_path, 'name = "failed"\n' + COOLING + FIT + "max_solves = 2\n", "failed.toml")
    runs = tmp_path / "runs"
    result = runner.invoke(app, ["run", str(good), str(failed), "--runs", str(runs)])
    assert result.exit_code == 1, result.output
    report = build_report(runs, tmp_path / "report", formats="md", jobs=1)
    text = report.markdown.read_text()
    assert "### Parameter estimates" in text and "| k | 0.04" in text
    assert "The fit failed:" in text and "did not converge within 2 model solves" in text
    assert "figures/good-data.png" in text and "figures/good-residuals.png" in text


def test_trial_points_that_cannot_be_solved_are_counted_in_the_terminal_json_and_report(tmp_path):
    # NIST's BoxBOD from Start 1: the first trial point (b2 = -530.7) blows up; the fit goes on.
    from odelab.report import build_report

    assets = ROOT / "tests" / "assets" / "fit"
    for name in ("boxbod.toml", "boxbod.csv"):
        shutil.copy(assets / name, tmp_path / name)
    runs = tmp_path / "runs"
    result = runner.invoke(app, ["run", str(tmp_path / "boxbod.toml"), "--runs", str(runs)], terminal_width=200)
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert ("1 trial point where the model could not be solved (blow-up, NaN or max steps): rejected as a step of "
            "infinite cost") in text
    assert "b1 213.809" in text
    stored = json.loads(next(runs.rglob("result.json")).read_text())
    assert stored["extra"]["fit"]["failed_trials"] == 1 and stored["extra"]["fit"]["status"] == "converged"
    report = build_report(runs, tmp_path / "report", formats="md", jobs=1)
    assert "At 1 trial point the model could not be solved" in report.markdown.read_text()
