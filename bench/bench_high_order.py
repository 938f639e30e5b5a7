"""Benchmark: work against precision of ode78/ode89 (Verner) and ode113 (Adams) next to ode45 and SciPy's DOP853.

Three non-stiff problems with an exact answer at the final time, the same Python right-hand
side for every solver, rtol = 1e-6 ... 1e-12 (atol = rtol / 1000):

* ``rigid``: MATLAB's rigid body on [0, 12] against a DOP853 solve at rtol 1e-14 (the only one
  without a closed form; its reference error is below 1e-13);
* ``arenstorf``: the Arenstorf orbit (restricted three-body problem, Hairer-Norsett-Wanner I,
  Sec. II.0) over one period T = 17.0652165601579625588917206249, where it returns to its
  initial state;
* ``kepler``: the two-body problem with eccentricity 0.6 over two periods (4 pi), back to
  its initial state.

For each solver and tolerance it prints function evaluations, steps, the best of ``--repeat``
wall times and the error at the final time (max norm), then the evaluations each method needs
to reach the errors 1e-6, 1e-9 and 1e-11 (log-log interpolation along its curve). Not a test:
run it and read the table.

    python bench/bench_high_order.py [--repeat 3] [--problems rigid,arenstorf,kepler]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import solve_ivp

import odelab

RTOLS = [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12]
METHODS = ["ode45", "ode113", "ode78", "ode89", "DOP853 (SciPy)"]
TARGETS = [1e-6, 1e-9, 1e-11]


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


MU = 0.012277471
ARENSTORF_T = 17.0652165601579625588917206249


def arenstorf(t, y):
    x, vx, z, vz = y
    mu1 = 1.0 - MU
    d1 = ((x + MU) ** 2 + z ** 2) ** 1.5
    d2 = ((x - mu1) ** 2 + z ** 2) ** 1.5
    return np.array([vx, x + 2 * vz - mu1 * (x + MU) / d1 - MU * (x - mu1) / d2,
                     vz, z - 2 * vx - mu1 * z / d1 - MU * z / d2])


def kepler(t, y):
    r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
    return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3])


E = 0.6
PROBLEMS = {
    "rigid": (rigid, (0.0, 12.0), np.array([0.0, 1.0, 1.0]), None),
    "arenstorf": (arenstorf, (0.0, ARENSTORF_T), np.array([0.994, 0.0, 0.0, -2.00158510637908252240537862224]),
                  "periodic"),
    "kepler": (kepler, (0.0, 4 * np.pi), np.array([1 - E, 0.0, 0.0, np.sqrt((1 + E) / (1 - E))]), "periodic"),
}


def reference(name):
    fun, tspan, y0, kind = PROBLEMS[name]
    if kind == "periodic":
        return y0
    return solve_ivp(fun, tspan, y0, method="DOP853", rtol=1e-14, atol=1e-16).y[:, -1]


def run(method, fun, tspan, y0, rtol):
    counter = [0]

    def counted(t, y):
        counter[0] += 1
        return fun(t, y)

    start = time.perf_counter()
    if method.endswith("(SciPy)"):
        res = solve_ivp(counted, tspan, y0, method="DOP853", rtol=rtol, atol=rtol * 1e-3)
        elapsed = time.perf_counter() - start
        return elapsed, counter[0], res.t.size - 1, res.y[:, -1]
    sol = odelab.solve(counted, list(tspan), y0, method=method, rtol=rtol, atol=rtol * 1e-3)
    elapsed = time.perf_counter() - start
    assert counter[0] == sol.stats.nfevals, (method, counter[0], sol.stats)
    return elapsed, sol.stats.nfevals, sol.stats.nsteps, sol.y[-1]


def work_to_reach(errors, work, target) -> str:
    """Evaluations needed for ``target`` error: the first crossing along the curve, log-log interpolated."""
    if errors[0] <= target:
        return f"<= {work[0]} (loosest run)"
    le, lw = np.log10(errors), np.log10(work)
    for i in range(len(le) - 1):
        if le[i + 1] <= np.log10(target) < le[i]:
            frac = (np.log10(target) - le[i]) / (le[i + 1] - le[i])
            return f"{10 ** (lw[i] + frac * (lw[i + 1] - lw[i])):.0f}"
    return "not reached"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--problems", default=",".join(PROBLEMS))
    args = parser.parse_args()
    for name in args.problems.split(","):
        fun, tspan, y0, _ = PROBLEMS[name]
        ref = reference(name)
        print(f"\n### {name}\n")
        print("| method | rtol | fevals | steps | seconds | error |")
        print("|---|---:|---:|---:|---:|---:|")
        curves = {}
        for method in METHODS:
            errs, works = [], []
            for rtol in RTOLS:
                best = np.inf
                for _ in range(args.repeat):
                    elapsed, nfev, nsteps, y_end = run(method, fun, tspan, y0, rtol)
                    best = min(best, elapsed)
                err = float(np.abs(y_end - ref).max())
                errs.append(max(err, 1e-16))
                works.append(nfev)
                print(f"| {method} | {rtol:.0e} | {nfev} | {nsteps} | {best:.4f} | {err:.2e} |")
            curves[method] = (errs, works)
        print("\nfevals to reach an error of " + ", ".join(f"{t:.0e}" for t in TARGETS) + ":\n")
        for method, (errs, works) in curves.items():
            print(f"- {method}: " + ", ".join(work_to_reach(errs, works, target) for target in TARGETS))


if __name__ == "__main__":
    main()
