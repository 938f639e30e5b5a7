"""Interrupted and concurrent runs with real processes: nothing stored is lost or half-written."""

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from odelab.store.results import list_runs, read_run

ROOT = Path(__file__).resolve().parents[2]

FAST = (ROOT / "experiments" / "exercise1.toml").read_text()
# Van der Pol with mu = 1000 given to ode45: stiff, so it takes a long time (bounded by max_steps).
# On the Python engine: with a warm compile cache, backend "auto" would finish its 1.7 million
# steps compiled in half a second, before the signal is sent.
SLOW = """
[parameters]
mu = 1000
[system]
states = ["x", "v"]
[system.equations]
x = "v"
v = "mu*(1 - x^2)*v - x"
[initial]
x = 2
v = 0
[time]
stop = 3000
[solver]
method = "ode45"
max_steps = 5000000
backend = "python"
"""


def _default_sigint():
    # A shell without job control starts background commands with SIGINT ignored, and Python
    # then installs no KeyboardInterrupt handler: the child would never see the Ctrl-C this
    # test sends when the suite itself runs in the background (`.ci/run &`).
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def odelab(*args, cwd):
    return subprocess.Popen([sys.executable, "-m", "odelab.cli", *map(str, args)], cwd=cwd, preexec_fn=_default_sigint,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for(path: Path, timeout=60.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if path.exists():
            return
        time.sleep(0.05)
    raise AssertionError(f"{path} did not appear")


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_interrupting_a_batch_keeps_finished_cases_and_no_partial_files(tmp_path, sig, code, word):
    (tmp_path / "a_fast.toml").write_text(FAST)
    (tmp_path / "b_slow.toml").write_text(SLOW)
    proc = odelab("run", tmp_path / "a_fast.toml", tmp_path / "b_slow.toml", "--runs", "runs", cwd=tmp_path)
    wait_for(tmp_path / "runs" / "a_fast" / "ode45" / "result.json")
    time.sleep(0.5)  # well into the slow case
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert f"{word}: 2 of 3 cases finished and stored" in err
    assert "Traceback" not in err
    runs = tmp_path / "runs"
    assert [p.relative_to(runs).as_posix() for p in list_runs(runs)] == ["a_fast/ode23", "a_fast/ode45"]
    for folder in list_runs(runs):
        assert read_run(folder)["status"] == "success"
    assert not [p for p in runs.rglob("*") if p.name.startswith(".")]  # no temporary folder, no .lock
    assert not (runs / "b_slow" / "ode45").exists()


def test_two_concurrent_runs_into_one_results_folder_corrupt_nothing(tmp_path):
    for name in ("exercise1.toml", "exercise2.toml", "rigid_body.toml"):
        (tmp_path / name).write_text((ROOT / "experiments" / name).read_text())
    procs = [odelab("run", tmp_path / "exercise1.toml", tmp_path / "exercise2.toml", tmp_path / "rigid_body.toml",
                    "--runs", "runs", cwd=tmp_path) for _ in range(2)]
    for proc in procs:
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
    folders = list_runs(tmp_path / "runs")
    assert len(folders) == 2 + 7 + 1
    for folder in folders:
        record = read_run(folder)  # valid JSON, a complete trajectory, consistent with each other
        assert record["status"] == "success"
        assert len(record["trajectory"]["t"]) == record["points"]
    assert not [p for p in (tmp_path / "runs").rglob("*") if p.name.startswith(".")]  # no temporary folder, no .lock


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_eight_concurrent_runs_into_one_folder_store_every_case_whole(tmp_path):
    """Four different files and the same file four times, at once, while a report reads the folder."""
    names = ["exercise1.toml", "exercise2.toml", "rigid_body.toml", "bouncing_ball.toml"]
    for name in names:
        (tmp_path / name).write_text((ROOT / "experiments" / name).read_text())
    procs = [odelab("run", tmp_path / name, "--runs", "runs", "--jobs", "1", cwd=tmp_path) for name in names]
    procs += [odelab("run", tmp_path / "exercise2.toml", "--runs", "runs", "--jobs", "1", cwd=tmp_path)
              for _ in range(4)]
    from odelab.report.collect import collect_runs

    seen_warnings = []
    while any(p.poll() is None for p in procs):  # a report during the runs reads only complete cases
        if (tmp_path / "runs").exists():
            groups, warnings = collect_runs(tmp_path / "runs")
            seen_warnings += warnings
            for g in groups:
                for r in g.runs:
                    assert len(r.t) == r.points and r.status
        time.sleep(0.05)
    for proc in procs:
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err
    assert not seen_warnings, seen_warnings
    folders = list_runs(tmp_path / "runs")
    expected = {"exercise1": 2, "exercise2": 7, "rigid_body": 1, "bouncing_ball": 1}
    assert sorted({f.parent.name for f in folders}) == sorted(expected)
    for exp, count in expected.items():
        assert len([f for f in folders if f.parent.name == exp]) == count
    for folder in folders:
        record = read_run(folder)  # valid JSON, a complete trajectory, the case its folder names
        assert record["status"] == "success" and record["experiment"] == folder.parent.name
        assert len(record["trajectory"]["t"]) == record["points"]
    assert not [p for p in (tmp_path / "runs").rglob("*") if p.name.startswith(".")]


def _draws(folder: Path, since: float) -> bool:
    """A figure was drawn: a new PNG in the figure cache (odelab.report.figcache stores each one as it is drawn;
    the report's own figures/ are written at the end, with index.html, too late to interrupt the drawing)."""
    return any(p.stat().st_mtime > since for p in folder.rglob("*.png")) if folder.is_dir() else False


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_interrupting_a_report_leaves_the_previous_one_whole(tmp_path, sig, code):
    runs = tmp_path / "runs"
    done = subprocess.run([sys.executable, "-m", "odelab", "run", str(ROOT / "experiments"), "--runs", str(runs)],
                          cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    first = subprocess.run([sys.executable, "-m", "odelab", "report", "--runs", "runs", "--out", "report"],
                           cwd=tmp_path, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    before = {k: v for k, v in _files(tmp_path / "report").items() if not k.startswith("figures/")}
    start = time.time()
    import os

    env = {**os.environ, "ODELAB_CACHE_DIR": str(tmp_path / "cold-cache")}  # every figure drawn again: slow
    proc = subprocess.Popen([sys.executable, "-m", "odelab", "report", "--runs", "runs", "--out", "report", "--jobs",
                             "1"], cwd=tmp_path, preexec_fn=_default_sigint, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    end = time.monotonic() + 120
    while not _draws(tmp_path / "cold-cache", start):
        assert proc.poll() is None and time.monotonic() < end, "the report ended before it drew a figure"
        time.sleep(0.02)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert "Traceback" not in err and ("interrupted" if code == 130 else "terminated") in err
    after = {k: v for k, v in _files(tmp_path / "report").items() if not k.startswith("figures/")}
    assert after == before  # index.html and report.md as they were
    assert not [p for p in (tmp_path / "report").rglob("*") if p.name.startswith(".")]  # no temporary file


# Exercise 1 with a stiff Van der Pol oscillator beside it, given to ode23 over a long span: minutes.
SLOW_EXERCISE1 = """
name = "exercise1"
[parameters]
mu = 1000
[system]
states = ["y", "x", "v"]
[system.equations]
y = "cos(t)"
x = "v"
v = "mu*(1 - x^2)*v - x"
[initial]
y = 2
x = 2
v = 0
[time]
stop = 30000
[exact]
y = "sin(t) + 2"
[solver]
method = "ode23"
max_steps = 50000000
backend = "python"
[[case]]
name = "ode23"
"""


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_interrupting_grade_leaves_the_previous_grades_whole(tmp_path, sig, code):
    import shutil

    shutil.copytree(ROOT / "examples" / "grading", tmp_path / "grading")
    first = subprocess.run([sys.executable, "-m", "odelab", "grade", "grading/rubric.toml", "--out", "grades"],
                           cwd=tmp_path, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    before = _files(tmp_path / "grades")
    slow = tmp_path / "grading" / "submissions" / "zz-slow"  # a student whose Exercise 1 runs for minutes
    slow.mkdir()
    (slow / "exercise1.toml").write_text(SLOW_EXERCISE1)
    proc = odelab("grade", "grading/rubric.toml", "--out", "grades", "--jobs", "1", "--max-steps", "0", cwd=tmp_path)
    time.sleep(6)  # the other students take about 2 s; zz-slow's case runs for minutes (tens of millions of steps)
    assert proc.poll() is None
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert "Traceback" not in err and "nothing was written" in err
    assert _files(tmp_path / "grades") == before
