"""Benchmark: studies and sweeps, as a user runs them (whole `odelab run` processes).

1. ``experiments/convergence.toml`` (60 fixed-step cases, up to 3200 steps each) serially
   (``--executor serial``) and with ``--jobs 2``: the speed-up of the process pool
   (target: at least 1.7x on 2 cores).
2. A 1000-case parameter sweep of Exercise 2's plant (unit step, ode45, damping b and
   stiffness k swept 40 x 25) with ``store = "summary"``: target under 10 s.

Best of ``--repeat`` runs each, serial and parallel interleaved. The machine must be otherwise
idle for the speed-up to mean anything: report the load average with the numbers.

    python bench/bench_studies.py [--repeat 3]
"""

from __future__ import annotations

import argparse
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
    start = time.perf_counter()
    subprocess.run(cmd, cwd=cwd, check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    odelab = [sys.executable, "-m", "odelab.cli", "run"]
    env_note = f"load average {os.getloadavg()[0]:.2f}, {os.cpu_count()} cores"
    with tempfile.TemporaryDirectory() as tmp:
        conv = str(ROOT / "experiments" / "convergence.toml")
        serial, pooled = float("inf"), float("inf")
        for i in range(args.repeat):
            serial = min(serial, wall([*odelab, conv, "--runs", f"r{i}s", "--executor", "serial"], tmp))
            pooled = min(pooled, wall([*odelab, conv, "--runs", f"r{i}p", "--jobs", "2"], tmp))
        print(f"convergence.toml: serial {serial:.2f} s, --jobs 2 {pooled:.2f} s, speed-up {serial / pooled:.2f}x "
              f"(target >= {SPEEDUP_TARGET}x; {env_note})")
        sweep = Path(tmp) / "sweep1000.toml"
        sweep.write_text(SWEEP_1000)
        best = {"serial": float("inf"), "2": float("inf")}
        for i in range(args.repeat):
            best["serial"] = min(best["serial"], wall([*odelab, str(sweep), "--runs", f"s{i}", "--executor", "serial"],
                                                      tmp))
            best["2"] = min(best["2"], wall([*odelab, str(sweep), "--runs", f"p{i}", "--jobs", "2"], tmp))
        rows = (Path(tmp) / "p0" / "sweep1000" / "sweep.csv").read_text().count("\n") - 1
        print(f"1000-case Exercise 2 sweep, store = summary ({rows} rows in sweep.csv): serial {best['serial']:.2f} s, "
              f"--jobs 2 {best['2']:.2f} s (target < {SWEEP_TARGET} s)")


if __name__ == "__main__":
    main()
