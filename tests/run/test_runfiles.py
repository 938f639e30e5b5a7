"""run_files: the core of `odelab run` loads, runs and stores, and says so in events; it never prints."""

from pathlib import Path

from odelab.run import runfiles as rf
from odelab.store.results import list_runs, read_run

TWO = """
[system]
states = ["x"]
[system.equations]
x = "-x"
[time]
stop = 1
[initial]
x = 1
[exact]
x = "exp(-t)"
[[case]]
name = "ode23"
solver.method = "ode23"
[[case]]
name = "ode45"
solver.method = "ode45"
"""


def test_events_of_a_run_with_a_good_and_a_bad_file(tmp_path, capsys):
    (tmp_path / "decay.toml").write_text(TWO)
    (tmp_path / "broken.toml").write_text("[system]\nstates = 1\n")
    runs = tmp_path / "runs"
    run = rf.run_files([tmp_path], rf.RunConfig(runs=runs, executor="serial"))
    events = list(run)
    kinds = [type(e).__name__ for e in events]
    assert kinds == ["FileError", "Started", "ExperimentStarted", "CaseDone", "CaseDone", "ExperimentDone",
                     "Finished"]
    assert events[0].message.startswith(str(tmp_path / "broken.toml"))
    assert events[1].total == 2 and run.total == 2 and run.finished == 2
    assert [(e.finished, e.failed) for e in events if isinstance(e, rf.CaseDone)] == [(1, 0), (2, 0)]
    done, finished = events[-2], events[-1]
    assert [r.case.name for r in done.results] == ["ode23", "ode45"]
    assert finished.stored == 2 and not finished.any_failed and finished.errors == (events[0].message,)
    folders = [p.relative_to(runs).as_posix() for p in list_runs(runs)]
    assert folders == ["decay/ode23", "decay/ode45"]
    assert all(read_run(runs / f)["status"] == "success" for f in folders)
    assert capsys.readouterr() == ("", "")  # the core never prints


def test_without_storing_nothing_is_written(tmp_path):
    (tmp_path / "decay.toml").write_text(TWO)
    events = list(rf.run_files([tmp_path / "decay.toml"], rf.RunConfig(runs=tmp_path / "runs", store=False,
                                                                        executor="serial")))
    assert events[-1].stored == 0 and not (tmp_path / "runs").exists()


def test_a_missing_path_is_an_error_line(tmp_path):
    events = list(rf.run_files([tmp_path / "nowhere.toml"]))
    assert isinstance(events[0], rf.FileError) and events[0].message.endswith("no such file or folder; check the path.")
    assert isinstance(events[-1], rf.Finished) and events[-1].errors
