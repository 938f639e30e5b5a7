"""Benchmark: a class's worth of small experiment files in one ``odelab run``, CPU per file.

Writes ``--files`` small experiment files (Exercise 1's equation with a different initial value
and stop time each, one ode45 case, an exact solution, so an error table), runs
``odelab run FOLDER --runs RUNS`` in a fresh process, stored, and reads the process's CPU time
(user + system, ``getrusage`` of the child), best of ``--repeat``. CPU per file is that time
over the number of files, start-up included; the marginal cost (the same batch minus a
one-file run, over files - 1) is printed too. Target: at most 4 ms CPU per file for 200 files.

    python bench/bench_batch.py [--files 200] [--repeat 3] [--profile]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_MS = 4.0

EXPERIMENT = """title = "Student {i}: dy/dt = cos(t), y(0) = {y0}"

[system]
states = ["y"]

[system.equations]
y = "cos(t)"

[initial]
y = {y0}

[time]
stop = {stop}

[exact]
y = "sin(t) + {y0}"

[solver]
method = "ode45"
"""


def write_batch(folder: Path, files: int) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(files):
        text = EXPERIMENT.format(i=i, y0=1 + i % 7, stop=round(3 + (i % 10) * 0.25, 2))
        (folder / f"student{i:03d}.toml").write_text(text, encoding="utf-8")


CHILD = """
import resource, subprocess, sys
code = subprocess.call(sys.argv[1:], stdout=subprocess.DEVNULL)
r = resource.getrusage(resource.RUSAGE_CHILDREN)
print(r.ru_utime, r.ru_stime)
sys.exit(code)
"""


def cpu_of(args: list[str], cwd: str) -> tuple[float, float, float]:
    """CPU seconds (user + system), wall seconds and system CPU seconds of one ``odelab`` process."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", CHILD, sys.executable, "-m", "odelab.cli", *args],
                         capture_output=True, text=True, cwd=cwd, env=os.environ, check=True)
    user, system = map(float, out.stdout.strip().splitlines()[-1].split())
    return user + system, time.perf_counter() - start, system


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--jobs", type=int, default=None, help="passed to odelab run (default: its own)")
    parser.add_argument("--profile", action="store_true", help="cProfile one batch in this process instead")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        batch = Path(tmp) / "batch"
        write_batch(batch, args.files)
        one = Path(tmp) / "one"
        write_batch(one, 1)
        if args.profile:
            _profile(batch, Path(tmp) / "runs")
            return
        jobs = ["--jobs", str(args.jobs)] if args.jobs else []
        cpu_of(["run", str(one), "--runs", "warm"], tmp)  # bytecode written, caches warm
        single = min(cpu_of(["run", str(one), "--runs", "runs1"], tmp)[0] for _ in range(args.repeat))
        best_cpu, best_wall, best_sys = float("inf"), float("inf"), float("inf")
        for _ in range(args.repeat):
            cpu, wall, system = cpu_of(["run", str(batch), "--runs", "runs", *jobs], tmp)
            if cpu < best_cpu:
                best_cpu, best_sys = cpu, system
            best_wall = min(best_wall, wall)
        stored = sum(1 for _ in (Path(tmp) / "runs").rglob("result.json"))
    per_file = best_cpu / args.files * 1e3
    marginal = (best_cpu - single) / max(args.files - 1, 1) * 1e3
    print(f"{args.files} files, one ode45 case each, stored ({stored} cases), "
          f"{'--jobs ' + str(args.jobs) if args.jobs else 'default --jobs'}; best of {args.repeat} processes")
    print(f"{'measure':<34} {'value':>10}")
    print(f"{'batch CPU (user + system)':<34} {best_cpu:>8.3f} s")
    print(f"{'  of which system (kernel)':<34} {best_sys:>8.3f} s")
    print(f"{'batch wall':<34} {best_wall:>8.3f} s")
    print(f"{'one-file run CPU (start-up)':<34} {single:>8.3f} s")
    print(f"{'CPU per file, start-up included':<34} {per_file:>7.2f} ms")
    print(f"{'CPU per further file':<34} {marginal:>7.2f} ms")
    verdict = "meets" if per_file <= TARGET_MS else "MISSES"
    print(f"CPU per file {per_file:.2f} ms ({verdict} the target of {TARGET_MS} ms)")


def _profile(batch: Path, runs: Path) -> None:
    import cProfile
    import pstats

    from odelab.cli import app

    profiler = cProfile.Profile(time.process_time)  # CPU time: a loaded machine does not blur it
    profiler.enable()
    try:
        app(["run", str(batch), "--runs", str(runs), "--jobs", "1"], standalone_mode=False)
    except SystemExit:
        pass
    profiler.disable()
    pstats.Stats(profiler, stream=sys.stderr).sort_stats(os.environ.get("SORT", "cumulative")).print_stats(45)


if __name__ == "__main__":
    main()
