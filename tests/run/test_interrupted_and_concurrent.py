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
