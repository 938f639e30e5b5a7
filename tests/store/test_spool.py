"""A long compiled run's rows go to a spool beside its case's folder as the loop fills its blocks; the store
writes the case from it: the same bytes as from memory, nothing half-written left behind."""

import time
from pathlib import Path

import numpy as np
import pytest

from odelab.experiment.loader import load_experiment
from odelab.run import runfiles as rf
from odelab.run.runner import run_case
from odelab.solvers.compiled import rows
from odelab.store import results
from odelab.store.results import read_run, write_case
from odelab.store.spool import Spool, blocks, release, take

# The rigid body (MATLAB's Lab 5) over [0, 60] at Refine 4: 397 rows; in blocks of 7 rows the loop stops
# and resumes 57 times, and every full block goes to the spool.
RIGID = """
[system]
states = ["y1", "y2", "y3"]
[system.equations]
y1 = "y2*y3"
y2 = "-y1*y3"
y3 = "-0.51*y1*y2"
[initial]
y1 = 0
y2 = 1
y3 = 1
[time]
stop = 60
[solver]
method = "ode45"
backend = "compiled"
rtol = 1e-4
atol = [1e-4, 1e-4, 1e-5]
estimate_error = true
"""


@pytest.fixture
def small_blocks(monkeypatch):
    """Blocks of 7 rows (a step's 4 rows fit once each) and trajectory.npz from 100 rows on; the zip's times fixed."""
    monkeypatch.setattr(rows, "BLOCK_BYTES", 8 * 4 * 7)
    monkeypatch.setattr(results, "LONG_RUN_ROWS", 100)
    monkeypatch.setattr(time, "time", lambda: 1.7e9)


def _case(tmp_path):
    path = tmp_path / "rigid.toml"
    path.write_text(RIGID)
    return load_experiment(path).cases[0]


def _leftovers(runs: Path) -> list[str]:
    return sorted(p.relative_to(runs).as_posix() for p in runs.rglob("*")) if runs.exists() else []


def test_a_spooled_run_stores_the_bytes_of_the_run_in_memory(tmp_path, small_blocks):
    case = _case(tmp_path)
    memory = run_case(case)
    spooled = run_case(case, spool_in=tmp_path / "spooled")
    assert memory.spool is None and isinstance(spooled.t, np.memmap) and spooled.spool.rows == spooled.t.size == 397
    (folder,) = (tmp_path / "spooled" / "rigid").iterdir()  # the spool: a hidden sibling of the case's folder
    assert folder.name.startswith(".ode45.") and sorted(p.name for p in folder.iterdir()) == ["t.f64", "x.f64"]
    np.testing.assert_array_equal(spooled.t, memory.t)
    np.testing.assert_array_equal(spooled.x, memory.x)
    assert spooled.stats == memory.stats and spooled.estimate.pop("tight")["nsteps"] == memory.estimate.pop("tight")[
        "nsteps"] and spooled.estimate == memory.estimate  # the estimate read the maps
    a = write_case(memory, tmp_path / "memory")
    b = write_case(spooled, tmp_path / "spooled")
    assert (a / "trajectory.npz").read_bytes() == (b / "trajectory.npz").read_bytes()
    assert _leftovers(tmp_path / "spooled") == ["rigid", "rigid/ode45", "rigid/ode45/resolved.toml",
                                                "rigid/ode45/result.json", "rigid/ode45/trajectory.npz"]
    assert spooled.spool.folder is None  # handed over: the store renamed it into place
    record = read_run(b)
    assert record["points"] == 397 and np.array_equal(record["trajectory"]["y3"], memory.x[:, 2])
    np.testing.assert_array_equal(spooled.x, memory.x)  # the maps outlive their removed files (POSIX)


def test_a_short_run_never_touches_the_disk(tmp_path, monkeypatch):
    monkeypatch.setattr(results, "LONG_RUN_ROWS", 100)
    result = run_case(_case(tmp_path), spool_in=tmp_path / "runs")  # 397 rows fit one block of 65,536
    assert result.spool is None and not isinstance(result.t, np.memmap) and not (tmp_path / "runs").exists()


@pytest.mark.parametrize("error", [RuntimeError("the loop failed"), KeyboardInterrupt()])
def test_a_run_that_fails_midway_leaves_no_spool(tmp_path, small_blocks, monkeypatch, error):
    appended = []
    append = Spool.append

    def failing(self, t, y):  # the third full block (whole steps of 4 rows, and the first row): the spool holds two
        append(self, t, y)
        appended.append(t.size)
        if len(appended) == 3:
            raise error

    monkeypatch.setattr(Spool, "append", failing)
    runs = tmp_path / "runs"
    with pytest.raises(type(error)):
        run_case(_case(tmp_path), spool_in=runs)
    assert appended == [5, 4, 4] and _leftovers(runs) == []  # not even the experiment folder it made


def test_a_store_that_fails_midway_leaves_no_spool_and_no_case(tmp_path, small_blocks, monkeypatch):
    runs = tmp_path / "runs"
    result = run_case(_case(tmp_path), spool_in=runs)

    block = results._trajectory_block
    written = []

    def disk_full(*args):  # trajectory.npz's third block of 16 rows
        written.append(args[2:])
        if len(written) == 3:
            raise OSError(28, "No space left on device")
        return block(*args)

    monkeypatch.setattr(results, "NPZ_BLOCK_ROWS", 16)
    monkeypatch.setattr(results, "_trajectory_block", disk_full)
    with pytest.raises(OSError, match="No space left"):
        write_case(result, runs)
    assert written == [(0, 16), (16, 32), (32, 48)] and _leftovers(runs) == []


def test_a_dropped_spool_removes_its_folder(tmp_path, small_blocks):
    result = run_case(_case(tmp_path), spool_in=tmp_path / "runs")
    folder = result.spool.folder
    assert folder.is_dir()
    del result
    import gc

    gc.collect()
    assert not folder.exists()


def test_odelab_run_spools_a_long_compiled_run_and_stores_it(tmp_path, small_blocks):
    (tmp_path / "rigid.toml").write_text(RIGID)
    runs = tmp_path / "runs"
    events = list(rf.run_files([tmp_path / "rigid.toml"], rf.RunConfig(runs=runs, executor="serial")))
    done = next(e for e in events if isinstance(e, rf.ExperimentDone))
    (result,) = done.results
    assert isinstance(result.t, np.memmap) and result.spool.folder is None  # spooled, then stored from it
    assert _leftovers(runs) == ["rigid", "rigid/ode45", "rigid/ode45/resolved.toml", "rigid/ode45/result.json",
                                "rigid/ode45/trajectory.npz"]
    memory = run_case(_case(tmp_path))
    np.testing.assert_array_equal(read_run(runs / "rigid" / "ode45")["trajectory"]["y1"], memory.x[:, 0])


def test_a_results_folder_that_cannot_be_written_is_one_line(tmp_path, small_blocks):
    (tmp_path / "rigid.toml").write_text(RIGID)
    (tmp_path / "file").write_text("not a folder")
    runs = tmp_path / "file" / "runs"  # even root cannot make a folder in a file
    events = list(rf.run_files([tmp_path / "rigid.toml"], rf.RunConfig(runs=runs, executor="serial")))
    fatal = [e for e in events if isinstance(e, rf.Fatal)]
    assert [e.message for e in fatal] == [f"cannot write results to {runs}: [Errno 20] Not a directory: "
                                          f"'{runs / 'rigid'}'"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "rigid.toml"]


def test_blocks_and_take_read_a_map_as_the_array(tmp_path):
    values = np.random.default_rng(3).standard_normal((1000, 3))
    values.tofile(tmp_path / "x.f64")
    mapped = np.memmap(tmp_path / "x.f64", dtype=float, mode="r", shape=(1000, 3))
    column = mapped[:, 1]
    np.testing.assert_array_equal(np.concatenate(list(blocks(column, 64))), values[:, 1])
    picks = np.array([999, 0, 5, 5, 640, 3])
    got = take(column, picks)
    assert got.flags.owndata and not isinstance(got, np.memmap)
    np.testing.assert_array_equal(got, values[picks, 1])
    np.testing.assert_array_equal(take(mapped, picks), values[picks])
    release(mapped)  # pages handed back: read again from the file
    np.testing.assert_array_equal(mapped, values)
    release(values)  # an array in memory: nothing to do
    np.testing.assert_array_equal(take(values, picks), values[picks])
