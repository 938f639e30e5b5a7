"""Benchmark: work-precision of the non-stiff solvers at tight tolerances (ode113 against the RK pairs).

Two problems with exact or tight references: the two-body orbit (eccentricity 0.5, four
periods, exact: back at the start) and MATLAB's rigid body on [0, 12] (reference: DOP853 at
rtol 1e-13). For each method and rtol (atol = rtol * 1e-3 for the rigid body, = rtol for the
orbit) it prints function evaluations, the error at the end in units of rtol and the best time
of ``--repeat`` runs. Adams methods pay two evaluations per step, the RK pairs six (ode45) to
twelve (DOP853), so ode113 should need the fewest evaluations at tight tolerances; its Python
overhead per step is larger, so time favours it only when ``fun`` is expensive. Not a test:
run it and read the table.

    python bench/bench_nonstiff.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import odelab

METHODS = ("ode113", "ode45", "ode78", "DOP853", "LSODA")
RTOLS = (1e-6, 1e-8, 1e-10, 1e-12)
ECC = 0.5
ORBIT_Y0 = np.array([1 - ECC, 0.0, 0.0, math.sqrt((1 + ECC) / (1 - ECC))])


def kepler(t, y):
    r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
    return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3])


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def problems():
    rigid_ref = odelab.solve(rigid, [0, 12], [0, 1, 1], method="DOP853", rtol=1e-13, atol=1e-15).y[-1]
    return [
        ("two-body, 4 orbits", kepler, [0, 8 * math.pi], ORBIT_Y0, ORBIT_Y0, 1.0),
        ("rigid body [0, 12]", rigid, [0, 12], np.array([0.0, 1, 1]), rigid_ref, 1e-3),
    ]


def run(method, fun, tspan, y0, rtol, atol, repeat):
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        sol = odelab.solve(fun, tspan, y0, method=method, rtol=rtol, atol=atol)
        best = min(best, time.perf_counter() - start)
    return sol, best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    for title, fun, tspan, y0, ref, atol_factor in problems():
        print(f"\n{title}")
        print(f"{'rtol':>7} {'method':>7} {'nfevals':>8} {'steps':>6} {'err/rtol':>9} {'time ms':>8} {'fevals/ode113':>14}")
        for rtol in RTOLS:
            rows = []
            for method in METHODS:
                sol, best = run(method, fun, tspan, y0, rtol, rtol * atol_factor, args.repeat)
                err = float(np.abs(sol.y[-1] - ref).max())
                rows.append((method, sol.stats.nfevals, sol.stats.nsteps, err / rtol, 1e3 * best))
            base = rows[0][1]
            for method, nfev, nsteps, units, ms in rows:
                print(f"{rtol:7.0e} {method:>7} {nfev:8d} {nsteps:6d} {units:9.1f} {ms:8.1f} {nfev / base:14.2f}")


if __name__ == "__main__":
    main()
