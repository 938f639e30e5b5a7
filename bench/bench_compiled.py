"""Benchmark: the compiled backend on a long run of an expression system, against SciPy's RK45.

MATLAB's rigid body, written as an experiment file's equations, over [0, 12000] with rtol 1e-6,
atol 1e-9. Measured in one run, on this machine:

* SciPy's RK45 with the equivalent Python right-hand side (time per accepted step);
* odelab's Python path on the same expression system (``backend = "python"``);
* odelab's compiled path with a warm cache (best of ``--repeat``), per step;
* the first run in a fresh process with an empty cache: import, generating the module,
  numba's compile and the solve, end to end (``python -c`` in a subprocess).
* a second process with that cache now warm: import, load and solve.
* a third process solving a new system (a damped oscillator driven by a sine input) with the
  loops cached: only its right-hand side is compiled; the first run a student sees on a machine
  where odelab has run before.
* a fourth process solving the bouncing ball with [events]: the events loop's one-time compile.

Not a test: run it and read the ratios (target: compiled ≤ 0.01x SciPy per step, first run ≤ 4 s).

    python bench/bench_compiled.py [--repeat 5] [--stop 12000]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

Y0 = (0.0, 1.0, 1.0)
RTOL, ATOL = 1e-6, 1e-9

CHILD = """
import time
start = time.perf_counter()
from odelab.solvers.compiled import CompiledSystem, solve_compiled
system = CompiledSystem.from_equations(["y1", "y2", "y3"], ["y2*y3", "-y1*y3", "a*y1*y2"], {{"a": -0.51}})
sol = solve_compiled(system, [0, {stop}], [0, 1, 1], "ode45", rtol={rtol}, atol={atol})
print(sol.stats.nsteps, time.perf_counter() - start)
"""


NEW_SYSTEM = """
import time
start = time.perf_counter()
from odelab.signals import Sine
from odelab.solvers.compiled import CompiledSystem, solve_compiled
system = CompiledSystem.from_system(["x", "v"], ["v", "(f - b*v - k*x)/m"], {{"m": 1.0, "b": 0.4, "k": 3.0}},
                                    inputs=["f"]).with_signals([Sine(amplitude=1.0, frequency=0.2)])
sol = solve_compiled(system, [0, {stop}], [0, 0], "ode45", rtol={rtol}, atol={atol})
print(sol.stats.nsteps, time.perf_counter() - start)
"""

EVENTS = """
import time
start = time.perf_counter()
from odelab.solvers.compiled import CompiledSystem, solve_compiled
ball = CompiledSystem.from_equations(["h", "v"], ["v", "-g"], {{"g": 9.81}}).with_events(["h"], [True], [-1],
                                                                                       {{"g": 9.81}})
sol = solve_compiled(ball, [0, 10], [10, 0], "ode45")
print(sol.stats.nsteps, time.perf_counter() - start)
"""


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def child(stop: float, cache: str, code: str = CHILD) -> tuple[float, float]:
    """Wall time of a fresh process (interpreter start included) and the in-process time."""
    env = {**os.environ, "ODELAB_CACHE_DIR": cache}
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code.format(stop=stop, rtol=RTOL, atol=ATOL)], env=env,
                         capture_output=True, text=True, check=True).stdout.split()
    return time.perf_counter() - start, float(out[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--stop", type=float, default=12000.0)
    args = parser.parse_args()
    from scipy.integrate import solve_ivp

    import odelab
    from odelab.solvers.compiled import CompiledSystem, solve_compiled

    tspan = (0.0, args.stop)
    with tempfile.TemporaryDirectory() as cache:
        first_wall, first_inside = child(args.stop, cache)
        warm_wall, warm_inside = child(args.stop, cache)
        new_wall, new_inside = child(args.stop, cache, NEW_SYSTEM)
        events_wall, events_inside = child(args.stop, cache, EVENTS)
        os.environ["ODELAB_CACHE_DIR"] = cache
        system = CompiledSystem.from_equations(["y1", "y2", "y3"], ["y2*y3", "-y1*y3", "a*y1*y2"], {"a": -0.51})
        system.module()
        best = {"scipy": np.inf, "python": np.inf, "compiled": np.inf}
        steps = {}
        from odelab.experiment.build import expr

        F = expr().compile_vector(["y2*y3", "-y1*y3", "a*y1*y2"], args=["t", "y1", "y2", "y3"], constants={"a": -0.51})
        for _ in range(args.repeat):
            start = time.perf_counter()
            res = solve_ivp(rigid, tspan, Y0, method="RK45", rtol=RTOL, atol=ATOL)
            best["scipy"] = min(best["scipy"], time.perf_counter() - start)
            steps["scipy"] = res.t.size - 1
            start = time.perf_counter()
            sol = odelab.ode45(lambda t, x: F(t, *x), tspan, Y0, rtol=RTOL, atol=ATOL)
            best["python"] = min(best["python"], time.perf_counter() - start)
            steps["python"] = sol.stats.nsteps
            start = time.perf_counter()
            sol = solve_compiled(system, tspan, Y0, "ode45", rtol=RTOL, atol=ATOL)
            best["compiled"] = min(best["compiled"], time.perf_counter() - start)
            steps["compiled"] = sol.stats.nsteps
    per = {k: best[k] / steps[k] for k in best}
    print(f"rigid body [0, {args.stop:g}], rtol {RTOL:g}, atol {ATOL:g}, best of {args.repeat}")
    print(f"{'solver':<30}{'steps':>8}{'seconds':>10}{'µs/step':>10}{'x SciPy/step':>14}")
    for name, label in (("scipy", "SciPy RK45 (Python rhs)"), ("python", "odelab ode45, python path"),
                        ("compiled", "odelab ode45, compiled (warm)")):
        print(f"{label:<30}{steps[name]:>8}{best[name]:>10.4f}{per[name] * 1e6:>10.3f}{per[name] / per['scipy']:>14.4f}")
    print(f"first run, empty cache (fresh process, compile included): {first_wall:.2f} s wall "
          f"({first_inside:.2f} s inside Python)")
    print(f"second run, warm cache (fresh process): {warm_wall:.2f} s wall ({warm_inside:.2f} s inside Python)")
    print(f"a new system with a sine input, loops cached (fresh process): {new_wall:.2f} s wall "
          f"({new_inside:.2f} s inside Python)")
    print(f"bouncing ball with [events], first use of the events loop (fresh process): {events_wall:.2f} s wall "
          f"({events_inside:.2f} s inside Python)")


if __name__ == "__main__":
    main()
