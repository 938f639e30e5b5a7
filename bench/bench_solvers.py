"""Benchmark: odelab's ode45 against SciPy's RK45 (and GNU Octave's ode45 if installed).

The rigid-body problem of MATLAB's documentation over [0, 1200] with rtol 1e-6, atol 1e-9,
the same Python right-hand side for odelab and SciPy. The methods take different numbers of
steps (MATLAB's controller is not SciPy's), so the figure compared is the time per accepted
step; each solver runs ``--repeat`` times interleaved and the best time is kept, so a busy
machine slows both alike. Not a test: run it and read the ratio.

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
TARGET = 0.7  # odelab's time per step must be at most this fraction of SciPy's


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def time_odelab():
    start = time.perf_counter()
    sol = odelab.ode45(rigid, TSPAN, Y0, rtol=RTOL, atol=ATOL)
    return time.perf_counter() - start, sol.stats.nsteps


def time_scipy():
    start = time.perf_counter()
    res = solve_ivp(rigid, TSPAN, Y0, method="RK45", rtol=RTOL, atol=ATOL)
    return time.perf_counter() - start, res.t.size - 1


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
    best = {"odelab ode45": (np.inf, 0), "SciPy RK45": (np.inf, 0)}
    for _ in range(args.repeat):
        for name, fn in (("odelab ode45", time_odelab), ("SciPy RK45", time_scipy)):
            seconds, steps = fn()
            best[name] = min(best[name], (seconds, steps))
    octave = time_octave(max(1, args.repeat // 3))
    if octave is not None:
        best["Octave ode45"] = octave
    scipy_per_step = best["SciPy RK45"][0] / best["SciPy RK45"][1]
    print(f"rigid body, t in {list(TSPAN)}, rtol {RTOL:g}, atol {ATOL:g}, best of {args.repeat}")
    print(f"{'solver':<14} {'steps':>7} {'seconds':>9} {'us/step':>9} {'x SciPy/step':>13}")
    for name, (seconds, steps) in best.items():
        per_step = seconds / steps
        print(f"{name:<14} {steps:>7d} {seconds:>9.4f} {per_step * 1e6:>9.2f} {per_step / scipy_per_step:>13.2f}")
    if octave is None:
        print("(GNU Octave: octave-cli not found; `apt-get install octave` to include it)")
    ratio = (best["odelab ode45"][0] / best["odelab ode45"][1]) / scipy_per_step
    verdict = "meets" if ratio <= TARGET else "MISSES"
    print(f"odelab/SciPy time per step: {ratio:.2f} ({verdict} the target of {TARGET})")


if __name__ == "__main__":
    main()
