"""Benchmark: `odelab report` of the lab's five experiments, cold and warm, per experiment.

Runs Exercise 1 on [0, pi] and [0, 2 pi], the rigid body, Exercise 2 and Figure 1 into a
results folder (not timed), then builds the report in a fresh process each time:

- cold: an empty cache folder (every figure drawn, every template compiled), with the
  default ``--jobs`` (figures drawn across the cores) and with ``--jobs 1``;
- warm: the same runs again (the figures and templates come from the cache);
- one experiment (Exercise 1 alone), cold and warm.

Wall time and CPU time (user + system of the process and its workers), best of ``--repeat``.
Targets: at most 0.12 s per experiment, the lab's report in at most 2 s.

    python bench/bench_report.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAB = ("exercise1", "exercise1_2pi", "rigid_body", "exercise2", "figure1")
PER_EXPERIMENT = 0.12
LAB_TARGET = 2.0

CHILD = """
import resource, subprocess, sys
code = subprocess.call(sys.argv[1:], stdout=subprocess.DEVNULL)
r = resource.getrusage(resource.RUSAGE_CHILDREN)
print(r.ru_utime + r.ru_stime)
sys.exit(code)
"""


def timed(args: list[str], cwd: Path, cache: Path) -> tuple[float, float]:
    """Wall and CPU seconds of one ``odelab`` process with ``cache`` as its cache folder."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["ODELAB_CACHE_DIR"] = str(cache)
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", CHILD, sys.executable, "-m", "odelab.cli", *args], cwd=cwd,
                         env=env, capture_output=True, text=True, check=True)
    return time.perf_counter() - start, float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        files = [str(ROOT / "experiments" / f"{name}.toml") for name in LAB]
        timed(["run", *files, "--runs", "runs"], work, work / "run-cache")
        figures = 0

        def best(name: str, extra: list[str], cold: bool) -> tuple[float, float]:
            nonlocal figures
            walls, cpus = [], []
            for i in range(args.repeat):
                cache = work / f"cache-{name}-{i if cold else 0}"
                if cold:
                    shutil.rmtree(cache, ignore_errors=True)
                else:  # warm: built once before
                    timed(["report", "--runs", "runs", "--out", f"out-{name}", *extra], work, cache)
                wall, cpu = timed(["report", "--runs", "runs", "--out", f"out-{name}", *extra], work, cache)
                walls.append(wall)
                cpus.append(cpu)
                figures = max(figures, len(list((work / f"out-{name}" / "figures").glob("*.png"))))
            return min(walls), min(cpus)

        rows = [
            ("lab, cold (figures drawn across the cores)", best("cold", [], True), len(LAB)),
            ("lab, cold, --jobs 1", best("serial", ["--jobs", "1"], True), len(LAB)),
            ("lab, warm (unchanged runs)", best("warm", [], False), len(LAB)),
            ("exercise1 alone, cold", best("one", ["exercise1"], True), 1),
            ("exercise1 alone, warm", best("one-warm", ["exercise1"], False), 1),
        ]
    print(f"odelab report, best of {args.repeat} fresh processes; the lab: {', '.join(LAB)} ({figures} figures)")
    print(f"{'build':<46} {'wall s':>7} {'CPU s':>7} {'wall s per experiment':>22}")
    for name, (wall, cpu), n in rows:
        print(f"{name:<46} {wall:7.2f} {cpu:7.2f} {wall / n:22.3f}")
    cold = rows[0][1][0]
    print(f"lab cold: {cold:.2f} s ({'meets' if cold <= LAB_TARGET else 'MISSES'} the {LAB_TARGET} s target), "
          f"{cold / len(LAB):.3f} s per experiment ({'meets' if cold / len(LAB) <= PER_EXPERIMENT else 'MISSES'} "
          f"the {PER_EXPERIMENT} s target); warm: {rows[2][1][0] / len(LAB):.3f} s per experiment")


if __name__ == "__main__":
    main()
