"""The results store: atomic writes, JSON safety, reading back."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from odelab.experiment.loader import load_experiment, load_experiments
from odelab.run.runner import run_case
from odelab.store.results import atomic_write, list_runs, read_run, write_case

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


def _two_runs(tmp_path):
    """Exercise 1's ode23 case at the lab's tolerance and at a tighter one (different trajectories)."""
    text = (ROOT / "experiments" / "exercise1.toml").read_text()
    path = tmp_path / "exercise1.toml"
    path.write_text(text)
    first = run_case(load_experiment(path).cases[0])
    path.write_text(text.replace('method = "ode23"', 'method = "ode23"\nrtol = 1e-6', 1))
    second = run_case(load_experiment(path).cases[0])
    assert first.t.size != second.t.size
    return first, second


def test_a_case_folder_holds_only_the_documented_files(tmp_path):
    first, _ = _two_runs(tmp_path)
    folder = write_case(first, tmp_path / "runs")
    write_case(first, tmp_path / "runs")
    assert sorted(p.name for p in folder.iterdir()) == ["resolved.toml", "result.json", "trajectory.csv"]
    assert sorted(p.name for p in folder.parent.iterdir()) == ["ode23"]  # no .lock, no temporary folders


@pytest.mark.parametrize("fail_at", ["resolved.toml", "result.mat", "result.json"])
def test_a_failed_write_leaves_the_previous_case_whole(tmp_path, monkeypatch, fail_at):
    """Disk full after trajectory.csv was written: the stored case is still entirely the previous run."""
    import os

    import odelab.store.results as store

    first, second = _two_runs(tmp_path)
    folder = write_case(first, tmp_path / "runs")
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    real_open = os.open

    def failing_open(path, *args, **kwargs):
        if str(path).endswith(fail_at):
            raise OSError(28, "No space left on device")
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(store.os, "open", failing_open)
    with pytest.raises(OSError, match="No space left"):
        write_case(second, tmp_path / "runs", mat=True)
    monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    record = read_run(folder)
    assert record["points"] == first.t.size == len(record["trajectory"]["t"])
    assert sorted(p.name for p in folder.parent.iterdir()) == ["ode23"]


def test_a_failed_swap_puts_the_previous_case_back(tmp_path, monkeypatch):
    import odelab.store.results as store

    first, second = _two_runs(tmp_path)
    folder = write_case(first, tmp_path / "runs")
    before = {p.name: p.read_bytes() for p in folder.iterdir()}

    real_rename = store.os.rename

    renames = []

    def failing_rename(src, dst):  # the swap of the new folder in fails; putting the old one back works
        renames.append((Path(src).name, Path(dst).name))
        if str(src).endswith(".tmp") and ".old." not in str(src):
            raise PermissionError(13, "Permission denied")
        real_rename(src, dst)

    monkeypatch.setattr(store.os, "rename", failing_rename)
    with pytest.raises(PermissionError):
        write_case(second, tmp_path / "runs")
    monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert sorted(p.name for p in folder.parent.iterdir()) == ["ode23"]
    away, new_in, back = renames  # the old case away, the new one in (failed), the old one back
    assert away[0] == "ode23" and away[1].startswith(".ode23.old.") and back == (away[1], "ode23")
    assert new_in[0].startswith(".ode23.") and new_in[1] == "ode23"


def test_a_new_run_without_mat_does_not_keep_the_old_result_mat(tmp_path):
    first, second = _two_runs(tmp_path)
    folder = write_case(first, tmp_path / "runs", mat=True)
    assert (folder / "result.mat").exists()
    write_case(second, tmp_path / "runs")
    assert not (folder / "result.mat").exists()
    assert read_run(folder)["points"] == second.t.size


def test_version_lookups_happen_once_per_process(tmp_path, monkeypatch):
    import odelab.store.results as store

    first, _ = _two_runs(tmp_path)
    write_case(first, tmp_path / "runs")
    calls = []
    monkeypatch.setattr(store.metadata, "version", lambda dist: calls.append(dist) or "0")
    write_case(first, tmp_path / "runs")
    write_case(first, tmp_path / "runs2", durable=False)
    assert calls == []


def test_the_stored_odelab_version_is_the_installed_one(tmp_path):
    from importlib import metadata

    first, _ = _two_runs(tmp_path)
    record = read_run(write_case(first, tmp_path / "runs"))
    assert record["versions"]["odelab"] == metadata.version("odelab")
    assert record["versions"]["scipy"] == metadata.version("scipy")


@pytest.mark.parametrize("name", ["exercise1.toml", "exercise2.toml", "damping.toml", "bouncing_ball.toml"])
def test_result_json_is_the_standard_librarys_text(tmp_path, name):
    import json

    for exp in load_experiments(ROOT / "experiments" / name):
        for case in exp.cases[:2]:
            text = (write_case(run_case(case), tmp_path / "runs") / "result.json").read_text(encoding="utf-8")
            assert text == json.dumps(json.loads(text), indent=2, allow_nan=False) + "\n"


@pytest.mark.parametrize("record", [
    {}, [], {"a": {}, "b": [], "c": [[]], "d": [{}]},
    {"é中文\u2028\x00\"\\/": ["\x1b[31m", "tab\t", ""], "n": [0, -0.0, 1e-320, 1e22, 2 ** 70, -5, 0.1, True, False,
                                                          None]},
    {"tuple": (1, (2.5, "x")), "deep": [[[[{"k": [1]}]]]]},
    {1: "int key", None: 2, 2.5: 3},  # not plain: left to json.dumps
])
def test_result_json_writes_what_json_dumps_writes(record):
    import json

    from odelab.store.results import result_json

    assert result_json(record) == json.dumps(record, indent=2, allow_nan=False) + "\n"


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_result_json_refuses_nan_and_infinity_as_json_does(bad):
    import json

    from odelab.store.results import result_json

    with pytest.raises(ValueError) as ours:
        result_json({"x": [1, {"y": bad}]})
    with pytest.raises(ValueError) as theirs:
        json.dumps({"x": [1, {"y": bad}]}, indent=2, allow_nan=False)
    assert str(ours.value) == str(theirs.value)


def test_infinity_in_result_json_is_a_broken_record(tmp_path):
    first, _ = _two_runs(tmp_path)
    folder = write_case(first, tmp_path / "runs")
    path = folder / "result.json"
    path.write_text(re.sub(r'"points": \d+', '"points": Infinity', path.read_text()))
    assert "Infinity" in path.read_text()
    with pytest.raises(ValueError, match="result.json holds Infinity, which odelab never writes"):
        read_run(folder)


def test_hidden_temporary_folders_are_not_runs(tmp_path):
    first, _ = _two_runs(tmp_path)
    folder = write_case(first, tmp_path / "runs")
    left = folder.parent / ".ode23.abc123.tmp"  # what a run killed with SIGKILL mid-write leaves
    left.mkdir()
    for p in folder.iterdir():
        (left / p.name).write_bytes(p.read_bytes())
    assert list_runs(tmp_path / "runs") == [folder]


@pytest.mark.parametrize("replacement, message", [
    ('"points": 1e400', "result.json holds 1e400, which overflows a double"),
    ('"points": ' + "[" * 100_000 + "]" * 100_000, "result.json nests arrays or objects too deeply"),
])
def test_hostile_numbers_and_nesting_in_result_json_are_broken_records(tmp_path, replacement, message):
    first, _ = _two_runs(tmp_path)
    folder = write_case(first, tmp_path / "runs")
    path = folder / "result.json"
    path.write_text(re.sub(r'"points": \d+', lambda m: replacement, path.read_text()))
    with pytest.raises(ValueError, match=message):
        read_run(folder)


def test_a_symlink_in_place_of_a_case_folder_is_replaced_not_followed(tmp_path):
    first, _ = _two_runs(tmp_path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "keep.txt").write_text("not odelab's")
    folder = tmp_path / "runs" / "exercise1" / "ode23"
    folder.parent.mkdir(parents=True)
    folder.symlink_to(elsewhere, target_is_directory=True)
    write_case(first, tmp_path / "runs")
    assert not folder.is_symlink() and read_run(folder)["points"] == first.t.size
    assert [p.name for p in elsewhere.iterdir()] == ["keep.txt"]  # nothing written or removed there
    assert sorted(p.name for p in folder.parent.iterdir()) == ["ode23"]


def test_long_runs_store_a_binary_trajectory_instead_of_the_csv(tmp_path, monkeypatch):
    from odelab.store import results as store

    result = run_case(load_experiment(ROOT / "experiments" / "rigid_body.toml").cases[0])
    csv_record = read_run(write_case(result, tmp_path / "csv"))
    assert csv_record["trajectory_file"] == "trajectory.csv"
    monkeypatch.setattr(store, "LONG_RUN_ROWS", result.t.size - 1)  # 85 rows: "long" for this test
    folder = write_case(result, tmp_path / "npz")
    assert sorted(p.name for p in folder.iterdir()) == ["resolved.toml", "result.json", "trajectory.npz"]
    record = read_run(folder)
    assert record["trajectory_file"] == "trajectory.npz"
    assert list(record["trajectory"]) == list(csv_record["trajectory"]) == [
        "t", "y1", "y2", "y3", "y1_ref", "y1_abs_err", "y1_rel_err", "y2_ref", "y2_abs_err", "y2_rel_err",
        "y3_ref", "y3_abs_err", "y3_rel_err"]
    for name, values in csv_record["trajectory"].items():  # the CSV's repr round-trips: the same doubles
        np.testing.assert_array_equal(record["trajectory"][name], values)
    np.testing.assert_array_equal(record["trajectory"]["y2"], result.x[:, 1])
    (folder / "trajectory.npz").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(ValueError, match="trajectory.npz is not a readable odelab trajectory"):
        read_run(folder)


def test_the_run_step_budget_says_how_to_lift_it(tmp_path):
    case = load_experiment(ROOT / "experiments" / "rigid_body.toml").cases[0]
    result = run_case(case, max_steps=5)
    assert result.status == "failed" and result.stats.nsteps == 5
    assert result.message.endswith(
        "It was odelab run's step budget that stopped it (--max-steps, 5 steps): lift it with --max-steps 50 "
        "(or --max-steps 0 for no limit).")


@pytest.mark.parametrize("asked", [0, 10**12])
def test_a_file_cannot_lift_the_run_step_budget(asked):
    """[solver] max_steps = 0 ("no limit") or 10^12 runs within odelab run's --max-steps, and says so."""
    import dataclasses

    case = load_experiment(ROOT / "experiments" / "rigid_body.toml").cases[0]
    problem = dataclasses.replace(case.problem, solver_options=case.problem.solver_options.updated(max_steps=asked))
    result = run_case(dataclasses.replace(case, problem=problem), max_steps=5)
    assert result.status == "failed" and result.stats.nsteps == 5
    assert f"[solver] asks max_steps = {asked:,}" in result.message
    assert "a file cannot lift the budget of whoever runs it" in result.message


def test_the_whole_block_csv_is_the_value_by_value_text_and_round_trips(tmp_path):
    from odelab.store.results import _trajectory_csv

    values = [0.0, -0.0, 0.1, 1e-05, 1e-4, 123456789012345680.0, 1.0000000000000002, -2.5e-310, math.inf,
              -math.inf, math.nan, 1 / 3, 6.02214076e23]
    data = np.array([values, values[::-1], [math.nan] * len(values)])
    text = _trajectory_csv([f"c{i}" for i in range(len(values))], data)
    expected = [",".join(f"c{i}" for i in range(len(values)))]
    expected += [",".join("" if v != v else repr(v) for v in row) for row in data.tolist()]
    assert text == "\n".join(expected) + "\n"
    assert text.splitlines()[1] == ("0.0,-0.0,0.1,1e-05,0.0001,1.2345678901234568e+17,1.0000000000000002,"
                                    "-2.5e-310,inf,-inf,,0.3333333333333333,6.02214076e+23")
    assert text.splitlines()[3] == "," * (len(values) - 1)
    back = np.array([[float(v) if v else math.nan for v in line.split(",")] for line in text.splitlines()[1:]])
    np.testing.assert_array_equal(back, data)  # equal doubles, NaN where NaN, the sign of -0.0 kept
    assert math.copysign(1, back[0, 1]) == -1
    assert _trajectory_csv(["t", "y"], np.empty((0, 2))) == "t,y\n"


@pytest.mark.parametrize("rows", [0, 1, 7, 64, 65, 200])
def test_the_streamed_npz_is_np_savez_of_the_whole_block_byte_for_byte(monkeypatch, rows):
    # trajectory.npz is written a block of rows at a time from the run's columns, never as one block: the
    # same archive np.savez(f, names=..., data=block) writes (the zip's times fixed for the comparison)
    import io
    import time

    from odelab.store import results

    monkeypatch.setattr(results, "NPZ_BLOCK_ROWS", 16)
    rng = np.random.default_rng(7)
    columns = {"t": np.linspace(0.0, 1.0, rows), "x": rng.standard_normal(rows), "event": np.arange(rows) % 3,
               "v": rng.standard_normal((rows, 2))[:, 1]}  # a strided view, as a state column of y
    block = np.empty((rows, len(columns)))
    for i, values in enumerate(columns.values()):
        block[:, i] = values
    monkeypatch.setattr(time, "time", lambda: 1.7e9)
    expected, streamed = io.BytesIO(), io.BytesIO()
    np.savez(expected, names=np.array(list(columns), dtype=str), data=block)
    results._trajectory_npz(columns, rows)(streamed)
    assert streamed.getvalue() == expected.getvalue()
    with np.load(io.BytesIO(streamed.getvalue())) as back:
        assert back["data"].tobytes() == block.tobytes() and list(back["names"]) == list(columns)


def test_reading_stored_runs_imports_neither_the_loader_nor_pydantic(tmp_path):
    """The report reads runs: it needs no experiment schema (pydantic's models cost tens of ms to build)."""
    import subprocess
    import sys

    folder = write_case(run_case(load_experiment(ROOT / "experiments" / "exercise1.toml").cases[0]), tmp_path)
    code = ("import sys\nfrom odelab.store.results import list_runs, read_run\n"
            f"assert read_run(list_runs({str(tmp_path)!r})[0])['points'] == 12\n"
            "print(sorted(m for m in ('pydantic', 'odelab.experiment.loader') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]" and folder.name == "ode23"
