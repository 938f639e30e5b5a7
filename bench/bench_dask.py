"""Benchmark: a 10,000-case study of an expression system on a Dask cluster of separate processes.

A damped pendulum (an expression system) swept over 100 dampings x 100 lengths, ode45,
``store = "summary"``. The cases are loaded once in this process (``--limit cases=10000``),
run serially (the reference, and the serial rate), then on a cluster started as a user starts
one: ``dask scheduler`` and 1, then 2, ``dask worker`` processes (one thread each) on loopback
ports (:func:`odelab.run.daskprocs.dask_processes`), through the same
``run_cases(executor="dask", scheduler=...)`` as ``odelab run --executor dask --scheduler``.

For each cluster: the first run and a second one (the workers warm: odelab imported, the
expressions' code compiled once), cases per second of wall time. The workers receive the built
cases (pickled: each case's expressions travel as their texts and are compiled again in the
worker, run/executors.py); before issue 38 each worker loaded the experiment file itself on
the first run (about 1.7 ms a case of the whole sweep, in every worker); every result is compared with the serial one (t, states, statistics,
bit for bit). Target: 2 workers >= 1.8x the cases per second of 1. The machine check (two
CPU-bound processes together against one after the other; 2.0x when both cores are free) and
the load average say what the machine allowed.

    python bench/bench_dask.py [--cases 10000]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_studies import machine_check  # noqa: E402

STUDY = """
title = "A damped pendulum: damping and length swept"
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
"parameters.c" = {{ from = 0.05, to = 2, count = {n} }}
"parameters.L" = {{ from = 0.5, to = 2, count = {m} }}
store = "summary"
"""
TARGET = 1.8


def same(a, b) -> bool:
    return all(x.case.index == y.case.index and x.status == y.status and x.stats == y.stats
               and np.array_equal(x.t, y.t) and np.array_equal(x.x, y.x) for x, y in zip(a, b)) and len(a) == len(b)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=10_000, help="a square number of cases (default 10000)")
    args = parser.parse_args()
    side = int(round(args.cases ** 0.5))
    from odelab.run import executors
    from odelab.run.daskprocs import dask_processes
    from odelab.run.executors import run_cases
    from odelab.experiment.limits import DEFAULT_LIMITS
    from odelab.experiment.loader import load_experiment

    load_before = os.getloadavg()
    check = machine_check()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "pendulum_study.toml"
        path.write_text(STUDY.format(n=side, m=side))
        limits = replace(DEFAULT_LIMITS, cases=side * side)
        start = time.perf_counter()
        cases = load_experiment(path, limits=limits).cases
        loading = time.perf_counter() - start
        start = time.perf_counter()
        serial = list(run_cases(cases, executor="serial"))
        serial_rate = len(cases) / (time.perf_counter() - start)
        executors._LOADED.clear()
        rows = []
        for workers in (1, 2):
            with dask_processes(workers, Path(tmp) / f"cluster-{workers}") as address:
                rates = []
                for _ in range(2):
                    start = time.perf_counter()
                    results = list(run_cases(cases, executor="dask", scheduler=address, limits=limits))
                    rates.append(len(cases) / (time.perf_counter() - start))
                    if not same(results, serial):
                        raise SystemExit(f"{workers} worker(s): the results differ from the serial run")
            rows.append((workers, *rates))
    load_after = os.getloadavg()
    print(f"{len(cases)} cases of an expression system (a damped pendulum, ode45), loaded in {loading:.1f} s; "
          f"results identical to serial on every cluster")
    print(f"load average {load_before[0]:.1f} before, {load_after[0]:.1f} after; machine check "
          f"{check:.2f}x (2.0x: two free cores)")
    print(f"{'run':<34} {'first run':>16} {'workers loaded':>16}")
    print(f"{'serial, this process':<34} {serial_rate:>10.0f} c/s {'':>16}")
    for workers, first, warm in rows:
        print(f"{f'Dask, {workers} worker(s) (separate processes)':<34} {first:>10.0f} c/s {warm:>12.0f} c/s")
    ratio_first, ratio_warm = rows[1][1] / rows[0][1], rows[1][2] / rows[0][2]
    print(f"2 workers over 1: {ratio_first:.2f}x (first run), {ratio_warm:.2f}x (workers loaded); target "
          f">= {TARGET}x: {'met' if ratio_warm >= TARGET else 'MISSED'}")


if __name__ == "__main__":
    main()
