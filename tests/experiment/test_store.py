"""The results store: atomic writes, JSON safety, reading back."""

import math
from pathlib import Path

import numpy as np
import pytest

from odelab.experiment.loader import load_experiment
from odelab.experiment.runner import run_case
from odelab.experiment.store import atomic_write, list_runs, read_run, write_case

ROOT = Path(__file__).resolve().parents[2]


def test_atomic_write_replaces_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "a" / "file.txt"
    atomic_write(target, "one")
    atomic_write(target, "two")
    assert target.read_text() == "two"
    assert [p.name for p in target.parent.iterdir()] == ["file.txt"]


def test_atomic_write_failure_keeps_the_old_file(tmp_path):
    target = tmp_path / "file.txt"
    atomic_write(target, "old")

    with pytest.raises(TypeError):
        atomic_write(target, object())  # cannot be encoded: fails mid-write
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["file.txt"]


def test_write_and_read_a_case(tmp_path):
    exp = load_experiment(ROOT / "experiments" / "exercise1.toml")
    result = run_case(exp.cases[0])
    folder = write_case(result, tmp_path)
    assert folder == tmp_path / "exercise1" / "ode23"
    record = read_run(folder)
    assert record["status"] == "success" and record["points"] == 12
    assert record["stats"] == {"nsteps": 11, "nfailed": 0, "nfevals": 34}
    assert record["file_sha256"] == exp.file_hash and record["versions"]["numpy"] == np.__version__
    traj = record["trajectory"]
    assert list(traj) == ["t", "y", "y_ref", "y_abs_err", "y_rel_err"]
    assert f"{traj['y_rel_err'].max():.3e}" == "1.068e-04"
    np.testing.assert_array_equal(traj["t"], result.t)  # repr round-trips doubles exactly
    assert list_runs(tmp_path) == [folder]


def test_undefined_relative_errors_are_null_in_json_and_empty_in_csv(tmp_path):
    path = tmp_path / "sine.toml"
    path.write_text('[system]\nstates = ["y"]\n[system.equations]\ny = "cos(t)"\n[initial]\ny = 0\n'
                    '[time]\nstop = 3\n[exact]\ny = "sin(t)"\n')
    result = run_case(load_experiment(path).cases[0])
    assert result.errors["y"].undefined == 1  # y(0) = 0
    assert any("relative error undefined where the reference is zero or tiny" in w and "y (1)" in w
               for w in result.warnings)
    folder = write_case(result, tmp_path / "runs")
    text = (folder / "result.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    csv_first_row = (folder / "trajectory.csv").read_text().splitlines()[1].split(",")
    assert csv_first_row[-1] == ""
    assert math.isnan(read_run(folder)["trajectory"]["y_rel_err"][0])
