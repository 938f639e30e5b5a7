"""Benchmark: the adaptive driver's time per step with and without events, against SciPy's RK45.

Events, NonNegative and dense output are steps of the one driver; a run with no events must
not pay for them. This times MATLAB's rigid body over [0, 1200] (rtol 1e-6, atol 1e-9) with
odelab's ode45 (no events; then an event on y1 = 0, about 390 crossings) and SciPy's RK45, best
of ``--repeat`` interleaved runs, in one process per source tree given with ``--src`` — so
an older checkout (``git worktree add /tmp/before <commit>``) and the current one are compared
in one run, each against SciPy on the same machine at the same time. Not a test.

    python bench/bench_events.py [--repeat 7] [--src /tmp/before/src --src src]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

CHILD = r"""
import json, sys, time
import numpy as np
from scipy.integrate import solve_ivp
import odelab

def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])

def crossing(t, y):
    return [y[0]], [0], [0]

kw = dict(rtol=1e-6, atol=1e-9)
runs = {
    "ode45": lambda: odelab.ode45(rigid, [0, 1200], [0, 1, 1], **kw),
    "scipy": lambda: solve_ivp(rigid, [0, 1200], [0, 1, 1], method="RK45", **kw),
}
try:
    odelab.ode45(rigid, [0, 1], [0, 1, 1], events=crossing)
    runs["ode45+events"] = lambda: odelab.ode45(rigid, [0, 1200], [0, 1, 1], events=crossing, **kw)
except (TypeError, ValueError):
    pass  # a tree from before events
best = {name: float("inf") for name in runs}
steps = {}
for _ in range(int(sys.argv[1])):
    for name, run in runs.items():
        start = time.perf_counter()
        out = run()
        best[name] = min(best[name], time.perf_counter() - start)
        steps[name] = out.t.size - 1 if name == "scipy" else out.stats.nsteps
print(json.dumps({name: [best[name], steps[name]] for name in runs}))
"""


def measure(src: str, repeat: int) -> dict:
    env = dict(os.environ, PYTHONPATH=os.path.abspath(src))
    out = subprocess.run([sys.executable, "-c", CHILD, str(repeat)], env=env, capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--src", action="append", help="a source tree holding odelab/ (default: ./src)")
    args = parser.parse_args()
    sources = args.src or [os.path.join(os.path.dirname(__file__), "..", "src")]
    print(f"rigid body [0, 1200], rtol 1e-6, atol 1e-9, best of {args.repeat}")
    print(f"{'tree':<28} {'run':<14} {'steps':>6} {'us/step':>8} {'x SciPy/step':>13}")
    for src in sources:
        result = measure(src, args.repeat)
        scipy_seconds, scipy_steps = result["scipy"]
        scipy_per_step = scipy_seconds / scipy_steps
        for name, (seconds, steps) in result.items():
            per_step = seconds / steps
            print(f"{src[-28:]:<28} {name:<14} {steps:>6d} {per_step * 1e6:>8.2f} {per_step / scipy_per_step:>13.2f}")


if __name__ == "__main__":
    main()
