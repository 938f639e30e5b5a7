"""Benchmark: what the global error estimate costs (odelab.run.estimate), as a ratio to the run alone.

Two measurements, each in this process, serial (``run_case`` one case after another), best of
``--repeat``, the compiled backend warmed first:

* the shipped experiments (``experiments/``, networks included): every case run with
  ``estimate=False`` (the run alone), as ``odelab run`` does by default (the estimate for the
  cases without a reference, not a sweep's), and with ``estimate=True`` (every case);
* a 1,000-case sweep (a damped oscillator over 1,000 stiffness values, ode45, no reference):
  the default (a sweep's cases get no estimate unasked) and ``--estimate``.

    python bench/bench_estimate.py [--repeat 3] [--cases 1000]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SWEEP = """
[parameters]
k = 1
[system]
states = ["x", "v"]
[system.equations]
x = "v"
v = "-k*x - 0.2*v"
[initial]
x = 1
v = 0
[time]
stop = 20
[sweep]
"parameters.k" = {{ from = 1, to = 100, count = {cases} }}
"""


def _cases(paths):
    from odelab.experiment.loader import load_experiments

    return [case for path in paths for exp in load_experiments(path) for case in exp.cases]


def _time(cases, estimate, repeat):
    from odelab.run.runner import run_case

    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        for case in cases:
            run_case(case, estimate=estimate)
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--cases", type=int, default=1000)
    args = parser.parse_args()
    shipped = sorted((ROOT / "experiments").rglob("*.toml"))
    cases = _cases(shipped)
    _time(cases, None, 1)  # warm: compiled modules, caches
    alone = _time(cases, False, args.repeat)
    default = _time(cases, None, args.repeat)
    every = _time(cases, True, args.repeat)
    estimated = sum(1 for c in cases if not c.swept and c.problem.reference == "none" and c.problem.linearize is None)
    print(f"load average {os.getloadavg()[0]:.2f}")
    print(f"shipped experiments: {len(cases)} cases ({estimated} without a reference, outside a sweep)")
    print(f"  run alone            {alone:7.2f} s")
    print(f"  default              {default:7.2f} s   ratio {default / alone:.2f}")
    print(f"  every case estimated {every:7.2f} s   ratio {every / alone:.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sweep.toml"
        path.write_text(SWEEP.format(cases=args.cases))
        cases = _cases([path])
        _time(cases[:5], True, 1)
        alone = _time(cases, False, args.repeat)
        default = _time(cases, None, args.repeat)
        every = _time(cases, True, args.repeat)
    print(f"a {len(cases):,}-case sweep (ode45, no reference):")
    print(f"  run alone            {alone:7.2f} s")
    print(f"  default (no estimate in a sweep) {default:7.2f} s   ratio {default / alone:.2f}")
    print(f"  --estimate           {every:7.2f} s   ratio {every / alone:.2f}")


if __name__ == "__main__":
    main()
