"""Benchmark: `odelab report` of the lab's five experiments and of the shipped set, cold and warm.

Runs Exercise 1 on [0, pi] and [0, 2 pi], the rigid body, Exercise 2 and Figure 1 into a
results folder, and every file in experiments/ (the shipped set) into another (not timed),
then builds the report in a fresh process each time:

- cold: an empty cache folder (every figure drawn, every template compiled), with the
  default ``--jobs`` (figures drawn across the cores) and with ``--jobs 1``;
- warm: the same runs again (the figures and templates come from the cache);
- one experiment (Exercise 1 alone), cold and warm;
- the shipped set, cold, with the default ``--jobs`` and with ``--jobs 1``.

Wall time and CPU time (user + system of the process and its workers), best of ``--repeat``.
Targets (issue 27): the lab's cold report in at most 2 s, at most 0.15 s an experiment on the
shipped set. The load average is printed: on a loaded machine CPU is the figure to trust.

``--figures`` instead draws the figures of the lab's report and of the shipped set's
(every file in experiments/) in this process, each figure's CPU time on a new figure
(no kept figure) and on a kept figure of as many panels (what a report does), interleaved,
in the order the report asks for them; the PNGs of both must be byte for byte the same.

    python bench/bench_report.py [--repeat 3] [--figures]
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
PER_EXPERIMENT = 0.15
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
    parser.add_argument("--figures", action="store_true", help="CPU a figure, new vs kept figures, in this process")
    args = parser.parse_args()
    if args.figures:
        figure_cpu(args.repeat)
        return
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        files = [str(ROOT / "experiments" / f"{name}.toml") for name in LAB]
        timed(["run", *files, "--runs", "runs"], work, work / "run-cache")
        shipped = sorted((ROOT / "experiments").glob("*.toml"))
        timed(["run", *map(str, shipped), "--runs", "shipped"], work, work / "run-cache")
        figures = 0
        load = os.getloadavg()[0]

        def best(name: str, extra: list[str], cold: bool, runs: str = "runs") -> tuple[float, float]:
            nonlocal figures
            walls, cpus = [], []
            for i in range(args.repeat):
                cache = work / f"cache-{name}-{i if cold else 0}"
                if cold:
                    shutil.rmtree(cache, ignore_errors=True)
                else:  # warm: built once before
                    timed(["report", "--runs", runs, "--out", f"out-{name}", *extra], work, cache)
                wall, cpu = timed(["report", "--runs", runs, "--out", f"out-{name}", *extra], work, cache)
                walls.append(wall)
                cpus.append(cpu)
                if runs == "runs":
                    figures = max(figures, len(list((work / f"out-{name}" / "figures").glob("*.png"))))
            return min(walls), min(cpus)

        rows = [
            ("lab, cold (figures drawn across the cores)", best("cold", [], True), len(LAB)),
            ("lab, cold, --jobs 1", best("serial", ["--jobs", "1"], True), len(LAB)),
            ("lab, warm (unchanged runs)", best("warm", [], False), len(LAB)),
            ("exercise1 alone, cold", best("one", ["exercise1"], True), 1),
            ("exercise1 alone, warm", best("one-warm", ["exercise1"], False), 1),
            (f"shipped set ({len(shipped)}), cold", best("shipped", [], True, "shipped"), len(shipped)),
            (f"shipped set ({len(shipped)}), cold, --jobs 1", best("shipped-serial", ["--jobs", "1"], True, "shipped"),
             len(shipped)),
        ]
        load = f"{load:.1f}-{os.getloadavg()[0]:.1f}"
    print(f"odelab report, best of {args.repeat} fresh processes, load average {load}; "
          f"the lab: {', '.join(LAB)} ({figures} figures)")
    print(f"{'build':<46} {'wall s':>7} {'CPU s':>7} {'wall s per experiment':>22}")
    for name, (wall, cpu), n in rows:
        print(f"{name:<46} {wall:7.2f} {cpu:7.2f} {wall / n:22.3f}")
    cold = rows[0][1][0]
    each = rows[5][1][0] / rows[5][2]
    print(f"lab cold: {cold:.2f} s ({'meets' if cold <= LAB_TARGET else 'MISSES'} the {LAB_TARGET} s target); "
          f"shipped set cold: {each:.3f} s an experiment ({'meets' if each <= PER_EXPERIMENT else 'MISSES'} "
          f"the {PER_EXPERIMENT} s target); warm: {rows[2][1][0] / len(LAB):.3f} s an experiment of the lab")


def _specs(runs: Path, out: Path) -> list:
    """The figure specs a build of the report of ``runs`` asks for, in its order (nothing drawn)."""
    from odelab.report import build, drawing

    asked: list = []
    real = drawing.render_pngs
    drawing.render_pngs = lambda specs, jobs=None: asked.extend(specs) or [b"" for _ in specs]
    try:
        build.build_report(runs, out, formats=("html",))
    finally:
        drawing.render_pngs = real
    return asked


def figure_cpu(repeat: int) -> None:
    import resource

    from odelab.report import plots

    def cpu() -> float:
        r = resource.getrusage(resource.RUSAGE_SELF)
        return r.ru_utime + r.ru_stime

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        os.environ["ODELAB_CACHE_DIR"] = str(work / "cache")
        sets = {}
        for name, files in (("lab", [ROOT / "experiments" / f"{n}.toml" for n in LAB]),
                            ("shipped set", sorted((ROOT / "experiments").glob("*.toml")))):
            subprocess.run([sys.executable, "-m", "odelab.cli", "run", *map(str, files), "--runs", name],
                           cwd=work, env=os.environ, capture_output=True, check=True)
            sets[name] = (_specs(work / name, work / f"out-{name}"), len(files))
    plots._draw_png(sets["lab"][0][0])  # fonts and imports, not timed
    print(f"CPU of the report's figures drawn in one process, best of {repeat}, interleaved; load average "
          f"{os.getloadavg()[0]:.1f} at the start")
    print(f"{'figures of':<14} {'n':>3} {'new figure s':>13} {'kept figure s':>14} {'ratio':>6} "
          f"{'s an experiment':>16}")
    for name, (specs, experiments) in sets.items():
        fresh, kept = [], []
        for _ in range(repeat):
            t, pngs = cpu(), []
            for spec in specs:
                plots._REUSABLE.clear()
                pngs.append(plots._draw_png(spec))
            fresh.append(cpu() - t)
            plots._REUSABLE.clear()
            t = cpu()
            same = [plots._draw_png(spec) for spec in specs] == pngs
            kept.append(cpu() - t)
            assert same, "a kept figure drew other bytes than a new one"
        print(f"{name:<14} {len(specs):3d} {min(fresh):13.2f} {min(kept):14.2f} {min(fresh) / min(kept):6.2f} "
              f"{min(kept) / experiments:16.3f}")


if __name__ == "__main__":
    main()
