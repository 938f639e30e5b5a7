"""Loading time of experiment files against their size: many cases over one large matrix.

A state-space system with an n x n matrix of numbers and parameter expressions, and c cases
that change only the tolerance. Loading must be linear in the file's size (issue 15): the
cases share the base's system table, which is built once per file and parameter values.

    python bench/bench_load.py
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from odelab.experiment.loader import load_experiment  # noqa: E402


def experiment(n: int, cases: int) -> str:
    rows = ",\n  ".join("[" + ", ".join('"-k"' if i == j else "1" if j == i + 1 else "0" for j in range(n)) + "]"
                        for i in range(n))
    states = ", ".join(f'"x{i}"' for i in range(n))
    text = (f'[parameters]\nk = 2\n[system]\nkind = "state-space"\nstates = [{states}]\nA = [\n  {rows}]\n'
            "[initial]\n" + "".join(f"x{i} = 1\n" for i in range(n)) + "[time]\nstop = 1\n")
    return text + "".join(f'\n[[case]]\nname = "c{c}"\nsolver.rtol = {1e-3 / (c + 1)}\n' for c in range(cases))


def main() -> None:
    print(f"{'n':>4} {'cases':>6} {'bytes':>8} {'seconds':>8} {'us/byte':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "load.toml"
        for n, cases in ((40, 40), (40, 160), (40, 640), (80, 160), (100, 1000)):
            text = experiment(n, cases)
            path.write_text(text)
            best = min(_timed(path) for _ in range(3))
            print(f"{n:>4} {cases:>6} {len(text):>8} {best:>8.2f} {best / len(text) * 1e6:>8.1f}")


def _timed(path: Path) -> float:
    start = time.perf_counter()
    load_experiment(path)
    return time.perf_counter() - start


if __name__ == "__main__":
    main()
