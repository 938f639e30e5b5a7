"""A Dask cluster started as a user starts one (`dask scheduler`, `dask worker`, separate processes,
loopback ports): results identical to serial, in case order, and no process left behind, even
when the block that uses it fails or the process that started it is killed."""

import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from odelab.run import executors
from odelab.run.executors import CaseError, dask_batches, run_cases
from odelab.experiment.limits import DEFAULT_LIMITS
from odelab.experiment.loader import load_experiment

pytest.importorskip("distributed", reason="the Dask tests need the `distributed` package (pip install 'odelab[dask]')")

from odelab.run.daskprocs import dask_processes  # noqa: E402

# An expression system (a damped pendulum) over a grid of damping and length: 48 cases, more
# than the default budget of cases would allow if it were 1,000 times bigger (the workers load
# the file again within the run's --limit).
STUDY = """
title = "A damped pendulum, damping and length swept"
[parameters]
g = 9.81
L = 1
c = 0.2
[system]
states = ["theta", "omega"]
[system.equations]
theta = "omega"
omega = "-(g/L)*sin(theta) - c*omega"
[initial]
theta = 1
omega = 0
[time]
stop = 10
[solver]
method = "ode45"
[reference]
method = "none"
[sweep]
"parameters.c" = { from = 0.05, to = 2, count = 8 }
"parameters.L" = { from = 0.5, to = 2, count = 6 }
"""


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return False
    return stat[0] != "Z"


def _gone(pids, timeout: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not any(_alive(p) for p in pids):
            return True
        time.sleep(0.1)
    return False


def _plain(results):
    out = []
    for r in results:
        assert not isinstance(r, CaseError)
        out.append((r.case.index, r.case.name, r.status, r.stats, r.t.tobytes(), r.x.tobytes(), r.warnings))
    return out


def _cluster_pids(folder: Path) -> set[int]:
    """The scheduler's and the workers' pids, children of this process (started by dask_processes)."""
    me = os.getpid()
    found = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
                cmd = Path(f"/proc/{entry}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if int(stat[1]) == me and b"dask" in cmd and stat[0] != "Z":
                found.add(int(entry))
    return found


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_a_cluster_of_separate_processes_gives_the_serial_results_and_leaves_nothing(tmp_path):
    path = tmp_path / "study.toml"
    path.write_text(STUDY)
    limits = replace(DEFAULT_LIMITS, cases=40)  # fewer than the file's 48: the workers must get the run's limits
    with pytest.raises(Exception, match="48 cases"):
        load_experiment(path, limits=limits)
    limits = replace(DEFAULT_LIMITS, cases=48)
    cases = load_experiment(path, limits=limits).cases
    serial = list(run_cases(cases, executor="serial"))
    executors._LOADED.clear()  # nothing inherited: the workers are other programs anyway
    with dask_processes(2, tmp_path / "cluster") as address:
        pids = _cluster_pids(tmp_path / "cluster")
        assert len(pids) == 3 and address.startswith("tcp://127.0.0.1:")
        finished = []
        on_cluster = list(run_cases(cases, executor="dask", scheduler=address, limits=limits,
                                    on_done=lambda done, failed: finished.append((done, failed))))
    assert [r.case.index for r in on_cluster] == list(range(48))
    assert _plain(on_cluster) == _plain(serial)
    assert finished[-1] == (48, 0) and len(finished) == 48
    assert _gone(pids), "a Dask process outlived its block"


def test_cases_go_to_dask_in_batches_in_schedule_order():
    order = list(range(10_000))
    batches = dask_batches(order, threads=2)
    assert [i for b in batches for i in b] == order  # consecutive: longest first stays longest first
    assert max(map(len, batches)) == executors.DASK_BATCH and len(batches) >= 2 * executors.DASK_TASKS_PER_WORKER
    assert dask_batches(list(range(6)), threads=1) == [[i] for i in range(6)]  # a small run: one case a task


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_the_cluster_stops_when_the_block_fails(tmp_path):
    pids = set()
    with pytest.raises(ZeroDivisionError):
        with dask_processes(1, tmp_path / "cluster"):
            pids = _cluster_pids(tmp_path / "cluster")
            1 / 0
    assert len(pids) == 2 and _gone(pids)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the parent-death signal is Linux's")
def test_the_cluster_dies_with_a_killed_parent(tmp_path):
    """kill -9 of the process that started the cluster: no chance to stop it, the kernel does."""
    code = ("import sys, time; from pathlib import Path; from odelab.run.daskprocs import dask_processes\n"
            "with dask_processes(1, Path(sys.argv[1])):\n"
            "    print('up', flush=True); time.sleep(600)\n")
    parent = subprocess.Popen([sys.executable, "-c", code, str(tmp_path / "cluster")], stdout=subprocess.PIPE,
                              text=True)
    try:
        assert parent.stdout.readline().strip() == "up"
        pids = {int(e) for e in os.listdir("/proc") if e.isdigit() and _alive(int(e))
                and Path(f"/proc/{e}/stat").read_text().rsplit(")", 1)[1].split()[1] == str(parent.pid)}
        assert len(pids) == 2
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()
    assert _gone(pids), "a Dask process outlived the killed process that started it"


def test_the_workers_load_the_file_within_the_runs_limits(tmp_path):
    path = tmp_path / "study.toml"
    path.write_text(STUDY)
    exp = load_experiment(path, limits=replace(DEFAULT_LIMITS, cases=48))
    executors._LOADED.clear()
    with pytest.raises(Exception, match="budget is 10 cases"):
        executors._run_batch([executors._submit_args(exp.cases[0], {})[:4]], {}, replace(DEFAULT_LIMITS, cases=10))
    executors._LOADED.clear()
    (outcome,) = executors._run_batch([executors._submit_args(exp.cases[3], {})[:4]], {},
                                      replace(DEFAULT_LIMITS, cases=48))
    assert outcome[0] == "ok" and np.array_equal(outcome[1].x, run_cases([exp.cases[3]]).__next__().x)
