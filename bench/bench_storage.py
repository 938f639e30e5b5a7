"""Benchmark: peak memory and time of a long run stored by ``odelab run`` (1 million steps).

The rigid body as an experiment file, ode45 with Refine 1 (one output row per step), over a
span long enough for about a million steps; ``odelab run`` in a fresh process per backend,
its peak resident memory read with ``getrusage`` (RUSAGE_CHILDREN). The trajectory is stored
as ``trajectory.npz`` (more than 100 000 rows). Not a test: run it and read the numbers
(target: at most 400 MB for a million steps stored).

    python bench/bench_storage.py [--stop 203000] [--backends compiled,python] [--csv-only]

First, the CSV formatting alone: the store's whole-block writer against value by value.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EXPERIMENT = """
title = "Rigid body, a million steps"
[parameters]
a = -0.51
[system]
states = ["y1", "y2", "y3"]
[system.equations]
y1 = "y2*y3"
y2 = "-y1*y3"
y3 = "a*y1*y2"
[initial]
y1 = 0
y2 = 1
y3 = 1
[time]
stop = {stop}
[solver]
method = "ode45"
rtol = 1e-6
atol = 1e-9
refine = 1
"""

CHILD = """
import resource, subprocess, sys
code = subprocess.call(sys.argv[1:])
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
sys.exit(code)
"""


def csv_formatting(rows: int = 100_000, repeat: int = 3) -> None:
    """The trajectory CSV of ``rows`` rows of 13 columns (the rigid body with its references and
    errors): the store's whole-block writer against formatting value by value, best of ``repeat``."""
    import numpy as np

    from odelab.store.results import _trajectory_csv

    rng = np.random.default_rng(1)
    data = rng.standard_normal((rows, 13))
    data[::50, 6] = np.nan  # relative errors undefined here and there
    names = [f"c{i}" for i in range(13)]

    def by_value():
        lines = [",".join(names)]
        lines.extend(",".join("" if v != v else repr(v) for v in row) for row in data.tolist())
        return "\n".join(lines) + "\n"

    def best(fn):
        times = []
        for _ in range(repeat):
            start = time.process_time()
            text = fn()
            times.append(time.process_time() - start)
        return min(times), text

    block, ours = best(lambda: _trajectory_csv(names, data))
    value, theirs = best(by_value)
    assert ours == theirs
    print(f"CSV of {rows} rows x 13 columns, CPU best of {repeat}: whole block {block:.3f} s, value by value "
          f"{value:.3f} s ({block / value:.2f}x), the same text")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=203000.0)
    parser.add_argument("--backends", default="compiled,python")
    parser.add_argument("--csv-only", action="store_true", help="only the CSV formatting comparison")
    args = parser.parse_args()
    csv_formatting()
    if args.csv_only:
        return
    with tempfile.TemporaryDirectory() as work:
        path = Path(work) / "million.toml"
        path.write_text(EXPERIMENT.format(stop=args.stop), encoding="utf-8")
        for backend in args.backends.split(","):
            runs = Path(work) / f"runs-{backend}"
            start = time.perf_counter()
            out = subprocess.run([sys.executable, "-c", CHILD, sys.executable, "-m", "odelab.cli", "run", str(path),
                                  "--runs", str(runs), "--backend", backend, "--max-steps", "0"],
                                 capture_output=True, text=True, env=os.environ)
            wall = time.perf_counter() - start
            peak_kb = int(out.stdout.strip().splitlines()[-1])
            record = json.loads(next(runs.rglob("result.json")).read_text())
            rows = record["points"]
            size = sum(p.stat().st_size for p in next(runs.rglob("result.json")).parent.iterdir())
            print(f"{backend:>9}: {record['stats']['nsteps']} steps, {rows} rows, {record['trajectory_file']} "
                  f"({size / 1e6:.1f} MB on disk); peak memory {peak_kb / 1024:.0f} MB "
                  f"({peak_kb * 1024 / rows:.0f} bytes per row); {wall:.1f} s wall")


if __name__ == "__main__":
    main()
