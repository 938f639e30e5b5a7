"""When the store flushes to disk (store.py's rule): every file before the rename that shows it, a new
case's folder once per run, a replaced case's folder before the previous case is removed."""

import os
from pathlib import Path

from odelab.run import runfiles as rf
from odelab.store import results as store
from odelab.store.results import list_runs, read_run

from ..run.test_runfiles import TWO as FILE  # one experiment, cases ode23 and ode45


def _record(monkeypatch) -> list[tuple]:
    """The store's fsyncs (by path), renames and removals, in order."""
    log: list[tuple] = []
    fsync, rename, remove = os.fsync, os.rename, store._remove

    def on_fsync(fd):
        log.append(("fsync", Path(os.readlink(f"/proc/self/fd/{fd}"))))
        return fsync(fd)

    def on_rename(src, dst):
        log.append(("rename", Path(src), Path(dst)))
        return rename(src, dst)

    def on_remove(path):
        log.append(("remove", Path(path)))
        return remove(path)

    monkeypatch.setattr(store.os, "fsync", on_fsync)
    monkeypatch.setattr(store.os, "rename", on_rename)
    monkeypatch.setattr(store, "_remove", on_remove)
    return log


def _batch(tmp_path, files: int) -> Path:
    batch = tmp_path / "batch"
    batch.mkdir(exist_ok=True)
    for i in range(files):
        (batch / f"e{i}.toml").write_text(FILE)
    return batch


def _run(batch, runs) -> list:
    return list(rf.run_files([batch], rf.RunConfig(runs=runs, executor="serial")))


def test_a_run_flushes_each_file_before_its_rename_and_each_new_experiment_folder_once_at_the_end(
        tmp_path, monkeypatch):
    runs = tmp_path / "runs"
    batch = _batch(tmp_path, 3)
    log = _record(monkeypatch)
    events = _run(batch, runs)
    assert events[-1].stored == 6
    renames = [i for i, e in enumerate(log) if e[0] == "rename"]
    assert len(renames) == 6 and not any(e[0] == "remove" for e in log)  # six new cases, nothing replaced
    for i in renames:
        _, tmp, final = log[i]
        flushed = [e[1] for e in log[:i] if e[0] == "fsync" and e[1].parent == tmp]
        assert sorted(p.name for p in flushed) == ["resolved.toml", "result.json", "trajectory.csv"]
        assert sorted(p.name for p in final.iterdir()) == ["resolved.toml", "result.json", "trajectory.csv"]
    folders = [e[1] for e in log if e[0] == "fsync" and e[1].is_dir()]
    # no folder flush per case: each experiment folder once, after the last case is in place
    assert sorted(folders) == sorted(runs.resolve() / f"e{i}" for i in range(3))
    assert all(log.index(("fsync", f)) > renames[-1] for f in folders)
    assert sum(e[0] == "fsync" for e in log) == 6 * 3 + 3  # three files a case, one folder an experiment


def test_a_replaced_case_has_its_folder_flushed_before_the_previous_case_is_removed(tmp_path, monkeypatch):
    runs = tmp_path / "runs"
    batch = _batch(tmp_path, 1)
    _run(batch, runs)
    log = _record(monkeypatch)
    _run(batch, runs)
    experiment = runs.resolve() / "e0"
    for case in ("ode23", "ode45"):
        put = log.index(next(e for e in log if e[0] == "rename" and e[2].resolve() == experiment / case))
        removed = log.index(next(e for e in log[put:] if e[0] == "remove"))
        assert ("fsync", experiment) in log[put + 1:removed]
    assert [read_run(p)["case"] for p in list_runs(runs)] == ["ode23", "ode45"]


def test_an_interrupted_run_flushes_the_folders_of_the_cases_it_stored(tmp_path, monkeypatch):
    runs = tmp_path / "runs"
    batch = _batch(tmp_path, 2)
    log = _record(monkeypatch)
    events = iter(rf.run_files([batch], rf.RunConfig(runs=runs, executor="serial")))
    while not isinstance(next(events), rf.CaseDone):  # the first case is stored
        pass
    try:
        events.throw(KeyboardInterrupt())  # as the CLI passes on a Ctrl-C
    except KeyboardInterrupt:
        pass
    stored = list_runs(runs)
    assert stored and all(("fsync", p.parent.resolve()) in log for p in stored)
    assert [e[1] for e in log if e[0] == "fsync" and e[1].is_dir()] == [runs.resolve() / "e0"]
