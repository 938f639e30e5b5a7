"""Fixtures for the report tests: real runs made with ``odelab run``, and reports built from them.

The shipped experiments (``experiments/`` and ``experiments/networks/``, as the README runs them) are run through the CLI once per session, with two
test experiments from ``assets/``: ``msd_inputs`` (cases that differ by their input, as in
Exercise 2) and ``nonlinear_spring``, to whose stored run a linearisation study of the
documented ``extra["linearization"]`` shape is added by hand (see :func:`linearisation_study`).
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
ASSETS = HERE / "assets"

# the helper modules next to this file (report_support, report_browser)
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

from report_support import ROOT, Report, build  # noqa: E402

EXPERIMENTS = ROOT / "experiments"


def readme_folders() -> list[Path]:
    """The folders the README's first line runs (tests/test_readme.py checks they are every folder of
    shipped experiments): `odelab run experiments/ experiments/networks/`."""
    line = (ROOT / "README.md").read_text(encoding="utf-8").split("```sh\n", 1)[1].splitlines()[0]
    command = line.split("/odelab run ", 1)[1].split("&&", 1)[0]
    return [ROOT / word for word in command.split() if not word.startswith("-")]


def odelab_run(paths: list[Path], runs: Path):
    """``odelab run PATHS --runs RUNS`` through the real CLI (typer's CliRunner on odelab.cli.app)."""
    from typer.testing import CliRunner

    from odelab.cli import app

    return CliRunner().invoke(app, ["run", *map(str, paths), "--runs", str(runs)])


def linearisation_study(amplitudes=(0.1, 0.3, 1.0, 3.0, 10.0), threshold: float = 0.05) -> dict:
    """A linearisation study of nonlinear_spring.toml, in the shape the runner stores.

    x'' = (f - b x' - k x - k3 x^3) / m about x = 0, f = 0: A = [[0, 1], [-k/m, -b/m]],
    B = [[0], [1/m]], C = [[1, 0]], D = [[0]]. For each step amplitude the nonlinear and
    linearised responses are solved with odelab's ode45; the error is
    max |y_nonlinear - y_linear| / max |y_nonlinear|.
    """
    import odelab

    m, b, k, k3 = 1.0, 4.0, 3.0, 2.0
    t = np.linspace(0.0, 10.0, 201)
    comparisons, errors = [], []
    for a in amplitudes:
        nonlinear = odelab.ode45(lambda t, x, a=a: [x[1], (a - b * x[1] - k * x[0] - k3 * x[0] ** 3) / m], t,
                                 [0.0, 0.0], rtol=1e-8, atol=1e-10)
        linear = odelab.ode45(lambda t, x, a=a: [x[1], (a - b * x[1] - k * x[0]) / m], t, [0.0, 0.0],
                              rtol=1e-8, atol=1e-10)
        yn, yl = nonlinear.y[:, 0], linear.y[:, 0]
        errors.append(float(np.max(np.abs(yn - yl)) / np.max(np.abs(yn))))
        comparisons.append({"amplitude": a, "t": t.tolist(), "nonlinear": {"y": yn.tolist()},
                            "linear": {"y": yl.tolist()}})
    within = [a for a, e in zip(amplitudes, errors) if e <= threshold]
    return {
        "operating_point": {"x": {"x": 0.0, "v": 0.0}, "u": {"f": 0.0}, "y": {"y": 0.0}, "residual": 0.0},
        "A": [[0.0, 1.0], [-k / m, -b / m]], "B": [[0.0], [1.0 / m]], "C": [[1.0, 0.0]], "D": [[0.0]],
        "states": ["x", "v"], "inputs": ["f"], "outputs": ["y"],
        "threshold": threshold, "quantity": "y", "amplitudes": list(amplitudes),
        "errors": {"y": errors},
        "max_amplitude_within": max(within) if within else None,
        "comparisons": comparisons,
    }


def add_linearisation(case_folder: Path, study: dict) -> None:
    path = case_folder / "result.json"
    record = json.loads(path.read_text())
    record["extra"]["linearization"] = study
    path.write_text(json.dumps(record, indent=2))


@pytest.fixture(scope="session")
def study() -> dict:
    return linearisation_study()


@pytest.fixture(scope="session")
def lab_runs(tmp_path_factory, study) -> Path:
    """Runs of every shipped experiment plus the two test experiments, made by `odelab run`."""
    runs = tmp_path_factory.mktemp("lab") / "runs"
    shipped = odelab_run(readme_folders(), runs)
    assert shipped.exit_code == 0, shipped.output  # stiff.toml's ode45 stops as it says it will
    extra = odelab_run([ASSETS / "msd_inputs.toml", ASSETS / "nonlinear_spring.toml"], runs)
    assert extra.exit_code == 0, extra.output
    add_linearisation(runs / "nonlinear_spring" / "ode45", study)
    return runs


@pytest.fixture(scope="session")
def lab_report(lab_runs, tmp_path_factory) -> Report:
    return build(lab_runs, tmp_path_factory.mktemp("report"))


def shipped_names() -> list[str]:
    """The experiment names of the files the README's first line runs: the shipped report."""
    import tomllib

    names = []
    for path in sorted(p for folder in readme_folders() for p in folder.glob("*.toml")):
        name = tomllib.loads(path.read_text(encoding="utf-8")).get("name", path.stem)
        names.append(name)
    return names


@pytest.fixture(scope="session")
def shipped_report(lab_runs, tmp_path_factory) -> Report:
    """The report of the shipped experiments alone: what the README's first line gives."""
    return build(lab_runs, tmp_path_factory.mktemp("shipped-report"), experiments=shipped_names())


@pytest.fixture(scope="session")
def special_runs(tmp_path_factory, lab_runs) -> Path:
    """Exercise 1's runs, a hostile experiment, a failing one, and four broken case folders."""
    runs = tmp_path_factory.mktemp("special") / "runs"
    shutil.copytree(lab_runs / "exercise1", runs / "exercise1")
    result = odelab_run([ASSETS / "hostile.toml", ASSETS / "failing.toml"], runs)
    assert result.exit_code == 1, result.output  # the failing case
    good = lab_runs / "exercise1" / "ode23"
    (runs / "broken" / "json").mkdir(parents=True)
    (runs / "broken" / "json" / "result.json").write_text('{"format": "odelab-result/1", "experiment": ')
    (runs / "foreign" / "thing").mkdir(parents=True)
    (runs / "foreign" / "thing" / "result.json").write_text('{"format": "someone-else/2", "rows": []}')
    (runs / "foreign" / "thing" / "trajectory.csv").write_text("t\n0.0\n")
    (runs / "notraj" / "ode23").mkdir(parents=True)
    shutil.copy(good / "result.json", runs / "notraj" / "ode23" / "result.json")
    (runs / "badcsv" / "ode23").mkdir(parents=True)
    shutil.copy(good / "result.json", runs / "badcsv" / "ode23" / "result.json")
    (runs / "badcsv" / "ode23" / "trajectory.csv").write_text("t,y\n0.0,2.0\n0.5,not-a-number\n")
    return runs


@pytest.fixture(scope="session")
def special_report(special_runs, tmp_path_factory) -> Report:
    return build(special_runs, tmp_path_factory.mktemp("special-report"))
