"""The results store: ``runs/<experiment>/<case>/`` with result.json, resolved.toml, trajectory.csv.

Every file is written atomically (a temporary file in the same folder, flushed, then renamed
over the target), and a case's files are written under an exclusive lock on the case folder,
so an interrupted or concurrent run never leaves a half-written or mixed case. ``result.json``
is written last: a case folder without it is incomplete and readers skip it.
"""

from __future__ import annotations

import contextlib
import json
import math
import platform
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from odelab.analysis.errors import error_columns
from odelab.fileio import atomic_write
from odelab.experiment.loader import slug
from odelab.experiment.result import CaseResult

__all__ = ["RESULT_FORMAT", "atomic_write", "case_dir", "summary", "write_case", "read_run", "list_runs"]

RESULT_FORMAT = "odelab-result/1"


@contextlib.contextmanager
def _locked(folder: Path, *, shared: bool = False):
    """An advisory lock on a case folder: exclusive to write its files, shared to read them."""
    if not shared:
        folder.mkdir(parents=True, exist_ok=True)
    try:
        fh = open(folder / ".lock", "a+b") if not shared or (folder / ".lock").exists() else None
    except OSError:  # a read-only results folder can still be read
        fh = None
    try:
        if fh is not None:
            try:
                import fcntl

                fcntl.flock(fh.fileno(), fcntl.LOCK_SH if shared else fcntl.LOCK_EX)
            except ImportError:  # pragma: no cover - non-POSIX: atomic renames still hold
                pass
        yield
    finally:
        if fh is not None:
            fh.close()


def case_dir(runs: Path, experiment: str, case: str) -> Path:
    """The folder of a case, with names made safe (they can never leave ``runs``)."""
    return Path(runs) / slug(experiment) / slug(case)


def _clean(value: Any) -> Any:
    """JSON-safe: NaN and inf become null (strict JSON has neither), arrays become lists."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def summary(result: CaseResult) -> dict[str, Any]:
    """The case's summary, as stored in result.json and printed by ``odelab run --json``."""
    case = result.case
    p = case.problem
    return _clean({
        "format": RESULT_FORMAT,
        "experiment": case.experiment,
        "case": case.name,
        "title": case.title,
        "method": p.method,
        "status": result.status,
        "message": result.message,
        "points": int(result.t.size),
        "stats": result.stats.as_dict(),
        "reference": result.reference_kind,
        "max_abs_error": {n: e.max_abs for n, e in result.errors.items()},
        "max_rel_error": {n: e.max_rel for n, e in result.errors.items()},
        "errors": {n: e.as_dict() for n, e in result.errors.items()},
        "states": list(p.states),
        "inputs": list(p.inputs),
        "outputs": list(p.outputs),
        "warnings": list(result.warnings),
        "elapsed_s": result.elapsed,
        "extra": result.extra,
    })


def _trajectory_csv(result: CaseResult) -> str:
    columns = {"t": result.t, **result.series()}
    for name, ref in result.reference.items():
        abs_err, rel_err = error_columns(columns[name], ref)
        columns[f"{name}_ref"] = ref
        columns[f"{name}_abs_err"] = abs_err
        columns[f"{name}_rel_err"] = rel_err
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    lines = [",".join(names)]
    lines.extend(",".join("" if v != v else repr(float(v)) for v in row) for row in data.tolist())
    return "\n".join(lines) + "\n"


def write_case(result: CaseResult, runs: Path, *, mat: bool = False) -> Path:
    """Store one case's results atomically; returns its folder."""
    import tomli_w

    case = result.case
    folder = case_dir(runs, case.experiment, case.name)
    record = summary(result)
    record.update({
        "source": str(case.source),
        "file_sha256": case.file_hash,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": {"odelab": _version("odelab"), "numpy": np.__version__, "scipy": _version("scipy"),
                     "python": platform.python_version()},
        "config": case.config,
    })
    with _locked(folder):
        atomic_write(folder / "trajectory.csv", _trajectory_csv(result))
        atomic_write(folder / "resolved.toml", _resolved_toml(result, tomli_w))
        if mat:
            atomic_write(folder / "result.mat", _mat_bytes(result))
        atomic_write(folder / "result.json", json.dumps(record, indent=2, allow_nan=False) + "\n")
    return folder


def _resolved_toml(result: CaseResult, tomli_w) -> str:
    case = result.case
    header = (f"# Resolved by odelab from {case.source} (sha256 {case.file_hash[:12]}), case {case.name!r}.\n"
              f"# `odelab run` this file to reproduce the case exactly.\n")
    return header + tomli_w.dumps(_clean(case.config))


def _mat_bytes(result: CaseResult) -> bytes:
    import io

    from scipy.io import savemat

    buf = io.BytesIO()
    data = {"t": result.t.reshape(-1, 1), "x": result.x}
    if result.y is not None:
        data["y"] = result.y
    if result.u is not None:
        data["u"] = result.u
    for name, ref in result.reference.items():
        data[f"ref_{slug(name).replace('-', '_').replace('.', '_')}"] = ref.reshape(-1, 1)
    savemat(buf, data)
    return buf.getvalue()


def read_run(folder: Path) -> dict[str, Any]:
    """Read a stored case: result.json plus the trajectory columns (raises ValueError if broken)."""
    with _locked(folder, shared=True):  # never read a case while another run rewrites it
        record = json.loads((folder / "result.json").read_text(encoding="utf-8"))
        text = (folder / "trajectory.csv").read_text(encoding="utf-8").splitlines()
    if not isinstance(record, dict) or record.get("format") != RESULT_FORMAT:
        raise ValueError(f"{folder / 'result.json'} is not an odelab result (format {RESULT_FORMAT})")
    for key in ("experiment", "case", "status", "method", "stats"):
        if key not in record:
            raise ValueError(f"{folder / 'result.json'} has no {key!r}")
    if not text:
        raise ValueError(f"{folder / 'trajectory.csv'} is empty")
    names = text[0].split(",")
    rows = [[float(v) if v else math.nan for v in line.split(",")] for line in text[1:] if line]
    data = np.array(rows, dtype=float).reshape(len(rows), len(names))
    record["trajectory"] = {n: data[:, i] for i, n in enumerate(names)}
    record["folder"] = str(folder)
    return record


def list_runs(runs: Path) -> list[Path]:
    """Case folders under ``runs`` holding a result.json, in a stable order."""
    runs = Path(runs)
    if not runs.is_dir():
        return []
    return sorted(p.parent for p in runs.glob("*/*/result.json"))
