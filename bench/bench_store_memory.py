"""Peak memory of a long run against the trajectory it stores: the store streams what it writes.

``odelab run`` of the rigid body (experiments/rigid_body.toml) over [0, 200000] with
``--max-steps 0``: 676,532 ode45 steps on the compiled backend and 2,706,129 output rows (Refine 4),
stored as an 87 MB trajectory.npz (t and three states, 8 bytes a value; the file's high-accuracy
[reference] is set to "none" unless ``--reference``); the steps and rows are read from the stored
result.json and printed. The compiled loop writes the rows to a spool beside the case's folder as
its blocks fill (odelab.store.spool), and the store assembles trajectory.npz from it. The run is a
subprocess; its peak resident memory is read from ``getrusage(RUSAGE_CHILDREN)`` (the largest of
the processes it waited for) and set against the stored trajectory's size, and against the floor a
run cannot go under: the same run over [0, 1] (Python, numpy, numba, the compiled loops and this
system's module loaded, a few steps run). Printed: the peak, the floor, the peak above the floor, and
both over the trajectory. Once with a cold compile cache (a fresh ``ODELAB_CACHE_DIR``: numba compiles
the loop) and once warm (the same folder again). Target: peak <= 2 x the trajectory (not reachable
here: the floor alone is 2.1x this trajectory), so the figure to watch is the peak above the floor.
``--extra "--no-estimate"`` leaves out the error estimate's second solve (default on for a case
without a reference, docs/guide/trust.md).

    python bench/bench_store_memory.py [--stop 200000] [--keep DIR] [--extra "--no-estimate"]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = 2.0


def _child_peak(cmd: list[str], env: dict) -> tuple[int, float, subprocess.CompletedProcess]:
    """Run ``cmd`` in a fresh forked helper (so RUSAGE_CHILDREN holds this command alone); its peak RSS in bytes."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the helper: runs the command, reports its children's peak
        os.close(read)
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=ROOT)
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024  # KiB on Linux
        cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
        with os.fdopen(write, "w") as f:
            f.write(f"{peak} {cpu.ru_utime + cpu.ru_stime} {done.returncode}\n{done.stdout}\n{done.stderr}")
        os._exit(0)
    os.close(write)
    with os.fdopen(read) as f:
        head, _, rest = f.read().partition("\n")
    os.waitpid(pid, 0)
    peak, cpu, code = head.split()
    return int(peak), float(cpu), subprocess.CompletedProcess(cmd, int(code), rest, "")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=200000)
    parser.add_argument("--reference", action="store_true",
                        help="keep the file's high-accuracy [reference] (13 columns: each state's reference and "
                             "errors; its values at 3.9 million points take minutes)")
    parser.add_argument("--keep", type=Path, help="keep the results folder and cache here")
    parser.add_argument("--extra", default="", help="more `odelab run` options, space separated")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        base = args.keep or Path(tmp)
        base.mkdir(parents=True, exist_ok=True)
        text = (ROOT / "experiments" / "rigid_body.toml").read_text()
        path = base / "rigid_body_long.toml"
        text = re.sub(r"(?m)^stop = .*$", f"stop = {args.stop:g}", text)
        if not args.reference:  # as measured in issue 38: t and the three states, 126 MB
            text = text.replace('method = "high-accuracy"', 'method = "none"')
        path.write_text(text)
        short = base / "rigid_body_floor.toml"
        short.write_text(re.sub(r"(?m)^stop = .*$", "stop = 1", text))
        env = dict(os.environ, ODELAB_CACHE_DIR=str(base / "cache"), COLUMNS="120")
        env.setdefault("PYTHONPATH", str(ROOT / "src"))
        rows = []
        for label in ("cold cache", "warm cache"):
            runs = base / f"runs-{label.split()[0]}"
            shutil.rmtree(runs, ignore_errors=True)
            peak, cpu, done = _child_peak([sys.executable, "-m", "odelab.cli", "run", str(path), "--runs", str(runs),
                                           "--max-steps", "0", "--jobs", "1", *args.extra.split()], env)
            if done.returncode != 0:
                print(done.stdout)
                return 1
            stored = sorted(runs.rglob("trajectory.*"))
            size = sum(p.stat().st_size for p in stored)
            rows.append((label, peak, cpu, size, stored))
        floor, _, _ = _child_peak([sys.executable, "-m", "odelab.cli", "run", str(short), "--runs",
                                   str(base / "runs-floor"), "--jobs", "1", "--backend", "compiled",
                                   *args.extra.split()], env)
        record = json.loads(next((base / "runs-warm").rglob("result.json")).read_text())
        print(f"odelab run rigid body over [0, {args.stop:g}], --max-steps 0 {args.extra}: "
              f"{record['stats']['nsteps']:,} steps, {record['points']:,} rows (PYTHONPATH={env['PYTHONPATH']})")
        print(f"  floor (the same run over [0, 1] on the compiled backend, warm cache): {floor / 1e6:.0f} MB")
        for label, peak, cpu, size, stored in rows:
            print(f"  {label}: peak RSS {peak / 1e6:.0f} MB, floor {floor / 1e6:.0f} MB, above the floor "
                  f"{(peak - floor) / 1e6:.0f} MB; stored {', '.join(p.name for p in stored)} {size / 1e6:.0f} MB: "
                  f"peak / trajectory {peak / size:.2f}x (target <= {TARGET:g}x), above the floor / trajectory "
                  f"{(peak - floor) / size:.2f}x; CPU {cpu:.1f} s")
        return 0 if all(peak <= TARGET * size for _, peak, _, size, _ in rows) else 1

if __name__ == "__main__":
    sys.exit(main())
