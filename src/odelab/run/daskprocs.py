"""A Dask cluster as a user starts one: ``dask scheduler`` and ``dask worker`` as separate processes.

:func:`dask_processes` starts a scheduler and ``workers`` single-threaded workers on the
loopback interface (ports chosen by the system), waits until every worker has joined, yields
the scheduler's address for ``odelab run --executor dask --scheduler ADDRESS`` (or
:func:`odelab.run.executors.run_cases`), and stops them all when the ``with`` block
ends, however it ends. Each process is started through :func:`odelab.run.lifeline.tied_command`,
so that none outlives the process that started it even if that one is killed (``kill -9``)
before it can stop them. For tests and ``bench/bench_dask.py``; a real cluster's processes are
started by its administrator.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

__all__ = ["dask_processes"]

#: One BLAS and OpenMP thread per worker: the workers are the parallelism.
_ONE_THREAD = {name: "1" for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}


def _dask(*args: str) -> list[str]:
    return [sys.executable, "-m", "dask", *args]  # the `dask` command of this interpreter's environment


@contextmanager
def dask_processes(workers: int, folder: Path, *, timeout: float = 60.0,
                   worker_env: dict[str, str] | None = None) -> Iterator[str]:
    """Start ``dask scheduler`` and ``workers`` ``dask worker`` processes; yield the scheduler's address.

    ``folder`` holds the scheduler file, the workers' scratch folders and each process's log
    (``scheduler.log``, ``worker-N.log``: read them when a start fails); ``worker_env`` is added
    to the workers' environment. Raises RuntimeError if the cluster is not up within ``timeout``
    seconds."""
    from odelab.run.lifeline import tied_command

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, **_ONE_THREAD}
    scheduler_file = folder / "scheduler.json"
    scheduler_file.unlink(missing_ok=True)
    procs: list[subprocess.Popen] = []
    logs = []

    def start(argv: list[str], log: str, extra: dict[str, str] | None = None) -> subprocess.Popen:
        out = open(folder / log, "wb")
        logs.append(out)
        proc = subprocess.Popen(tied_command(argv), stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                env={**env, **(extra or {})}, cwd=folder)
        procs.append(proc)
        return proc

    deadline = time.monotonic() + timeout
    try:
        scheduler = start(_dask("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                "--scheduler-file", str(scheduler_file)), "scheduler.log")
        address = None
        while address is None:
            if scheduler.poll() is not None:
                raise RuntimeError(f"`dask scheduler` exited with code {scheduler.returncode}; see {folder / 'scheduler.log'}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"`dask scheduler` did not start within {timeout:g} s; see {folder / 'scheduler.log'}")
            try:
                address = json.loads(scheduler_file.read_text())["address"]
            except (OSError, ValueError, KeyError):
                time.sleep(0.05)
        for i in range(workers):
            start(_dask("worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1",
                        "--name", f"worker-{i}", "--local-directory", str(folder / f"worker-{i}")), f"worker-{i}.log",
                  worker_env)
        _wait_for_workers(address, workers, procs, max(deadline - time.monotonic(), 1.0))
        yield address
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.terminate()
        for proc in procs:
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        for out in logs:
            out.close()


def _wait_for_workers(address: str, workers: int, procs: list, timeout: float) -> None:
    from distributed import Client

    with Client(address, timeout=timeout) as client:
        deadline = time.monotonic() + timeout
        while len(client.scheduler_info(n_workers=-1)["workers"]) < workers:
            dead = [p.args for p in procs if p.poll() is not None]
            if dead:
                raise RuntimeError(f"a Dask process exited while the cluster started: {' '.join(dead[0][-12:])}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"only {len(client.scheduler_info(n_workers=-1)['workers'])} of {workers} Dask "
                                   f"workers joined within {timeout:.0f} s")
            time.sleep(0.05)
