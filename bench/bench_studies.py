"""Benchmark: studies and sweeps, as a user runs them (whole `odelab run` processes).

1. ``experiments/convergence.toml`` (60 fixed-step cases, up to 3200 steps each) serially
   (``--executor serial``) and with ``--jobs 2``: the speed-up of the process pool
   (target: at least 1.7x on 2 cores), with Amdahl's bound for it: the serial run's wall
   time split into the cases' own time (the sum of ``elapsed_s`` in sweep.json, what a pool
   can share out) and the rest (start-up, imports, loading, storing, printing: what it cannot).
2. A 1000-case parameter sweep of Exercise 2's plant (unit step, ode45, damping b and
   stiffness k swept 40 x 25) with ``store = "summary"``: target under 10 s.

Best of ``--repeat`` runs each, serial and parallel interleaved. A speed-up only means something
on an otherwise idle machine: the table shows the load average and a check of the machine
itself (two CPU-bound Python processes against one after the other: about 2.0x when both cores
are free). Python's bytecode cache is on for the runs (as for any installed package), even if
this shell sets PYTHONDONTWRITEBYTECODE.

    python bench/bench_studies.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SPEEDUP_TARGET = 1.7
SWEEP_TARGET = 10.0

SWEEP_1000 = """
title = "Exercise 2's plant: 1000 variants of damping and stiffness"
[parameters]
m = 1
k = 3
b = 4
q = 10
[system]
kind = "state-space"
states = ["x", "v"]
inputs = ["f"]
outputs = ["y"]
A = [[0, 1], ["-k/m", "-b/m"]]
B = [[0], ["1/m"]]
C = [["q", 0]]
D = [[0]]
[initial]
x = 0
v = 0
[time]
stop = 10
[inputs.f]
type = "step"
time = 0
[solver]
method = "ode45"
[reference]
method = "none"          # a parameter study: the quantities of interest, not errors
[sweep]
"parameters.b" = { from = 0.5, to = 8, count = 40 }
"parameters.k" = { from = 1, to = 25, count = 25 }
store = "summary"
"""


def wall(cmd: list[str], cwd: str) -> float:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    start = time.perf_counter()
    subprocess.run(cmd, cwd=cwd, check=True, capture_output=True, env=env)
    return time.perf_counter() - start


def _spin(n: int) -> float:
    start = time.perf_counter()
    s = 0
    for i in range(n):
        s += i * i % 7
    return time.perf_counter() - start


def machine_check(n: int = 2_000_000, repeat: int = 3) -> float:
    """Two CPU-bound processes at once against one after the other (2.0x: two free cores)."""
    best = 0.0
    with multiprocessing.get_context("fork").Pool(2) as pool:
        pool.map(_spin, [1000, 1000])
        for _ in range(repeat):
            serial = sum(pool.apply(_spin, (n,)) for _ in range(2))
            start = time.perf_counter()
            pool.map(_spin, [n, n], chunksize=1)
            best = max(best, serial / (time.perf_counter() - start))
    return best


def cases_time(runs: Path) -> float:
    """The cases' own time in a run of convergence.toml: the sum of elapsed_s over its sweeps."""
    return sum(row["elapsed_s"] for f in runs.glob("*/sweep.json") for row in json.loads(f.read_text())["rows"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    odelab = [sys.executable, "-m", "odelab.cli", "run"]
    load = os.getloadavg()[0]
    check = machine_check()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        conv = str(ROOT / "experiments" / "convergence.toml")
        wall([*odelab, conv, "--runs", "warm", "--executor", "serial"], tmp)  # bytecode cache, disk cache
        serial, pooled, cases = float("inf"), float("inf"), float("inf")
        for i in range(args.repeat):
            t = wall([*odelab, conv, "--runs", f"r{i}s", "--executor", "serial"], tmp)
            if t < serial:
                serial, cases = t, cases_time(Path(tmp) / f"r{i}s")
            pooled = min(pooled, wall([*odelab, conv, "--runs", f"r{i}p", "--jobs", "2"], tmp))
        rest = serial - cases
        bound = serial / (rest + cases / 2)
        speedup = serial / pooled
        rows += [
            ("convergence.toml (60 cases), serial", f"{serial:.2f} s", ""),
            ("  of which the cases themselves (sum of elapsed_s)", f"{cases:.2f} s", ""),
            ("  of which start-up, loading, storing, printing", f"{rest:.2f} s", ""),
            ("convergence.toml, --jobs 2", f"{pooled:.2f} s", ""),
            ("speed-up of --jobs 2", f"{speedup:.2f}x", f">= {SPEEDUP_TARGET}x: {'met' if speedup >= SPEEDUP_TARGET else 'missed'}"),
            ("Amdahl's bound for 2 jobs (serial / (rest + cases / 2))", f"{bound:.2f}x", ""),
        ]
        sweep = Path(tmp) / "sweep1000.toml"
        sweep.write_text(SWEEP_1000)
        best = {"serial": float("inf"), "2": float("inf")}
        for i in range(args.repeat):
            best["serial"] = min(best["serial"], wall([*odelab, str(sweep), "--runs", f"s{i}", "--executor", "serial"],
                                                      tmp))
            best["2"] = min(best["2"], wall([*odelab, str(sweep), "--runs", f"p{i}", "--jobs", "2"], tmp))
        count = (Path(tmp) / "p0" / "sweep1000" / "sweep.csv").read_text().count("\n") - 1
        rows += [
            (f"1000-case Exercise 2 sweep ({count} rows), summary, serial", f"{best['serial']:.2f} s", ""),
            ("1000-case Exercise 2 sweep, summary, --jobs 2", f"{best['2']:.2f} s",
             f"< {SWEEP_TARGET:g} s: {'met' if best['2'] < SWEEP_TARGET else 'missed'}"),
        ]
    rows.append(("machine check: 2 CPU-bound processes at once", f"{check:.2f}x", "2.0x on 2 free cores"))
    print(f"best of {args.repeat}; load average {load:.2f} before the runs, {os.getloadavg()[0]:.2f} after; "
          f"{os.cpu_count()} cores")
    width = max(len(r[0]) for r in rows)
    print(f"| {'run':<{width}} | {'value':>8} | target |")
    print(f"|{'-' * (width + 2)}|{'-' * 9}:|--------|")
    for name, value, target in rows:
        print(f"| {name:<{width}} | {value:>8} | {target} |")


if __name__ == "__main__":
    main()
