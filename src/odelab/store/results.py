"""The results store: ``runs/<experiment>/<case>/`` with result.json, resolved.toml, trajectory.csv.

A case changes all at once or not at all. Its files are written into a hidden temporary
sibling folder (``runs/<experiment>/.<case>.XXXX.<pid>.tmp``), flushed to disk, and the folder is
then swapped in place of the old case folder with renames, under an exclusive lock on the
experiment folder; readers take the same lock shared. So a failed write (disk full, I/O error,
a permission change, Ctrl-C) leaves the previous case whole, a reader never pairs a
trajectory from one run with a result.json from another, and a file that the new run does
not write (an old ``result.mat``) cannot survive next to the new ones. The commit is one
rename per case (two when a previous run is replaced), and no lock file is left behind: the
lock is taken on the experiment folder itself. A process killed mid-write leaves its hidden folder,
which the next ``odelab run`` removes (:mod:`odelab.store.hidden`: its owner's lock tells a dead
owner's folder from a live one's); a failed write leaves nothing, not even an empty experiment folder.

Flushing to disk (against a power cut or an OS crash; a killed process loses nothing the
kernel has). Each case's files are flushed (one fsync each) before the rename that makes the
case visible, so no name ever points at data that is not on disk: after a power cut a case is
its previous state or its new one, never half. The rename itself is made durable by flushing
the folder that holds it. ``write_case`` does that at once (one folder fsync per
case) unless it is given ``unsynced``, a set the caller flushes with
:func:`sync_folders` when it is done: ``odelab run`` passes one for the whole run (so a case
costs its file fsyncs and no folder fsync, and each experiment folder is flushed once, at the
end of the run or when it is interrupted). Until then a power cut can only undo the latest
new cases whole (they are not there, as before the run); a folder fsync never makes a swap
less atomic, only durable. A case that replaces a previous one flushes its folder at once all
the same, before the previous one is removed: on a filesystem that does not keep renames in
order, removing it first could lose both.
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import math
import os
import platform
import secrets
import shutil
import time
from datetime import datetime, timezone
from importlib import metadata
from json.encoder import encode_basestring_ascii
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from odelab import __version__  # the one `odelab --version` prints (tests/experiment/test_store.py: the same
# as the installed metadata's): a metadata lookup fewer at every start
from odelab.analysis.errors import HEADLINE_RULE, error_columns
from odelab.fileio import atomic_write
from odelab.experiment.naming import slug
from odelab.store.hidden import HiddenFolder, hold, new_hidden_folder, remove_if_empty
from odelab.store.hidden import locked as _locked
from odelab.store.result import CaseResult
from odelab.store.spool import release

__all__ = ["RESULT_FORMAT", "Pace", "atomic_write", "case_dir", "json_safe", "summary", "sync_folders", "write_case",
           "read_run", "list_runs"]

RESULT_FORMAT = "odelab-result/1"
_TMP_SUFFIX = ".tmp"


class Pace:
    """When to rewrite a file that grows with a run (a sweep's table after each case): at once,
    unless the last write of it ended less than ``ratio`` times its duration ago. The rewrites
    then cost at most 1/``ratio`` of the run, and a small table is always current."""

    def __init__(self, ratio: float = 10.0):
        self.ratio = ratio
        self._next: dict[Any, float] = {}

    def due(self, key) -> bool:
        return time.monotonic() >= self._next.get(key, -math.inf)

    @contextlib.contextmanager
    def timed(self, key):
        start = time.monotonic()
        try:
            yield
        finally:
            end = time.monotonic()
            self._next[key] = end + self.ratio * (end - start)


def case_dir(runs: Path, experiment: str, case: str) -> Path:
    """The folder of a case, with names made safe (they can never leave ``runs``)."""

    return Path(runs) / slug(experiment) / slug(case)


def json_safe(value: Any) -> Any:
    """JSON-safe: NaN and inf become null (strict JSON has neither), arrays become lists."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


@functools.cache
def versions() -> dict[str, str | None]:
    """The versions stored with every case, looked up once per process (metadata lookups are slow)."""

    def version(dist: str) -> str | None:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return None

    return {"odelab": __version__, "numpy": np.__version__, "scipy": version("scipy"),
            "python": platform.python_version()}


def summary(result: CaseResult) -> dict[str, Any]:
    """The case's summary, as stored in result.json and printed by ``odelab run --json``."""
    case = result.case
    p = case.problem
    return json_safe({
        "format": RESULT_FORMAT,
        "experiment": case.experiment,
        "case": case.name,
        "case_index": case.index,  # its place in the experiment: the report lists the cases in this order
        "title": case.title,
        "method": p.method,
        "backend": result.backend,
        "status": result.status,
        "message": result.message,
        **({"expected": result.expected_stop, "expect": result.case.config["expect"]}
           if result.case.config.get("expect") else {}),
        "points": int(result.t.size),
        "stats": result.stats.as_dict(),
        "reference": result.reference_kind,
        "max_abs_error": {n: e.max_abs for n, e in result.errors.items()},
        "max_rel_error": {n: e.max_rel for n, e in result.errors.items()},
        # the headline relative error of each quantity and its basis, by analysis.errors.HEADLINE_RULE
        "rel_error": {n: e.headline for n, e in result.errors.items()},
        "rel_basis": {n: e.basis for n, e in result.errors.items()},
        "rel_error_rule": HEADLINE_RULE if result.errors else None,
        "errors": {n: e.as_dict() for n, e in result.errors.items()},
        "states": list(p.states),
        "inputs": list(p.inputs),
        "outputs": list(p.outputs),
        "warnings": list(result.warnings),
        "elapsed_s": result.elapsed,
        "extra": result.extra,
        **({"events": result.events} if result.case.problem.system.events is not None else {}),
        # the global error estimate (odelab.run.estimate): per quantity the estimated max error and digits
        **({"estimate": result.estimate} if result.estimate is not None else {}),
    })


#: Runs with more output rows than this store their trajectory as ``trajectory.npz`` (binary,
#: 8 bytes a value, written and read at disk speed) instead of ``trajectory.csv``: a CSV of a
#: million rows is too big for a spreadsheet and costs seconds to format and parse.
LONG_RUN_ROWS = 100_000


def _trajectory_columns(result: CaseResult) -> dict[str, np.ndarray]:
    """The trajectory's columns by name, in the file's order (the run's own arrays where it has them)."""
    columns = {"t": result.t, **result.series()}
    if result.event_marks is not None:  # 1-based number of the event (result.json "events") at that row
        columns["event"] = result.event_marks
    for name, ref in result.reference.items():
        abs_err, rel_err = error_columns(columns[name], ref)
        columns[f"{name}_ref"] = ref
        columns[f"{name}_abs_err"] = abs_err
        columns[f"{name}_rel_err"] = rel_err
    return columns


def _trajectory_block(columns: dict[str, np.ndarray], rows: int, lo: int = 0, hi: int | None = None) -> np.ndarray:
    """Rows ``lo:hi`` of the trajectory as one float block (rows, columns), filled column by column."""
    hi = rows if hi is None else hi
    block = np.empty((hi - lo, len(columns)))
    for i, values in enumerate(columns.values()):
        block[:, i] = np.asarray(values, dtype=float) if hi - lo == rows else np.asarray(values)[lo:hi]
    return block


def _trajectory_csv(names: list[str], data: np.ndarray) -> str:
    """The CSV text of the whole block at once: ``repr`` of every double (the shortest text that
    reads back to the same double), an empty field for NaN, one format operation for all rows.

    ``repr`` never writes "nan" inside another number, so the NaN fields are emptied by one
    replace over the text. The same text as formatting value by value, about a third faster
    (the rest is Python's float-to-text itself).
    """
    rows, cols = data.shape
    header = ",".join(names) + "\n"
    if rows == 0 or cols == 0:
        return header + "\n" * rows
    body = ((",".join(["%r"] * cols) + "\n") * rows) % tuple(data.ravel().tolist())
    return header + (body.replace("nan", "") if np.isnan(data).any() else body)


#: Rows of a long trajectory written at a time (trajectory.npz): 2 MB for four columns.
NPZ_BLOCK_ROWS = 65536


def _trajectory_npz(columns: dict[str, np.ndarray], rows: int):
    """A writer of the ``.npz`` file, called with the open file: ``np.savez(f, names=..., data=...)``
    byte for byte (the same zip archive, member names, .npy headers and data), but the ``data``
    block is never built: its rows go to the archive a block at a time from the run's own arrays,
    so storing a long run adds a few megabytes to its memory, not a copy of its trajectory (nor, for a
    spooled run, the pages of its maps: :mod:`odelab.store.spool`)."""
    import zipfile

    from numpy.lib import format as npy

    names = np.array(list(columns), dtype=str)

    def write(f) -> None:
        # np.savez's archive: numpy's zipfile_factory (allowZip64), stored members, each forced to zip64
        with zipfile.ZipFile(f, mode="w", compression=zipfile.ZIP_STORED, allowZip64=True) as archive:
            with archive.open("names.npy", "w", force_zip64=True) as member:
                npy.write_array(member, names, allow_pickle=True)
            with archive.open("data.npy", "w", force_zip64=True) as member:
                npy.write_array_header_1_0(member, {"descr": npy.dtype_to_descr(np.dtype(float)),
                                                    "fortran_order": False, "shape": (rows, len(columns))})
                for lo in range(0, rows, NPZ_BLOCK_ROWS):
                    member.write(_trajectory_block(columns, rows, lo, min(rows, lo + NPZ_BLOCK_ROWS)).tobytes())
                    for values in columns.values():  # a spooled run's maps: their pages handed back
                        release(values)

    return write


def trajectory_file(result: CaseResult) -> str:
    """The name of the case's trajectory file: trajectory.csv, or trajectory.npz for long runs."""
    return "trajectory.npz" if np.size(result.t) > LONG_RUN_ROWS else "trajectory.csv"


def write_case(result: CaseResult, runs: Path, *, mat: bool = False, durable: bool = True,
               unsynced: set[Path] | None = None) -> Path:
    """Store one case's results, all at once or not at all; returns its folder.

    ``durable=False`` skips flushing the files to disk before the swap (the swap stays atomic
    for readers, but a power cut may lose the case): for throw-away results folders.
    ``unsynced``: the case's experiment folder is added to it instead of being flushed now;
    the caller flushes the set with :func:`sync_folders` (see the module's docstring).
    """
    case = result.case
    folder = case_dir(runs, case.experiment, case.name)
    record = summary(result)
    record.update({
        "source": str(case.source),
        "file_sha256": case.file_hash,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": dict(versions()),
        "config": case.config,
    })
    columns = _trajectory_columns(result)
    rows = int(np.size(result.t))
    trajectory = trajectory_file(result)
    record["trajectory_file"] = trajectory
    if trajectory.endswith(".npz"):  # streamed from the columns when the folder is written
        files = {trajectory: _trajectory_npz(columns, rows)}
    else:
        files = {trajectory: _trajectory_csv(list(columns), _trajectory_block(columns, rows))}
    files["resolved.toml"] = _resolved_toml(result, tomli_w)
    if mat:
        files["result.mat"] = _mat_bytes(result)
    files["result.json"] = result_json(record)
    spool = result.spool
    staged = spool.handover() if spool is not None and spool.target == folder else None
    commit_folder(folder, files, durable=durable, unsynced=unsynced, staged=staged,
                  drop=(spool.T_FILE, spool.X_FILE) if staged is not None else ())
    return folder


def result_json(record: dict) -> str:
    """``json.dumps(record, indent=2, allow_nan=False)`` and a newline, the same text at half the cost.

    With ``indent`` the standard library encodes in Python, call by call; here the strings and
    numbers go to its C functions and the nesting is joined once per container. Anything but
    plain JSON types (or a NaN, which ``json`` refuses with its own message) is left to
    ``json.dumps``."""
    try:
        return _json(record, "") + "\n"
    except _NotPlain:
        return json.dumps(record, indent=2, allow_nan=False) + "\n"


class _NotPlain(Exception):
    pass


def _json(value, indent: str) -> str:
    kind = type(value)
    if kind is str:
        return encode_basestring_ascii(value)
    if value is None or kind is bool:
        return "null" if value is None else "true" if value else "false"
    if kind is int:
        return int.__repr__(value)
    if kind is float:
        if not math.isfinite(value):
            raise _NotPlain
        return float.__repr__(value)
    inner = indent + "  "
    if kind is dict:
        if not value:
            return "{}"
        if not all(type(k) is str for k in value):
            raise _NotPlain
        items = [f"{inner}{encode_basestring_ascii(k)}: {_json(v, inner)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + indent + "}"
    if kind is list or kind is tuple:
        if not value:
            return "[]"
        return "[\n" + ",\n".join([inner + _json(v, inner) for v in value]) + "\n" + indent + "]"
    raise _NotPlain


def commit_folder(folder: Path, files: dict, *, durable: bool = True, unsynced: set[Path] | None = None,
                  staged: HiddenFolder | None = None, drop: tuple[str, ...] = ()) -> None:
    """Replace ``folder`` by a folder holding exactly ``files``, atomically for readers.

    ``files`` maps each file's name to its text, its bytes, or a function that writes it to
    the open (binary) file it is given.

    The files go into a hidden temporary sibling folder; once all are written (and, if
    ``durable``, flushed to disk), the old folder is renamed away, the new one renamed into its
    place and the old one removed, under the exclusive lock of the parent folder. Any failure
    before the swap removes the temporary folder (and the parent folder, if that leaves it empty)
    and leaves the old folder untouched. If ``durable``, the parent folder is then flushed too, or,
    given ``unsynced`` and no old folder to remove, added to it for the caller to flush later
    (:func:`sync_folders`). Both hidden folders, the new case's and the replaced one's, are held
    (:mod:`odelab.store.hidden`) until they are renamed into place or removed: a later run removes
    them if this process is killed meanwhile, never while it lives.

    ``staged``: a temporary sibling folder already made (a run's spool, :mod:`odelab.store.spool`) to write
    the files into instead of a new one; its files named in ``drop`` (the spool's raw rows, which ``files``
    may read as they are written) are removed before the swap.
    """
    folder = Path(folder)
    parent = folder.parent
    tmp = staged if staged is not None else new_hidden_folder(parent, folder.name)
    old: HiddenFolder | None = None
    try:
        for name, data in files.items():
            _write_file(tmp.path / name, data.encode("utf-8") if isinstance(data, str) else data, durable)
        for name in drop:
            os.unlink(tmp.path / name)
        with _locked(parent) as parent_fd:
            if _exists(folder):
                # a fresh hidden name (random; we hold the lock): the previous case, or whatever was there
                away = parent / f".{folder.name}.old.{secrets.token_hex(6)}.{os.getpid()}{_TMP_SUFFIX}"
                os.rename(folder, away)
                old = HiddenFolder(away, hold(away))  # held before the lock lets a stale-folder search look
            try:
                os.rename(tmp.path, folder)
            except BaseException:
                if old is not None:  # put the previous case back
                    os.rename(old.path, folder)
                    old.release()
                    old = None
                raise
            tmp.release()
            tmp = None
            if durable and (unsynced is None or old is not None):  # the new name is durable before the old goes
                _fsync_folder(parent, parent_fd)
            elif durable:
                unsynced.add(parent)
    finally:
        for leftover in (tmp, old):  # the replaced case (a hidden name: no reader looks for it) or a failed write
            if leftover is not None:
                _remove(leftover.path)
                leftover.release()
        if tmp is not None:  # nothing stored: an experiment folder made for it is not left empty
            remove_if_empty(parent)


def _write_file(path: Path, data, durable: bool) -> None:
    """A new file holding ``data`` (flushed to disk if ``durable``), written with plain system calls;
    ``data`` may also be a function that writes the file's contents to the open file it is given."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)  # the umask applies
    if callable(data):
        with os.fdopen(fd, "wb") as f:
            data(f)
            if durable:
                f.flush()
                os.fsync(f.fileno())
        return
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
        if durable:
            os.fsync(fd)
    finally:
        os.close(fd)


def _exists(path: Path) -> bool:
    """Something (a folder, a file, a symlink, even a dangling one) is at ``path``."""
    try:
        os.lstat(path)
    except FileNotFoundError:
        return False
    return True


def _remove(path: Path) -> None:
    """Remove a replaced case folder; a symlink planted in its place is removed, never followed."""
    if path.is_symlink():
        with contextlib.suppress(OSError):
            path.unlink()
    else:
        shutil.rmtree(path, ignore_errors=True)


def sync_folders(folders: set[Path]) -> None:
    """Flush the renames made in ``folders`` (those ``write_case`` left unsynced) to disk, and empty the set.

    Every folder is flushed, whatever the filesystem (on ext4 the first flush commits the
    journal and the others find little left to do)."""
    while folders:
        _fsync_folder(folders.pop())


def _fsync_folder(folder: Path, fd: int | None = None) -> None:
    """Make the renames in ``folder`` durable (POSIX; a no-op where folders cannot be opened).
    ``fd``: the folder, already open (the lock's)."""
    own = fd is None
    if own:
        try:
            fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        except OSError:  # pragma: no cover
            return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover - some filesystems refuse fsync on folders
        pass
    finally:
        if own:
            os.close(fd)


def _resolved_toml(result: CaseResult, tomli_w) -> str:
    case = result.case
    from odelab.expressions.functions import shadowing_note

    header = (f"# Resolved by odelab from {case.source} (sha256 {case.file_hash[:12]}), case {case.name!r}.\n"
              f"# `odelab run` this file to reproduce the case exactly.\n")
    header += "".join(f"# {note}; in this file's expressions it is the parameter.\n"
                      for note in shadowing_note(case.config.get("parameters") or {}))
    header += "".join(f"# {note}: the number below.\n" for note in getattr(case.problem, "notes", ()))
    return header + tomli_w.dumps(json_safe(case.config))


def _mat_bytes(result: CaseResult) -> bytes:
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
    folder = Path(folder)
    with _locked(folder.parent, shared=True):  # never read a case while another run swaps it
        record = _strict_json((folder / "result.json").read_text(encoding="utf-8"))
        binary = (folder / "trajectory.npz").is_file()
        if binary:
            names, data = _read_npz(folder / "trajectory.npz")
        else:
            text = (folder / "trajectory.csv").read_text(encoding="utf-8").splitlines()
    if not isinstance(record, dict) or record.get("format") != RESULT_FORMAT:
        raise ValueError(f"{folder / 'result.json'} is not an odelab result (format {RESULT_FORMAT})")
    for key in ("experiment", "case", "status", "method", "stats"):
        if key not in record:
            raise ValueError(f"{folder / 'result.json'} has no {key!r}")
    if not binary:
        if not text:
            raise ValueError(f"{folder / 'trajectory.csv'} is empty")
        names = text[0].split(",")
        rows = [[float(v) if v else math.nan for v in line.split(",")] for line in text[1:] if line]
        data = np.array(rows, dtype=float).reshape(len(rows), len(names))
    record["trajectory"] = {n: data[:, i] for i, n in enumerate(names)}
    record["folder"] = str(folder)
    return record


def _read_npz(path: Path) -> tuple[list[str], np.ndarray]:
    """A binary trajectory: column names and an (N, columns) float array (ValueError if broken)."""
    import zipfile

    try:
        with np.load(path, allow_pickle=False) as npz:
            names = [str(n) for n in npz["names"]]
            data = np.asarray(npz["data"], dtype=float)
    except (OSError, KeyError, zipfile.BadZipFile, EOFError) as exc:
        raise ValueError(f"{path} is not a readable odelab trajectory ({exc})") from None
    if data.ndim != 2 or data.shape[1] != len(names):
        raise ValueError(f"{path} holds {data.shape} values for {len(names)} columns")
    return names, data


def _strict_json(text: str) -> Any:
    """result.json as odelab writes it: strict JSON, finite numbers, shallow (else ValueError)."""
    try:
        return json.loads(text, parse_constant=_no_constant, parse_float=_finite_float)
    except RecursionError:
        raise ValueError("result.json nests arrays or objects too deeply to be an odelab result") from None


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):  # 1e400 overflows to inf
        raise ValueError(f"result.json holds {text}, which overflows a double; odelab never writes it")
    return value


def _no_constant(name: str):
    """result.json is strict JSON: NaN and Infinity are stored as null, so one of them means a foreign file."""
    raise ValueError(f"result.json holds {name}, which odelab never writes (it stores null)")


def list_runs(runs: Path) -> list[Path]:
    """Case folders under ``runs`` holding a result.json, in a stable order (temporary folders skipped)."""
    runs = Path(runs)
    if not runs.is_dir():
        return []
    return sorted(p.parent for p in runs.glob("*/*/result.json")
                  if not p.parent.name.startswith(".") and not p.parent.parent.name.startswith("."))
