"""Benchmark: `odelab run experiments/exercise1.toml` end to end, as a user runs it, against GNU Octave.

Wall time of the whole process (interpreter start, imports, loading, both solves, error
tables, printing and storing), best of ``--repeat`` runs, against GNU Octave running the same
two solves as a script (``octave-cli``), the runs interleaved so that both see the same
machine. Also the floor odelab cannot go under: the interpreter with the packages the run needs
(numpy, typer, pydantic, rich) imported and nothing done. Wall and CPU time (user + system of
the process, which load does not blur). Target: at most 2x Octave's time.

    python bench/bench_run.py [--repeat 10]

Bytecode is written on the first run (as an installed odelab has it); PYTHONDONTWRITEBYTECODE
is cleared for the measured processes.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = 2.0

OCTAVE = """
[t, y] = ode23(@(t, y) cos(t), [0 pi], 2);
e23 = max(abs(sin(t) + 2 - y) ./ abs(sin(t) + 2));
[t, y] = ode45(@(t, y) cos(t), [0 pi], 2);
e45 = max(abs(sin(t) + 2 - y) ./ abs(sin(t) + 2));
printf('%g %g\\n', e23, e45);
"""

FLOOR = "import numpy, typer, pydantic, rich.console, rich.table"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=10)
    args = parser.parse_args()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    exp = str(ROOT / "experiments" / "exercise1.toml")
    with tempfile.TemporaryDirectory() as tmp:
        commands = {
            "odelab run exercise1.toml": [sys.executable, "-m", "odelab.cli", "run", exp, "--runs", "runs"],
            "odelab run exercise1.toml --jobs 1": [sys.executable, "-m", "odelab.cli", "run", exp, "--runs", "runs",
                                                   "--jobs", "1"],
            "odelab --help": [sys.executable, "-m", "odelab.cli", "--help"],
            "python: imports only (floor)": [sys.executable, "-c", FLOOR],
            "python -c pass": [sys.executable, "-c", "pass"],
        }
        octave = shutil.which("octave-cli")
        if octave:
            script = Path(tmp) / "ex1.m"
            script.write_text(OCTAVE)
            commands["octave-cli ex1.m"] = [octave, "--no-gui", "--quiet", str(script)]
        best = {name: float("inf") for name in commands}
        cpu = {name: float("inf") for name in commands}  # user + system of the process: what load does not blur
        for cmd in commands.values():  # warm-up: bytecode, disk cache
            subprocess.run(cmd, cwd=tmp, check=True, capture_output=True, env=env)
        for _ in range(args.repeat):  # interleaved: every command sees the same load
            for name, cmd in commands.items():
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                start = time.perf_counter()
                subprocess.run(cmd, cwd=tmp, check=True, capture_output=True, env=env)
                best[name] = min(best[name], time.perf_counter() - start)
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu[name] = min(cpu[name], after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    print(f"best of {args.repeat} interleaved runs, wall and CPU time of the whole process; load average "
          f"{os.getloadavg()[0]:.1f}")
    print(f"{'command':<38} {'wall s':>8} {'x Octave':>9} {'CPU s':>8} {'x Octave':>9}")
    ref, ref_cpu = best.get("octave-cli ex1.m"), cpu.get("octave-cli ex1.m")
    for name, seconds in best.items():
        ratio = f"{seconds / ref:8.2f}x" if ref else ""
        ratio_cpu = f"{cpu[name] / ref_cpu:8.2f}x" if ref_cpu else ""
        print(f"{name:<38} {seconds:8.3f} {ratio:>9} {cpu[name]:8.3f} {ratio_cpu:>9}")
    if ref:
        ratio = best["odelab run exercise1.toml"] / ref
        ratio_cpu = cpu["odelab run exercise1.toml"] / ref_cpu
        verdict = "meets" if ratio_cpu <= TARGET else "MISSES"
        print(f"odelab run / Octave: {ratio:.2f}x wall, {ratio_cpu:.2f}x CPU ({verdict} the target of {TARGET}x)")


if __name__ == "__main__":
    main()
