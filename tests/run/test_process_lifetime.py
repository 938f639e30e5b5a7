"""No process outlives its run, and a case is stored the moment it finishes (real processes, SIGKILL)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from odelab.store.results import list_runs, read_run

# Van der Pol with mu = 1000 given to ode45 on the Python engine: stiff, so it runs for minutes
# (the tests kill it long before). Each case is one such solve.
LONG = """
title = "long"
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
max_steps = 50000000
backend = "python"
"""

# Case "long" first (and longest, so a pool hands it out first), then a tiny one.
LONG_THEN_TINY = LONG + """
[[case]]
name = "long"
[[case]]
name = "tiny"
time.stop = 0.01
parameters.mu = 1
"""

# Four long cases: enough work for both pool workers.
FOUR_LONG = LONG + "".join(f'\n[[case]]\nname = "c{i}"\nparameters.mu = {1000 + i}\n' for i in range(4))


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # see test_interrupted_and_concurrent


def _start(tmp_path, *args):
    return subprocess.Popen([sys.executable, "-m", "odelab.cli", "run", *map(str, args), "--runs", "runs"],
                            cwd=tmp_path, preexec_fn=_default_sigint, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)


def _children(pids: set[int]) -> set[int]:
    found = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) in pids:
                found.add(int(entry))
    return found


def _descendants(pid: int) -> set[int]:
    seen: set[int] = set()
    frontier = {pid}
    while frontier:
        frontier = _children(frontier) - seen
        seen |= frontier
    return seen


def _alive(pid: int) -> bool:
    """Running (a zombie waiting for its new parent to reap it has exited)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _kill_all(pids) -> None:
    for pid in pids:
        if _alive(pid):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def _wait_children(proc, count: int, seen: set[int], timeout: float = 120.0, settle: float = 1.0) -> None:
    """Collect the descendants of ``proc`` in ``seen`` until there are at least ``count`` and none
    has appeared for ``settle`` s."""
    end = time.monotonic() + timeout
    stable_since = time.monotonic()
    while time.monotonic() < end and proc.poll() is None:
        now = _descendants(proc.pid)
        if now - seen:
            seen |= now
            stable_since = time.monotonic()
        elif len(seen) >= count and time.monotonic() - stable_since >= settle:
            return
        time.sleep(0.05)
    raise AssertionError(f"the run did not start {count} worker processes (exit {proc.poll()}, saw {sorted(seen)})")


GONE_WITHIN = 30.0  # s: generous, so that a machine under load cannot fail the test


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()[:120]
    except OSError:
        return "?"


def _killed_run_leaves_nothing(tmp_path, *args, count: int):
    (tmp_path / "four.toml").write_text(FOUR_LONG)
    proc = _start(tmp_path, "four.toml", *args)
    workers: set[int] = set()
    try:
        _wait_children(proc, count, workers)
        proc.kill()
        proc.wait(timeout=10)
        killed = time.monotonic()
        # The kernel kills them at once (PR_SET_PDEATHSIG); the bound only waits for a loaded
        # machine to schedule their exit, it measures nothing (bench/ measures the time).
        while time.monotonic() - killed < GONE_WITHIN and any(map(_alive, workers)):
            time.sleep(0.02)
        left = {p: _cmdline(p) for p in sorted(workers) if _alive(p)}
        assert not left, f"still running {GONE_WITHIN:.0f} s after the SIGKILL: {left}"
        return time.monotonic() - killed
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        _kill_all(workers | _descendants(proc.pid))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sigkilled_pool_run_leaves_no_worker(tmp_path):
    _killed_run_leaves_nothing(tmp_path, "--jobs", "2", count=2)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sigkilled_dask_run_leaves_no_worker(tmp_path):
    pytest.importorskip("distributed")
    _killed_run_leaves_nothing(tmp_path, "--executor", "dask", "--jobs", "2", count=2)


def test_pool_workers_exit_with_their_parent_even_before_arming(tmp_path):
    """The race: a parent that died before the worker armed its parent-death signal is seen too."""
    code = ("import os, sys; from odelab.run.lifeline import exit_with_parent; "
            "exit_with_parent(os.getppid() + 1 if os.getppid() != 1 else 2); print('survived')")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and "survived" not in done.stdout


def _wait_for_file(proc, path: Path, seen: set[int], timeout: float = 120.0) -> None:
    """Wait for ``path`` while the run goes on, collecting its processes in ``seen`` (to clean up)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        seen |= _descendants(proc.pid)
        if path.exists():
            return
        assert proc.poll() is None, f"the run ended (exit {proc.returncode}) before storing {path}"
        time.sleep(0.02)
    raise AssertionError(f"{path} was not stored while the long case ran")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_pool_stores_a_finished_case_while_an_earlier_one_runs_and_a_kill_keeps_it(tmp_path):
    (tmp_path / "two.toml").write_text(LONG_THEN_TINY)
    proc = _start(tmp_path, "two.toml", "--jobs", "2")
    workers: set[int] = set()
    try:
        # "tiny" is case 2 of 2; before, a pool stored cases in case order, so only after "long"
        _wait_for_file(proc, tmp_path / "runs" / "two" / "tiny" / "result.json", workers)
        proc.kill()
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        _kill_all(workers | _descendants(proc.pid))
    runs = tmp_path / "runs"
    assert [p.relative_to(runs).as_posix() for p in list_runs(runs)] == ["two/tiny"]
    record = read_run(runs / "two" / "tiny")
    assert record["status"] == "success" and len(record["trajectory"]["t"]) == record["points"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_killed_sweep_keeps_the_table_of_what_finished(tmp_path):
    sweep = LONG + '\n[sweep]\n"parameters.mu" = [1000, 1]\n"time.stop" = [3000, 0.01]\nmode = "zip"\n'
    (tmp_path / "sweep.toml").write_text(sweep)
    proc = _start(tmp_path, "sweep.toml", "--jobs", "2")
    workers: set[int] = set()
    try:
        _wait_for_file(proc, tmp_path / "runs" / "sweep" / "sweep.json", workers)
        proc.kill()
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        _kill_all(workers | _descendants(proc.pid))
    record = json.loads((tmp_path / "runs" / "sweep" / "sweep.json").read_text())
    assert record["complete"] is False and record["cases_total"] == 2
    assert [(row["swept"], row["status"]) for row in record["rows"]] == [
        ({"parameters.mu": 1, "time.stop": 0.01}, "success")]
