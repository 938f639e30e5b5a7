"""Benchmark: `odelab grade` on a class of 100 students (copies of examples/grading's six), `--jobs 2`.

The class is the example's six submissions (correct, a wrong tolerance, a wrong sign, ode45 for
ode23, a broken TOML file, a Python function) copied round-robin into 100 students' folders.
Measured: the wall time of the whole `odelab grade rubric.toml CLASS --jobs 2` process
(interpreter start, imports, the reference, loading and running 100 x 4 cases, the checks,
writing the grades folder), best of ``--repeat``; and serially (``--jobs 1``) for comparison.
The scores are checked against the example's expected ones. Target: under a minute with 2 jobs.

    python bench/bench_grade.py [--students 100] [--repeat 3]
"""

from __future__ import annotations

import argparse
import csv
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "grading"
TARGET = 60.0
EXPECTED = {"broken-toml": "3", "correct": "8", "ode45-for-ode23": "5", "python-function": "5", "wrong-sign": "6",
            "wrong-tolerance": "5"}


def build_class(where: Path, students: int) -> Path:
    kinds = sorted(p.name for p in (EXAMPLE / "submissions").iterdir() if p.is_dir())
    folder = where / "class"
    for i in range(students):
        kind = kinds[i % len(kinds)]
        shutil.copytree(EXAMPLE / "submissions" / kind, folder / f"s{i:03d}-{kind}")
    shutil.copytree(EXAMPLE / "reference", where / "reference")
    shutil.copy(EXAMPLE / "rubric.toml", where / "rubric.toml")
    return folder


def run(where: Path, folder: Path, jobs: int) -> float:
    cmd = [sys.executable, "-m", "odelab.cli", "grade", str(where / "rubric.toml"), str(folder), "--out",
           str(where / f"grades-{jobs}"), "--jobs", str(jobs), "--json"]
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=where)
    elapsed = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"odelab grade failed ({proc.returncode}):\n{proc.stderr}")
    with open(where / f"grades-{jobs}" / "summary.csv") as fh:
        for row in csv.DictReader(fh):
            kind = row["student"].split("-", 1)[1]
            if row["total"] != EXPECTED[kind]:
                raise SystemExit(f"{row['student']} scored {row['total']}, expected {EXPECTED[kind]}")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--students", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        where = Path(tmp)
        folder = build_class(where, args.students)
        times = {jobs: [] for jobs in (2, 1)}
        for _ in range(args.repeat):
            for jobs in times:
                times[jobs].append(run(where, folder, jobs))
        same = all((where / "grades-2" / name).read_bytes() == (where / "grades-1" / name).read_bytes()
                   for name in ("summary.csv", "results.json"))
    best2, best1 = min(times[2]), min(times[1])
    print(f"odelab grade, {args.students} students (4 cases each), best of {args.repeat}:")
    print(f"  --jobs 2: {best2:6.2f} s   (all: {', '.join(f'{t:.2f}' for t in times[2])})")
    print(f"  --jobs 1: {best1:6.2f} s   (all: {', '.join(f'{t:.2f}' for t in times[1])})")
    print(f"  summary.csv and results.json identical with 1 and 2 jobs: {same}")
    print(f"  target: under {TARGET:.0f} s with --jobs 2: {'met' if best2 < TARGET else 'NOT met'}")


if __name__ == "__main__":
    main()
