"""What a failed or killed run leaves in the results folder (odelab.store.hidden): a failed run nothing, not
even an empty experiment folder; a run killed with SIGKILL its hidden temporary folder, which the next
`odelab run` removes, saying so, while a live run's folder is never touched."""

import fcntl
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.run import runfiles as rf
from odelab.store import hidden
from odelab.store.hidden import Stale, new_hidden_folder, remove_if_empty, remove_stale
from odelab.store.spool import Spool

from .test_spool import RIGID, _leftovers, small_blocks  # noqa: F401 - the fixture

ROOT = Path(__file__).resolve().parents[2]

# A run's spool, mid-run: three blocks of 1,000 rows of three states written (t.f64 24,000 bytes, x.f64
# 72,000), then the child waits for a line on stdin (a live run) or for its SIGKILL (the OOM killer).
SPOOLING = """
import sys
from pathlib import Path
import numpy as np
from odelab.store.spool import Spool
spool = Spool(Path(sys.argv[1]))
for block in range(3):
    spool.append(np.arange(1000.0) + 1000 * block, np.ones((1000, 3)))
print(spool.folder.name, flush=True)
sys.stdin.readline()
"""

# The atomic case writer, mid-write: result.json written (2 bytes), trajectory.npz 5,000 bytes into its
# data; and, given a second argument, a replaced case mid-removal (its .old. folder).
WRITING = """
import sys
from pathlib import Path
from odelab.store import results
def trajectory(f):
    f.write(b"x" * 5000)
    f.flush()
    if len(sys.argv) == 2:
        print("writing", flush=True)
        sys.stdin.readline()
def removing(path):
    print(Path(path).name, flush=True)
    sys.stdin.readline()
results._remove = removing
results.commit_folder(Path(sys.argv[1]), {"result.json": "{}", "trajectory.npz": trajectory})
"""


def child(script: str, *args) -> tuple[subprocess.Popen, str]:
    """A process running ``script``, once it has said it is ready (its first line)."""
    proc = subprocess.Popen([sys.executable, "-c", script, *map(str, args)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    line = proc.stdout.readline().strip()
    assert line, proc.wait()
    return proc, line


def killed(proc: subprocess.Popen) -> int:
    proc.send_signal(signal.SIGKILL)
    assert proc.wait(timeout=30) == -signal.SIGKILL
    return proc.pid


def test_a_run_killed_mid_spool_leaves_its_folder_for_the_next_run_to_remove(tmp_path):
    runs = tmp_path / "runs"
    proc, name = child(SPOOLING, runs / "long" / "ode45")
    folder = runs / "long" / name
    assert name.startswith(".ode45.") and name.endswith(f".{proc.pid}.tmp")
    pid = killed(proc)
    assert sorted(p.name for p in folder.iterdir()) == ["t.f64", "x.f64"]  # what SIGKILL leaves
    assert remove_stale(runs) == [Stale(folder, 96_000, pid)]
    assert _leftovers(runs) == []  # and the experiment folder it leaves empty
    assert remove_stale(runs) == []


def test_a_run_killed_mid_write_of_a_case_leaves_its_folder_for_the_next_run_to_remove(tmp_path):
    runs = tmp_path / "runs"
    (runs / "exp" / "other").mkdir(parents=True)  # another case: it stays, and so does its experiment folder
    proc, _ = child(WRITING, runs / "exp" / "case")
    (name,) = [p.name for p in (runs / "exp").iterdir() if p.name.startswith(".")]
    pid = killed(proc)
    assert sorted(p.name for p in (runs / "exp" / name).iterdir()) == ["result.json", "trajectory.npz"]
    assert remove_stale(runs) == [Stale(runs / "exp" / name, 5002, pid)]
    assert _leftovers(runs) == ["exp", "exp/other"]


def test_a_run_killed_while_removing_a_replaced_case_leaves_it_for_the_next_run(tmp_path):
    runs = tmp_path / "runs"
    (runs / "exp" / "case").mkdir(parents=True)
    (runs / "exp" / "case" / "result.json").write_text("the previous run's")
    proc, name = child(WRITING, runs / "exp" / "case", "replace")
    assert name.startswith(".case.old.") and name.endswith(f".{proc.pid}.tmp")
    pid = killed(proc)
    assert remove_stale(runs) == [Stale(runs / "exp" / name, 18, pid)]
    assert _leftovers(runs) == ["exp", "exp/case", "exp/case/result.json", "exp/case/trajectory.npz"]
    assert (runs / "exp" / "case" / "result.json").read_text() == "{}"  # the new case, whole


def test_a_live_concurrent_runs_folder_is_never_removed(tmp_path):
    runs = tmp_path / "runs"
    proc, name = child(SPOOLING, runs / "long" / "ode45")
    try:
        assert remove_stale(runs) == []
        assert sorted(p.name for p in (runs / "long" / name).iterdir()) == ["t.f64", "x.f64"]
    finally:
        proc.stdin.close()  # the run ends: it removes its spool, and the experiment folder it made
        assert proc.wait(timeout=30) == 0
    assert _leftovers(runs) == []


def test_this_processs_own_live_spool_is_never_removed(tmp_path):
    spool = Spool(tmp_path / "runs" / "long" / "ode45")
    spool.append(np.arange(10.0), np.ones((10, 2)))
    assert remove_stale(tmp_path / "runs") == [] and spool.folder.is_dir()
    spool.discard()
    assert _leftovers(tmp_path / "runs") == []


def test_folders_whose_owner_cannot_be_tested_are_left_alone(tmp_path):
    runs = tmp_path / "runs"
    legacy = runs / "exp" / ".ode23.abc123abc123.tmp"  # named before the locks: its owner cannot be tested
    legacy.mkdir(parents=True)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "keep.txt").write_text("not odelab's")
    (runs / "exp" / ".ode45.abcdef012345.1.tmp").symlink_to(elsewhere, target_is_directory=True)
    assert remove_stale(runs) == []
    assert _leftovers(runs) == ["exp", "exp/.ode23.abc123abc123.tmp", "exp/.ode45.abcdef012345.1.tmp"]
    assert [p.name for p in elsewhere.iterdir()] == ["keep.txt"]


def test_no_stale_folder_search_looks_while_a_folder_is_made_and_not_yet_held(tmp_path, monkeypatch):
    """The window between a hidden folder's mkdir and its owner's lock: the experiment folder is locked
    shared, so a search (which locks it exclusive) cannot look."""
    seen = []
    mkdir = os.mkdir

    def made(path, mode=0o777):
        mkdir(path, mode)
        if Path(path).name.startswith(".case."):
            fd = os.open(Path(path).parent, os.O_RDONLY)
            try:
                with pytest.raises(BlockingIOError):
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                seen.append(Path(path).name)
            finally:
                os.close(fd)

    monkeypatch.setattr(hidden.os, "mkdir", made)
    folder = new_hidden_folder(tmp_path / "exp", "case")
    monkeypatch.undo()
    assert seen == [folder.path.name] and hidden._take(folder.path) is None  # then held
    folder.remove()
    assert not (tmp_path / "exp").exists()


def test_a_writer_makes_its_experiment_folder_again_if_another_run_removed_it_as_empty(tmp_path, monkeypatch):
    """Another run's cleanup may remove the (empty) experiment folder between a writer's mkdir of it and
    the writer's own folder in it: the writer makes it again."""
    mkdir = os.mkdir
    removed = []

    def raced(path, mode=0o777):
        if Path(path).name.startswith(".case.") and not removed:
            removed.append(remove_if_empty(Path(path).parent))  # the other run, just then
        mkdir(path, mode)

    monkeypatch.setattr(hidden.os, "mkdir", raced)
    folder = new_hidden_folder(tmp_path / "exp", "case")
    monkeypatch.undo()
    assert removed == [True] and folder.path.is_dir() and folder.path.parent == tmp_path / "exp"
    folder.remove()


def test_an_experiment_folder_holding_anything_is_never_removed(tmp_path):
    (tmp_path / "exp" / "case").mkdir(parents=True)
    assert remove_if_empty(tmp_path / "exp") is False and (tmp_path / "exp" / "case").is_dir()
    assert remove_if_empty(tmp_path / "exp" / "case") is True and remove_if_empty(tmp_path / "nothing") is False


def test_an_interrupted_run_leaves_no_empty_folder(tmp_path, small_blocks, monkeypatch):
    """Ctrl-C while a long run spools, into a new results folder: nothing is left, not runs/ nor runs/rigid/."""
    (tmp_path / "rigid.toml").write_text(RIGID)
    append = Spool.append

    def interrupted(self, t, y):
        append(self, t, y)
        raise KeyboardInterrupt

    monkeypatch.setattr(Spool, "append", interrupted)
    runs = tmp_path / "runs"
    with pytest.raises(KeyboardInterrupt):
        list(rf.run_files([tmp_path / "rigid.toml"], rf.RunConfig(runs=runs, executor="serial")))
    assert not runs.exists()
    (runs / "other" / "case").mkdir(parents=True)  # a results folder holding another run's results
    with pytest.raises(KeyboardInterrupt):
        list(rf.run_files([tmp_path / "rigid.toml"], rf.RunConfig(runs=runs, executor="serial")))
    assert _leftovers(runs) == ["other", "other/case"]


def test_a_case_that_cannot_be_stored_leaves_no_empty_experiment_folder(tmp_path, monkeypatch):
    from odelab.store import results

    (tmp_path / "exp.toml").write_text((ROOT / "experiments" / "exercise1.toml").read_text())
    runs = tmp_path / "runs"
    (runs / "other").mkdir(parents=True)

    def full(path, data, durable):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(results, "_write_file", full)
    events = list(rf.run_files([tmp_path / "exp.toml"], rf.RunConfig(runs=runs, executor="serial")))
    assert [e.message for e in events if isinstance(e, rf.Fatal)] == [
        f"cannot write results to {runs}: [Errno 28] No space left on device"]
    assert _leftovers(runs) == ["other"]


def test_odelab_run_says_what_it_removed_in_one_line(tmp_path):
    runs = tmp_path / "runs"
    proc, name = child(SPOOLING, runs / "long" / "ode45")
    pid = killed(proc)
    (tmp_path / "exercise1.toml").write_text((ROOT / "experiments" / "exercise1.toml").read_text())
    result = CliRunner().invoke(app, ["run", str(tmp_path / "exercise1.toml"), "--runs", str(runs)])
    assert result.exit_code == 0, result.output
    assert result.stderr.splitlines() == [
        f"note: removed {runs}/long/{name} (96.0 kB), left by a killed run."]
    assert name.endswith(f".{pid}.tmp")  # whose it was
    assert _leftovers(runs)[:1] == ["exercise1"] and not (runs / "long").exists()


def test_odelab_run_json_lists_what_it_removed(tmp_path):
    import json

    runs = tmp_path / "runs"
    proc, name = child(SPOOLING, runs / "long" / "ode45")
    pid = killed(proc)
    (tmp_path / "exercise1.toml").write_text((ROOT / "experiments" / "exercise1.toml").read_text())
    result = CliRunner().invoke(app, ["run", str(tmp_path / "exercise1.toml"), "--runs", str(runs), "--json"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert document["removed"] == [{"path": f"{runs}/long/{name}", "bytes": 96_000, "pid": pid}]
    assert [e["name"] for e in document["experiments"]] == ["exercise1"]


def test_the_line_for_several_removed_folders(tmp_path):
    from odelab.cli.app import leftovers_line

    removed = [Stale(Path("runs/a/.ode45.abcdef012345.11.tmp"), 126_400_000, 11),
               Stale(Path("runs/b/.x.old.abcdef012345.11.tmp"), 300, 11),
               Stale(Path("runs/c/.y.abcdef012345.12.tmp"), 100_000, 12)]
    assert leftovers_line(removed) == (
        "removed 3 folders (126.5 MB) left by killed runs: runs/a/.ode45.abcdef012345.11.tmp, "
        "runs/b/.x.old.abcdef012345.11.tmp and 1 more.")
    assert leftovers_line(removed[1:2]) == "removed runs/b/.x.old.abcdef012345.11.tmp (0.3 kB), left by a killed run."
