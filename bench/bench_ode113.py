"""Benchmark: ode113's time per step against SciPy's RK45 on cheap right-hand sides (issue 27).

The target is ode113 at <= 0.5x SciPy RK45's time per step on a cheap right-hand side: each
ode113 step is two evaluations of ``fun`` and Shampine & Gordon's bookkeeping (the divided
differences, the order and step rules), a RK45 step six evaluations and SciPy's Python loop.
Both run the same problems at the same tolerances in this process, alternated run by run, each
timed as the best CPU time of ``--repeat`` runs (CPU time, so that other processes on a loaded machine
count less). Not a test: run it and read the table.

    python bench/bench_ode113.py [--repeat 7]
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np
from scipy.integrate import solve_ivp

import odelab


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def kepler(t, y):
    r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
    return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3])


ECC = 0.5
PROBLEMS = {  # name: (fun, tspan, y0, rtol, atol)
    "rigid body [0, 300], rtol 1e-6": (rigid, [0.0, 300.0], [0.0, 1.0, 1.0], 1e-6, 1e-9),
    "two-body, 10 orbits, rtol 1e-9": (kepler, [0.0, 20 * math.pi], [1 - ECC, 0.0, 0.0, math.sqrt((1 + ECC) / (1 - ECC))],
                                       1e-9, 1e-9),
}


def per_step(runs, repeat: int) -> list[tuple[float, int]]:
    """Each run's best CPU time a step over ``repeat`` rounds, the runs alternated within a round
    (so that a change in the machine's load falls on all of them); ``[(seconds, steps), ...]``."""
    best, steps = [math.inf] * len(runs), [0] * len(runs)
    for _ in range(repeat):
        for i, run in enumerate(runs):
            start = time.process_time()
            steps[i] = run()
            best[i] = min(best[i], time.process_time() - start)
    return [(b / n, n) for b, n in zip(best, steps)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} at the start")
    print(f"{'problem':34s} {'RK45 us/step':>13s} {'ode113 us/step':>15s} {'ratio':>6s}   steps (RK45, ode113)")
    for name, (fun, tspan, y0, rtol, atol) in PROBLEMS.items():
        def rk45():
            return solve_ivp(fun, tspan, y0, method="RK45", rtol=rtol, atol=atol).t.size - 1

        def ode113():
            return odelab.ode113(fun, tspan, y0, rtol=rtol, atol=atol).stats.nsteps

        rk45(), ode113()  # warm up
        (rk, n_rk), (ab, n_ab) = per_step([rk45, ode113], args.repeat)
        print(f"{name:34s} {rk * 1e6:13.1f} {ab * 1e6:15.1f} {ab / rk:6.2f}   {n_rk}, {n_ab}")
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
