"""Benchmark: odelab's ode45 against SciPy's RK45 (and GNU Octave's ode45 if installed).

The rigid-body problem of MATLAB's documentation over [0, 1200] with rtol 1e-6, atol 1e-9,
the same Python right-hand side for odelab and SciPy. The methods take different numbers of
steps (MATLAB's controller is not SciPy's), so the figure compared is the time per accepted
step; each solver runs ``--repeat`` times interleaved and the best time is kept, so a busy
machine slows both alike. Both the wall time and the process's CPU time are reported: on a
machine shared with other work the CPU time is the steadier of the two (time spent waiting
for a core is not counted). Not a test: run it and read the ratio (target: at most 0.40).

    python bench/bench_solvers.py [--repeat 7]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import tempfile
import time

import numpy as np
from scipy.integrate import solve_ivp

import odelab

TSPAN = (0.0, 1200.0)
Y0 = (0.0, 1.0, 1.0)
RTOL, ATOL = 1e-6, 1e-9
TARGET = 0.40  # odelab's time per step must be at most this fraction of SciPy's (issue 13)


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def time_odelab():
    start, cpu = time.perf_counter(), time.process_time()
    sol = odelab.ode45(rigid, TSPAN, Y0, rtol=RTOL, atol=ATOL)
    return time.perf_counter() - start, time.process_time() - cpu, sol.stats.nsteps


def time_scipy():
    start, cpu = time.perf_counter(), time.process_time()
    res = solve_ivp(rigid, TSPAN, Y0, method="RK45", rtol=RTOL, atol=ATOL)
    return time.perf_counter() - start, time.process_time() - cpu, res.t.size - 1


OCTAVE_SCRIPT = """
rigid = @(t, y) [y(2)*y(3); -y(1)*y(3); -0.51*y(1)*y(2)];
opts = odeset('RelTol', {rtol}, 'AbsTol', {atol});
best = Inf;
for k = 1:{repeat}
  tic; sol = ode45(rigid, [{t0} {tf}], [{y0}], opts); el = toc;
  best = min(best, el);
end
printf('steps %d seconds %.9f\\n', numel(sol.x) - 1, best);
"""


def time_octave(repeat: int):
    exe = shutil.which("octave-cli")
    if exe is None:
        return None
    script = OCTAVE_SCRIPT.format(rtol=RTOL, atol=ATOL, repeat=repeat, t0=TSPAN[0], tf=TSPAN[1],
                                  y0=" ".join(map(str, Y0)))
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bench_rigid.m")
        with open(path, "w") as fh:
            fh.write(script)
        out = subprocess.run([exe, "--no-gui", "--quiet", path], capture_output=True, text=True, timeout=1800)
    match = re.search(r"steps (\d+) seconds ([0-9.eE+-]+)", out.stdout)
    if not match:
        return None
    return float(match.group(2)), int(match.group(1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    time_odelab(), time_scipy()  # warm-up: imports and caches
    wall = {"odelab ode45": np.inf, "SciPy RK45": np.inf}
    cpu = dict(wall)
    steps = {}
    for _ in range(args.repeat):
        for name, fn in (("odelab ode45", time_odelab), ("SciPy RK45", time_scipy)):
            seconds, cpu_seconds, steps[name] = fn()
            wall[name] = min(wall[name], seconds)
            cpu[name] = min(cpu[name], cpu_seconds)
    octave = time_octave(max(1, args.repeat // 3))
    if octave is not None:
        wall["Octave ode45"], steps["Octave ode45"] = octave
    scipy_wall = wall["SciPy RK45"] / steps["SciPy RK45"]
    scipy_cpu = cpu["SciPy RK45"] / steps["SciPy RK45"]
    print(f"rigid body, t in {list(TSPAN)}, rtol {RTOL:g}, atol {ATOL:g}, Python right-hand side, best of {args.repeat}")
    print(f"{'solver':<14} {'steps':>7} {'wall us/step':>13} {'x SciPy':>8} {'CPU us/step':>12} {'x SciPy':>8}")
    for name in wall:
        per_step = wall[name] / steps[name]
        row = f"{name:<14} {steps[name]:>7d} {per_step * 1e6:>13.2f} {per_step / scipy_wall:>8.3f}"
        if name in cpu:
            per_cpu = cpu[name] / steps[name]
            row += f" {per_cpu * 1e6:>12.2f} {per_cpu / scipy_cpu:>8.3f}"
        print(row)
    if octave is None:
        print("(GNU Octave: octave-cli not found; `apt-get install octave` to include it)")
    for label, ratio in (("wall", (wall["odelab ode45"] / steps["odelab ode45"]) / scipy_wall),
                         ("CPU", (cpu["odelab ode45"] / steps["odelab ode45"]) / scipy_cpu)):
        verdict = "meets" if ratio <= TARGET else "MISSES"
        print(f"odelab/SciPy time per step ({label}): {ratio:.3f} ({verdict} the target of {TARGET})")


if __name__ == "__main__":
    main()
