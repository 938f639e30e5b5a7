"""Every stored result of the shipped experiments, byte for byte, between two source trees.

Runs ``odelab run experiments/ --runs FOLDER`` once with each tree's ``src`` on PYTHONPATH (a
fresh process each, serial, so that the order of work cannot matter) and compares the two
results folders file by file: the same files, the same bytes, except result.json's ``created``
timestamp and the wall times (``elapsed_s`` and ``seconds``, in the JSON files and sweep.csv's columns).
A refactoring that claims "results bit-identical" runs this before landing:

    python bench/compare_stored.py --before /tmp/base/src --after src [--keep DIR [--reuse]] [files...]

Give each tree as a copy that nobody edits while it runs (``git archive COMMIT src | tar -x -C DIR``):
the runs take minutes. ``--reuse`` keeps a ``before`` folder already in ``--keep`` (the base runs once).

Exit 0 when every file matches, 1 with the differing files listed.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# result.json keys that record when and how long, not what (wall clock).
VOLATILE = {"created", "elapsed", "elapsed_s", "wall", "wall_s", "seconds"}


def run(src: Path, runs: Path, files: list[str], extra: list[str]) -> int:
    env = dict(os.environ, PYTHONPATH=str(src.resolve()), COLUMNS="200")
    cmd = [sys.executable, "-m", "odelab.cli", "run", *files, "--runs", str(runs), "--jobs", "1", *extra]
    done = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True)
    (runs.parent / f"{runs.name}.out").write_text(done.stdout + done.stderr)
    return done.returncode


def _scrub(value):
    if isinstance(value, dict):
        return {k: _scrub(v) for k, v in value.items() if k not in VOLATILE}
    if isinstance(value, list):
        return [_scrub(v) for v in value]
    return value


def _csv(path: Path) -> list[list[str]]:
    """A CSV's rows without its wall-time columns (elapsed_s...)."""
    rows = list(csv.reader(path.read_text().splitlines()))
    keep = [i for i, name in enumerate(rows[0] if rows else []) if name not in VOLATILE]
    return [[row[i] for i in keep if i < len(row)] for row in rows]


def same(a: Path, b: Path) -> bool:
    if a.suffix == ".json":
        return _scrub(json.loads(a.read_text())) == _scrub(json.loads(b.read_text()))
    if a.name == "sweep.csv":
        return _csv(a) == _csv(b)
    return a.read_bytes() == b.read_bytes()


def compare(before: Path, after: Path) -> list[str]:
    files_a = {p.relative_to(before) for p in before.rglob("*") if p.is_file()}
    files_b = {p.relative_to(after) for p in after.rglob("*") if p.is_file()}
    out = [f"only before: {p}" for p in sorted(files_a - files_b)]
    out += [f"only after: {p}" for p in sorted(files_b - files_a)]
    out += [f"differs: {p}" for p in sorted(files_a & files_b) if not same(before / p, after / p)]
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, required=True, help="the src folder of the tree before")
    parser.add_argument("--after", type=Path, default=ROOT / "src", help="the src folder of the tree after")
    parser.add_argument("--keep", type=Path, help="keep both results folders here")
    parser.add_argument("--reuse", action="store_true", help="with --keep: the before folder there is reused")
    parser.add_argument("--extra", default="", help="more `odelab run` options, space separated")
    parser.add_argument("files", nargs="*", default=["experiments"])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        base = args.keep or Path(tmp)
        base.mkdir(parents=True, exist_ok=True)
        codes = {}
        for name, src in (("before", args.before), ("after", args.after)):
            if name == "before" and args.reuse and (base / "before").is_dir():
                codes[name] = int((base / "before.code").read_text()) if (base / "before.code").is_file() else 0
                continue
            shutil.rmtree(base / name, ignore_errors=True)  # a folder left by an earlier comparison
            codes[name] = run(src, base / name, args.files, args.extra.split())
            (base / f"{name}.code").write_text(f"{codes[name]}\n")
        diffs = compare(base / "before", base / "after")
        n = sum(1 for p in (base / "before").rglob("*") if p.is_file())
        for name in ("before", "after"):
            (base / f"{name}.out").is_file() or (base / f"{name}.out").write_text("")
        print(f"exit codes: before {codes['before']}, after {codes['after']}; {n} files stored before")
        if codes["before"] != codes["after"]:
            diffs.insert(0, "the exit codes differ")
        (base / "before.out").read_text() == (base / "after.out").read_text() or print(
            "note: the printed output differs (timings and progress are expected to)")
        for line in diffs:
            print(line)
        print("identical" if not diffs else f"{len(diffs)} differences")
        return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
