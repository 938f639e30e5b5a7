"""Benchmark: the adaptive driver's time per step with and without events, against SciPy's RK45.

Events, NonNegative and dense output are steps of the one driver; a run with no events must
not pay for them. This times MATLAB's rigid body over [0, 1200] (rtol 1e-6, atol 1e-9):
odelab's ode45 with no events, with an event on y1 = 0 (about 390 crossings), SciPy's RK45,
and, with ``--before OLD/engine.py`` (e.g. ``git show 9fd3c90:src/odelab/solvers/engine.py >
/tmp/engine_before.py``), the driver of an older commit called with the same arguments. All
run interleaved in one process, best of ``--repeat``, so a busy machine slows them alike;
wall and CPU time (the steadier one on a shared machine). Not a test.

    python bench/bench_events.py [--repeat 9] [--before /tmp/engine_before.py]
"""

from __future__ import annotations

import argparse
import importlib.util
import time

import numpy as np
from scipy.integrate import solve_ivp

import odelab
from odelab.solvers import engine
from odelab.solvers.registry import get_method

RTOL, ATOL = 1e-6, 1e-9


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def crossing(t, y):
    return [y[0]], [0], [0]


def driver(module):
    """The bare driver of ``module`` (an engine.py) on the rigid body: no API layer around it."""
    m = get_method("ode45")
    tab = m.tableau
    tspan = np.array([0.0, 1200.0])
    y0 = np.array([0.0, 1.0, 1.0])
    threshold = np.full(3, ATOL / RTOL)

    def run():
        out = module.integrate_adaptive(rigid, tspan, y0, rigid(0.0, y0), tab.A, tab.c, tab.error_weights, tab.dense,
                                        m.power, m.shrink_min, RTOL, threshold, 120.0, float("nan"), 4, False, 0)
        return out.nsteps if hasattr(out, "nsteps") else out[2]

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    parser.add_argument("--before", help="an older engine.py to compare the bare driver with")
    args = parser.parse_args()
    runs = {
        "SciPy RK45": lambda: solve_ivp(rigid, [0, 1200], [0, 1, 1], method="RK45", rtol=RTOL, atol=ATOL).t.size - 1,
        "ode45": lambda: odelab.ode45(rigid, [0, 1200], [0, 1, 1], rtol=RTOL, atol=ATOL).stats.nsteps,
        "ode45, events": lambda: odelab.ode45(rigid, [0, 1200], [0, 1, 1], rtol=RTOL, atol=ATOL,
                                              events=crossing).stats.nsteps,
        "driver now": driver(engine),
    }
    if args.before:
        spec = importlib.util.spec_from_file_location("engine_before", args.before)
        before = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(before)
        runs["driver before"] = driver(before)
    best = {name: float("inf") for name in runs}
    best_cpu = dict(best)
    steps = {}
    for _ in range(args.repeat):
        for name, run in runs.items():
            start, cpu = time.perf_counter(), time.process_time()
            steps[name] = run()
            best[name] = min(best[name], time.perf_counter() - start)
            best_cpu[name] = min(best_cpu[name], time.process_time() - cpu)
    scipy_per_step = best["SciPy RK45"] / steps["SciPy RK45"]
    scipy_cpu = best_cpu["SciPy RK45"] / steps["SciPy RK45"]
    print(f"rigid body [0, 1200], rtol {RTOL:g}, atol {ATOL:g}, best of {args.repeat}")
    print(f"{'run':<16} {'steps':>6} {'wall us/step':>13} {'x SciPy':>8} {'CPU us/step':>12} {'x SciPy':>8}")
    for name in runs:
        per_step = best[name] / steps[name]
        per_cpu = best_cpu[name] / steps[name]
        print(f"{name:<16} {steps[name]:>6d} {per_step * 1e6:>13.2f} {per_step / scipy_per_step:>8.3f} "
              f"{per_cpu * 1e6:>12.2f} {per_cpu / scipy_cpu:>8.3f}")


if __name__ == "__main__":
    main()
