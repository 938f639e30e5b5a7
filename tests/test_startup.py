"""Start-up of the commands that solve: BLAS pinned to one thread before numpy loads it."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"

# Records the BLAS thread variables at the moment numpy is first imported.
PROBE = """
import os, sys
seen = []
class Probe:
    def find_spec(self, name, path=None, target=None):
        if name == "numpy" and not seen:
            seen.append(tuple(os.environ.get(v) for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")))
        return None
sys.meta_path.insert(0, Probe())
from odelab.cli import app
try:
    app(sys.argv[1:])
except SystemExit:
    pass
print("BLAS", *(seen[0] if seen else ("numpy never imported",)))
"""


def _blas_at_numpy_import(tmp_path, env_extra: dict, *args) -> list[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                             "MKL_NUM_THREADS")}
    env.update(env_extra)
    out = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, env=env,
                         cwd=tmp_path, check=True).stdout
    return next(line for line in out.splitlines() if line.startswith("BLAS")).split()[1:]


@pytest.mark.parametrize("extra", [{}, {"OPENBLAS_NUM_THREADS": "2"}])
def test_odelab_run_pins_blas_to_one_thread_before_numpy_loads(tmp_path, extra):
    seen = _blas_at_numpy_import(tmp_path, extra, "run", str(EXPERIMENTS / "exercise1.toml"), "--runs", "runs")
    # the user's own setting is kept; otherwise one thread, as `odelab grade` does
    assert seen == [extra.get("OPENBLAS_NUM_THREADS", "1"), "1", "1"]


# The modules a command imported, printed when it returns (its own output goes to a pipe).
MODULES = """
import sys
from odelab.cli import app
try:
    app(sys.argv[1:])
except SystemExit:
    pass
print("MODULES", *sorted(sys.modules))
"""

# Packages a plain explicit experiment never needs: the reference solvers and .mat files (scipy), the report
# (matplotlib, jinja2), the compiled backend (numba), control and symbolic analysis, Dask, the progress bar.
NOT_FOR_A_PLAIN_RUN = ("scipy", "matplotlib", "jinja2", "numba", "llvmlite", "control", "sympy", "dask",
                       "distributed", "rich.progress", "rich.table", "odelab.report", "odelab.analysis.reference",
                       "odelab.solvers.compiled.cache", "odelab.fmi", "odelab.analysis.estimate", "odelab.cli.study_views",
                       "odelab.formats.matlab", "odelab.formats.simulink")


def _imported(tmp_path, *args) -> set[str]:
    # a piped run as a script runs it: without the COLUMNS and LINES that GNU readline, which pytest loads,
    # exports to the processes it starts (80 x 24)
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
    out = subprocess.run([sys.executable, "-c", MODULES, *args], capture_output=True, text=True, cwd=tmp_path,
                         check=True, env=env).stdout
    return set(next(line for line in out.splitlines() if line.startswith("MODULES")).split()[1:])


def test_a_plain_run_imports_only_what_it_needs(tmp_path):
    modules = _imported(tmp_path, "run", str(EXPERIMENTS / "exercise1.toml"), "--runs", "runs")
    assert (tmp_path / "runs" / "exercise1" / "ode45" / "result.json").is_file()  # it ran and stored
    assert {"numpy", "pydantic", "odelab.store.results"} <= modules
    loaded = sorted(m for m in modules if m.split(".")[0] in {n.split(".")[0] for n in NOT_FOR_A_PLAIN_RUN}
                    and any(m == n or m.startswith(n + ".") for n in NOT_FOR_A_PLAIN_RUN))
    assert loaded == []
    assert not [m for m in modules if m.startswith("odelab_kernels_")]  # the compiled loops' generated module


@pytest.mark.parametrize("args", [["--help"], ["--version"]])
def test_help_and_version_import_neither_numpy_nor_pydantic_nor_rich(tmp_path, args):
    modules = _imported(tmp_path, *args)
    assert not {m.split(".")[0] for m in modules} & {"numpy", "pydantic", "pydantic_core", "rich", "scipy"}


def test_python_m_odelab_is_the_odelab_command(tmp_path):
    # the same app: a run stores its result, and --version prints odelab's version
    from odelab import __version__

    version = subprocess.run([sys.executable, "-m", "odelab", "--version"], capture_output=True, text=True,
                             cwd=tmp_path)
    assert version.returncode == 0 and __version__ in version.stdout
    run = subprocess.run([sys.executable, "-m", "odelab", "run", str(EXPERIMENTS / "exercise1.toml"), "--runs", "runs"],
                         capture_output=True, text=True, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "runs" / "exercise1" / "ode45" / "result.json").is_file()
    bad = subprocess.run([sys.executable, "-m", "odelab", "run", str(tmp_path / "missing.toml")], capture_output=True,
                         text=True, cwd=tmp_path)
    assert bad.returncode != 0 and "missing.toml" in bad.stderr + bad.stdout and "Traceback" not in bad.stderr
