"""A Dask cluster that loses its scheduler or a worker mid-study, and a worker with another odelab (issue 41).

The cluster is the one a user starts (`dask scheduler`, `dask worker`: separate processes on
loopback, odelab.run.daskprocs); `odelab run` runs as its own process, as a user runs it.
"""

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed", reason="the Dask tests need the `distributed` package (pip install 'odelab[dask]')")

from odelab import __version__  # noqa: E402
from odelab.run.daskprocs import dask_processes  # noqa: E402
from odelab.run.executors import DASK_SILENT_SECONDS  # noqa: E402

pytestmark = pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")

# Cheap cases, many of them: x' = -k x + sin(w t) over a grid of k and w.
def _study(nk: int, nw: int) -> str:
    return f"""
title = "A forced decay over a grid"
[parameters]
k = 1
w = 1
[system]
states = ["x"]
[system.equations]
x = "-k*x + sin(w*t)"
[initial]
x = 1
[time]
stop = 2
[solver]
method = "ode45"
[reference]
method = "none"
[sweep]
"parameters.k" = {{ from = 0.5, to = 5, count = {nk} }}
"parameters.w" = {{ from = 0.5, to = 5, count = {nw} }}
"""


def _procs(word: bytes) -> set[int]:
    """This process's children whose command line holds ``dask`` and ``word`` (scheduler, worker)."""
    me = str(os.getpid())
    found = set()
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
            cmd = Path(f"/proc/{entry}/cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if stat[1] == me and stat[0] != "Z" and b"dask" in b" ".join(cmd) and word in cmd:
            found.add(int(entry))
    return found


def _odelab(*args, cwd):
    return subprocess.Popen([sys.executable, "-m", "odelab", *map(str, args)], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _wait_for(path: Path, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} did not appear"
        time.sleep(0.1)


def _busy_worker(address: str, timeout: float = 600.0) -> str:
    """The name (0, 1...) of a worker with tasks of the run in hand, once some tasks have finished."""
    from distributed import Client

    deadline = time.monotonic() + timeout
    with Client(address, timeout=30) as client:
        while True:
            assert time.monotonic() < deadline, "the run's tasks never reached the workers"
            counts = client.run_on_scheduler(lambda dask_scheduler: (
                sum(ts.state == "memory" for ts in dask_scheduler.tasks.values()),
                {ws.name: len(ws.processing) for ws in dask_scheduler.workers.values()}))
            done, processing = counts
            busy = [name for name, n in processing.items() if n]
            if done >= 2 and busy:
                return str(busy[0]).removeprefix("worker-")
            time.sleep(0.05)


def _results(rows):
    return [{k: v for k, v in r.items() if k != "elapsed_s"} for r in rows]


def test_a_scheduler_killed_mid_study_is_one_clear_error_and_what_finished_is_stored(tmp_path):
    (tmp_path / "grid.toml").write_text(_study(40, 50))  # 2,000 cases
    with dask_processes(2, tmp_path / "cluster") as address:
        (scheduler,) = _procs(b"scheduler")
        run = _odelab("run", "grid.toml", "--executor", "dask", "--scheduler", address, "--limit", "cases=2000",
                      cwd=tmp_path)
        _wait_for(tmp_path / "runs" / "grid" / "sweep.csv")  # the table so far: some cases have finished
        os.kill(scheduler, signal.SIGKILL)
        killed = time.monotonic()
        out, err = run.communicate(timeout=120)
        took = time.monotonic() - killed
    assert run.returncode == 2 and "Traceback" not in err, err
    assert f"lost the Dask scheduler at '{address}' mid-run" in err and "Start it again" in err
    assert took < DASK_SILENT_SECONDS, took  # noticed at once: its connection closed
    stored = _rows(tmp_path / "runs" / "grid" / "sweep.csv")
    assert 0 < len(stored) < 2000 and f"{len(stored)} of 2000 cases finished and are stored." in err
    assert not list((tmp_path / "runs").rglob("*.tmp"))


def test_a_worker_killed_mid_study_is_said_and_the_10000_results_equal_serial(tmp_path):
    (tmp_path / "grid.toml").write_text(_study(100, 100))  # 10,000 cases
    serial = subprocess.run([sys.executable, "-m", "odelab", "run", "grid.toml", "--executor", "serial", "--limit",
                             "cases=10000", "--runs", "serial"], cwd=tmp_path, capture_output=True, text=True)
    assert serial.returncode == 0, serial.stderr
    with dask_processes(2, tmp_path / "cluster") as address:
        workers = sorted(_procs(b"worker"))
        assert len(workers) == 2
        run = _odelab("run", "grid.toml", "--executor", "dask", "--scheduler", address, "--limit", "cases=10000",
                      "--runs", "dask", cwd=tmp_path)
        busy = _busy_worker(address)  # a worker running the study's tasks, with more waiting
        (pid,) = [p for p in workers if f"worker-{busy}".encode() in Path(f"/proc/{p}/cmdline").read_bytes()]
        os.kill(pid, signal.SIGKILL)
        out, err = run.communicate(timeout=900)
    assert run.returncode == 0 and "Traceback" not in err, err
    assert "warning: the Dask worker worker-" in err and "left the Dask scheduler" in err
    assert "ran again on the other workers" in err
    assert _results(_rows(tmp_path / "dask" / "grid" / "sweep.csv")) == \
        _results(_rows(tmp_path / "serial" / "grid" / "sweep.csv"))


def test_a_worker_with_another_odelab_is_refused_naming_both_versions(tmp_path):
    elsewhere = tmp_path / "other-site"
    info = elsewhere / "odelab-0.0.9.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: odelab\nVersion: 0.0.9\n")
    (tmp_path / "grid.toml").write_text(_study(4, 4))
    path = os.pathsep.join([str(elsewhere), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    with dask_processes(1, tmp_path / "cluster", worker_env={"PYTHONPATH": path}) as address:
        run = _odelab("run", "grid.toml", "--executor", "dask", "--scheduler", address, cwd=tmp_path)
        out, err = run.communicate(timeout=120)
    assert run.returncode == 2 and "Traceback" not in err, err
    assert "has odelab 0.0.9, and this process runs odelab " + __version__ in " ".join(err.split())
    assert f"pip install odelab=={__version__}" in " ".join(err.split())
    assert not (tmp_path / "runs").exists()


def test_a_worker_with_the_same_version_but_other_code_is_refused(tmp_path):
    """A worker started from another checkout (the same version number, one file edited) is refused before
    any case runs: the version strings agree, the source digests do not."""
    import shutil

    import odelab
    from odelab.run.executors import source_digest

    other = tmp_path / "other-checkout"
    shutil.copytree(Path(odelab.__file__).resolve().parent, other / "odelab",
                    ignore=shutil.ignore_patterns("__pycache__"))
    edited = other / "odelab" / "solvers" / "tableau.py"
    edited.write_text(edited.read_text() + "\n# an edit in the worker's tree\n")
    (tmp_path / "grid.toml").write_text(_study(4, 4))
    path = os.pathsep.join([str(other), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    with dask_processes(1, tmp_path / "cluster", worker_env={"PYTHONPATH": path}) as address:
        run = _odelab("run", "grid.toml", "--executor", "dask", "--scheduler", address, cwd=tmp_path)
        out, err = run.communicate(timeout=120)
    said = " ".join(err.split())
    assert run.returncode == 2 and "Traceback" not in err, err
    assert f"runs odelab {__version__} from other source files than this process" in said
    assert f"this one's {source_digest()[:12]}): every worker must run the same odelab code" in said
    assert not (tmp_path / "runs").exists()
