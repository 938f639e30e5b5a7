"""Compiled stiff solvers: odelab's ode23s and ode15s on the compiled backend, per step, against
SciPy's LSODA (its Fortran loop calling a Python right-hand side and Jacobian), in one run.

Problems (issue 27, target 3): Robertson on [0, 4e10] (rtol 1e-4, atol [1e-8, 1e-14, 1e-8]),
HIRES on [0, 321.8122] (Hairer & Wanner's test set; rtol 1e-4, atol 1e-7), van der Pol with
mu = 1000 on [0, 3000] (MATLAB's defaults) and a chain of 100 masses (200 states, rtol 1e-4,
atol 1e-7), written as experiment equations. odelab's runs use the exact Jacobian (complex step:
generated code on the compiled path, the expression compiler on the Python path, as an
experiment's stiff case does), and the compiled run is checked to take the Python path's steps
with the same statistics. LSODA gets hand-written numpy functions for f and its exact Jacobian
(the fastest Python a user would write). The figure is time per step (LSODA's own steps),
the best of ``--repeat`` runs after a warm-up; the first compile is timed separately (the
compiled column's time excludes it: the cache keeps it for later runs).

The chain's iteration matrices factor banded on both odelab paths (its equations' structure,
permuted by reverse Cuthill-McKee, has kl = ku = 3: odelab.solvers.banded); LSODA gets the
dense Jacobian a user would write and factors it dense (LINPACK, which does not thread). The
chain's figures are measured with ``OPENBLAS_NUM_THREADS=1`` (the header says which): on a
shared 2-core machine OpenBLAS's threads contend (a dense 200-by-200 factorisation took 3-16 ms
threaded under load, 0.7 ms on one thread).

    python bench/bench_compiled_stiff.py [--repeat 5] [--problems robertson,hires,vdp,chain]
                                         [--methods ode23s,ode15s] [--masses 100]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import odelab
from odelab.expressions import compile_vector
from odelab.solvers.compiled import CompiledSystem, solve_compiled
from odelab.systems.jacobian import complex_step_jacobian

ROBER = (["y1", "y2", "y3"], ["-0.04*y1 + 1e4*y2*y3", "0.04*y1 - 1e4*y2*y3 - 3e7*y2^2", "3e7*y2^2"])
HIRES = ([f"y{i}" for i in range(1, 9)],
         ["-1.71*y1 + 0.43*y2 + 8.32*y3 + 0.0007", "1.71*y1 - 8.75*y2", "-10.03*y3 + 0.43*y4 + 0.035*y5",
          "8.32*y2 + 1.71*y3 - 1.12*y4", "-1.745*y5 + 0.43*y6 + 0.43*y7",
          "-280*y6*y8 + 0.69*y4 + 1.71*y5 - 0.43*y6 + 0.69*y7", "280*y6*y8 - 1.81*y7", "-280*y6*y8 + 1.81*y7"])
VDP = (["x", "v"], ["v", "mu*(1 - x^2)*v - x"])


def chain_equations(n):
    states = [f"x{i}" for i in range(n)] + [f"v{i}" for i in range(n)]
    equations = [f"v{i}" for i in range(n)]
    for i in range(n):
        lx, rx = (f"x{i - 1}" if i else "0"), (f"x{i + 1}" if i < n - 1 else f"x{i}")
        lv, rv = (f"v{i - 1}" if i else "0"), (f"v{i + 1}" if i < n - 1 else f"v{i}")
        equations.append(f"k*({lx} - 2*x{i} + {rx}) + c*({lv} - 2*v{i} + {rv})" + (" + 1" if i == n - 1 else ""))
    return states, equations


def rober(t, y):
    return np.array([-0.04 * y[0] + 1e4 * y[1] * y[2], 0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2,
                     3e7 * y[1] ** 2])


def rober_jac(t, y):
    return np.array([[-0.04, 1e4 * y[2], 1e4 * y[1]], [0.04, -1e4 * y[2] - 6e7 * y[1], -1e4 * y[1]],
                     [0.0, 6e7 * y[1], 0.0]])


def hires(t, y):
    return np.array([-1.71 * y[0] + 0.43 * y[1] + 8.32 * y[2] + 0.0007, 1.71 * y[0] - 8.75 * y[1],
                     -10.03 * y[2] + 0.43 * y[3] + 0.035 * y[4], 8.32 * y[1] + 1.71 * y[2] - 1.12 * y[3],
                     -1.745 * y[4] + 0.43 * y[5] + 0.43 * y[6],
                     -280 * y[5] * y[7] + 0.69 * y[3] + 1.71 * y[4] - 0.43 * y[5] + 0.69 * y[6],
                     280 * y[5] * y[7] - 1.81 * y[6], -280 * y[5] * y[7] + 1.81 * y[6]])


def hires_jac(t, y):
    J = np.zeros((8, 8))
    J[0, :3] = -1.71, 0.43, 8.32
    J[1, :2] = 1.71, -8.75
    J[2, 2:5] = -10.03, 0.43, 0.035
    J[3, 1:4] = 8.32, 1.71, -1.12
    J[4, 4:7] = -1.745, 0.43, 0.43
    J[5, 3:8] = 0.69, 1.71, -0.43 - 280 * y[7], 0.69, -280 * y[5]
    J[6, 5:8] = 280 * y[7], -1.81, 280 * y[5]
    J[7, 5:8] = -280 * y[7], 1.81, -280 * y[5]
    return J


def vdp(t, y):
    return np.array([y[1], 1000.0 * (1 - y[0] ** 2) * y[1] - y[0]])


def vdp_jac(t, y):
    return np.array([[0.0, 1.0], [-2000.0 * y[0] * y[1] - 1.0, 1000.0 * (1 - y[0] ** 2)]])


def chain_functions(n, k=1e4, c=1e3):
    L = np.diag(-2.0 * np.ones(n)) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1)
    L[-1, -1] = -1.0  # free right end
    A = np.block([[np.zeros((n, n)), np.eye(n)], [k * L, c * L]])
    force = np.zeros(2 * n)
    force[-1] = 1.0

    def fun(t, y):
        return A @ y + force

    return fun, (lambda t, y: A)


def problems(masses):
    states, equations = chain_equations(masses)
    fun, jac = chain_functions(masses)
    return {
        "robertson": (*ROBER, {}, [0.0, 4e10], [1.0, 0.0, 0.0], dict(rtol=1e-4, atol=[1e-8, 1e-14, 1e-8]), rober,
                      rober_jac),
        "hires": (*HIRES, {}, [0.0, 321.8122], [1, 0, 0, 0, 0, 0, 0, 0.0057], dict(rtol=1e-4, atol=1e-7), hires,
                  hires_jac),
        "vdp": (*VDP, {"mu": 1000.0}, [0.0, 3000.0], [2.0, 0.0], dict(rtol=1e-3, atol=1e-6), vdp, vdp_jac),
        "chain": (states, equations, {"k": 1e4, "c": 1e3}, [0.0, 10.0], np.zeros(2 * masses),
                  dict(rtol=1e-4, atol=1e-7), fun, jac),
    }


def best(run, repeat):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return min(times), result


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--problems", default="robertson,hires,vdp,chain")
    parser.add_argument("--methods", default="ode23s,ode15s")
    parser.add_argument("--masses", type=int, default=100)
    args = parser.parse_args()
    from scipy.integrate import solve_ivp

    print(f"machine load (1 min): {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; best of {args.repeat}; "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    print(f"{'problem':10s} {'method':7s} {'steps':>6s} {'same':>5s} {'compile':>8s} {'compiled':>10s} "
          f"{'Python':>10s} {'LSODA':>10s} {'vs LSODA':>9s}")
    print(f"{'':10s} {'':7s} {'':>6s} {'':>5s} {'s':>8s} {'us/step':>10s} {'us/step':>10s} {'us/step':>10s} "
          f"{'ratio':>9s}")
    for name in args.problems.split(","):
        states, equations, parameters, tspan, y0, options, fun, jac = problems(args.masses)[name]
        t_lsoda, lsoda = best(lambda: solve_ivp(fun, tspan, y0, method="LSODA", jac=jac, rtol=options["rtol"],
                                                atol=options["atol"]), max(1, args.repeat // 2))
        lsoda_step = t_lsoda / (lsoda.t.size - 1) * 1e6  # LSODA reports no step count: its output points are its steps
        system = CompiledSystem.from_equations(states, equations, parameters)
        F = compile_vector(equations, args=["t", *states], constants=parameters)
        J = complex_step_jacobian(equations, states, parameters)
        for method in args.methods.split(","):
            start = time.perf_counter()
            solve_compiled(system, tspan, y0, method, jacobian=J, **options)  # compile (or load) first
            compile_s = time.perf_counter() - start
            t_c, compiled = best(lambda: solve_compiled(system, tspan, y0, method, jacobian=J, **options), args.repeat)
            t_p, python = best(lambda: odelab.solve(lambda t, x: F(t, *x), tspan, y0, method=method, jacobian=J,
                                                    **options), max(1, args.repeat // 2))
            same = compiled.stats == python.stats and np.array_equal(compiled.y, python.y)
            steps = compiled.stats.nsteps
            per_step = t_c / steps * 1e6
            print(f"{name:10s} {method:7s} {steps:6d} {'yes' if same else 'NO':>5s} {compile_s:8.2f} {per_step:10.2f} "
                  f"{t_p / steps * 1e6:10.1f} {lsoda_step:10.1f} {per_step / lsoda_step:8.3f}x")


if __name__ == "__main__":
    main()
