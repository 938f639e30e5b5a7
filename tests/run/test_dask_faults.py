"""Dask faults: a clear message and exit 2 within a bounded time, no traceback, nothing left running.

Only loopback addresses."""

import os
import socket
import threading
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.run import executors

distributed = pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[2]


def _children() -> set[int]:
    me = os.getpid()
    found = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(stat[1]) == me and stat[0] != "Z":
                found.add(int(entry))
    return found


def _run(tmp_path, *args):
    (tmp_path / "ex1.toml").write_text((ROOT / "experiments" / "exercise1.toml").read_text())
    start = time.monotonic()
    result = CliRunner().invoke(app, ["run", str(tmp_path / "ex1.toml"), "--runs", str(tmp_path / "runs"),
                                      "--executor", "dask", *args])
    return result, time.monotonic() - start


@pytest.fixture
def silent_server():
    """A loopback socket that accepts connections and never says a word."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    accepted = []
    stop = threading.Event()

    def serve():
        server.settimeout(0.1)
        while not stop.is_set():
            try:
                accepted.append(server.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}", accepted
    stop.set()
    thread.join()
    for conn in accepted:
        conn.close()
    server.close()


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_a_scheduler_that_accepts_and_stays_silent_is_a_clear_error(tmp_path, monkeypatch, silent_server):
    address, accepted = silent_server
    monkeypatch.setattr(executors, "DASK_CONNECT_SECONDS", 1.0)
    before = _children()
    result, took = _run(tmp_path, "--scheduler", address)
    assert result.exit_code == 2, result.output
    assert accepted, "the run never connected"
    assert f"cannot reach the Dask scheduler at '{address}'" in result.output
    assert "no answer within 1 s" in result.output
    assert "Traceback" not in result.output
    assert took < 60  # it waited for its deadline (1 s), not for ever
    assert _children() <= before
    assert not (tmp_path / "runs").exists()


def test_a_scheduler_with_no_workers_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setattr(executors, "DASK_WORKERS_SECONDS", 1.0)
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None,
                                  protocol="tcp", host="127.0.0.1") as cluster:
        result, took = _run(tmp_path, "--scheduler", cluster.scheduler_address)
    assert result.exit_code == 2, result.output
    assert "has no workers (none joined within 1 s)" in result.output
    assert f"dask worker {cluster.scheduler_address}" in result.output
    assert "Traceback" not in result.output
    assert took < 60
    assert not (tmp_path / "runs").exists()


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_a_local_cluster_whose_workers_cannot_make_their_folder_is_a_clear_error(tmp_path):
    import dask

    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the workers' folder should go\n")
    before = _children()
    with dask.config.set({"temporary-directory": str(blocker)}):
        result, took = _run(tmp_path, "--jobs", "1")
    assert result.exit_code == 2, result.output
    assert "could not start a local Dask cluster" in result.output
    assert "Not a directory" in result.output and "DASK_TEMPORARY_DIRECTORY" in result.output
    assert "Traceback" not in result.output
    assert _children() <= before
    assert not (tmp_path / "runs").exists()
