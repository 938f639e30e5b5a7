"""Benchmark: `odelab run experiments/exercise1.toml` end to end, as a user runs it.

Wall time of the whole process (interpreter start, imports, loading, both solves, error
tables, printing and storing), best of ``--repeat`` runs, against GNU Octave running the same
two solves as a script (when ``octave-cli`` is installed). Target: under 0.4 s.

    python bench/bench_run.py [--repeat 10]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = 0.4

OCTAVE = """
[t, y] = ode23(@(t, y) cos(t), [0 pi], 2);
e23 = max(abs(sin(t) + 2 - y) ./ abs(sin(t) + 2));
[t, y] = ode45(@(t, y) cos(t), [0 pi], 2);
e45 = max(abs(sin(t) + 2 - y) ./ abs(sin(t) + 2));
printf('%g %g\\n', e23, e45);
"""


def best_wall(cmd: list[str], repeat: int, cwd: str) -> float:
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run(cmd, cwd=cwd, check=True, capture_output=True)
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=10)
    args = parser.parse_args()
    odelab = shutil.which("odelab", path=str(Path(sys.executable).parent)) or "odelab"
    with tempfile.TemporaryDirectory() as tmp:
        exp = str(ROOT / "experiments" / "exercise1.toml")
        rows = [("odelab run exercise1.toml", best_wall([odelab, "run", exp, "--runs", "runs"], args.repeat, tmp))]
        rows.append(("odelab --help", best_wall([odelab, "--help"], args.repeat, tmp)))
        octave = shutil.which("octave-cli")
        if octave:
            script = Path(tmp) / "ex1.m"
            script.write_text(OCTAVE)
            rows.append(("octave-cli ex1.m", best_wall([octave, "--no-gui", "--quiet", str(script)],
                                                       max(3, args.repeat // 3), tmp)))
    print(f"best of {args.repeat} runs, wall time of the whole process")
    for name, seconds in rows:
        print(f"{name:<28} {seconds:6.3f} s")
    verdict = "meets" if rows[0][1] < TARGET else "MISSES"
    print(f"odelab run: {rows[0][1]:.3f} s ({verdict} the target of {TARGET} s)")


if __name__ == "__main__":
    main()
