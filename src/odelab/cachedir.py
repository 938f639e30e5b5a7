"""Cache folders odelab can trust, and entries checked before they are used.

Every cache odelab keeps (numba's machine code of the compiled backend, the report's figures,
the report's compiled templates) holds things that are *executed or embedded* when loaded:
numba's index is a pickle, a template's bytecode is marshalled code, a PNG goes into the report.
So a cache is untrusted input, and two rules hold for all of them:

1. **The folder.** A cache folder is used only if it, and every folder between it and the
   cache root, is a real folder (not a symbolic link), owned by the user running odelab, not
   writable by group or others, and writable by its owner (checked by writing to it: a
   read-only file system refuses even root). Otherwise, with one note, the run uses a private
   temporary cache (``mkdtemp``, mode 0700, removed at exit) instead; if even that cannot be
   made, no cache.
2. **The entries.** An entry is written together with a seal, ``<name>.sha256``: the SHA-256
   of its bytes. An entry is loaded only if its bytes match its seal; one that does not (a
   truncated file, a disk error, a file odelab did not write) is deleted, with a note, and
   built again.

Cache root: ``$ODELAB_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/odelab``, else
``~/.cache/odelab``. Anything in it can be deleted at any time.

The core never prints: the notes are collected here, and whoever talks to the user (a run's
case warnings, the report's warnings) takes them with :func:`take_notes`.
"""

from __future__ import annotations

import atexit
import hashlib
import os
import shutil
import stat
import tempfile
from pathlib import Path

__all__ = ["SEAL_SUFFIX", "cache_folder", "cache_root", "folder_problem", "note", "read_entry", "seal",
           "take_notes", "unsafe", "verify", "write_entry"]

SEAL_SUFFIX = ".sha256"

_NOTES: list[str] = []
_FOLDERS: dict[tuple[str, str], Path | None] = {}
_PRIVATE: list[tuple[int, Path]] = []  # (pid that made it, folder)


def note(text: str) -> None:
    """Keep a note for the user (once until it is taken)."""
    if text not in _NOTES:
        _NOTES.append(text)


def take_notes() -> list[str]:
    """The notes kept since the last call (and forget them)."""
    taken = list(_NOTES)
    _NOTES.clear()
    return taken


def cache_root() -> Path:
    """The configured cache root (see the module docstring); not checked."""
    explicit = os.environ.get("ODELAB_CACHE_DIR")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "odelab"


def unsafe(path: Path) -> str | None:
    """Why the existing folder ``path`` is not one odelab may use (rule 1, this folder only), or None."""
    try:
        st = os.lstat(path)
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    if stat.S_ISLNK(st.st_mode):
        return "is a symbolic link"
    if not stat.S_ISDIR(st.st_mode):
        return "is a file, not a folder"
    if hasattr(os, "geteuid") and st.st_uid != os.geteuid():
        return f"belongs to another user (uid {st.st_uid})"
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"can be written by other users (mode {stat.S_IMODE(st.st_mode):04o})"
    if not st.st_mode & stat.S_IWUSR:
        return f"is read-only (mode {stat.S_IMODE(st.st_mode):04o})"
    return None


def folder_problem(root: Path, relative: str | Path = "") -> str | None:
    """Make ``root / relative`` (mode 0700) and say why it cannot be trusted, or None if it can.

    Checked: the root and each folder below it down to the target (rule 1 of the module
    docstring), and a test write in the target.
    """
    root = Path(root)
    chain = [root]
    for part in Path(relative).parts:
        chain.append(chain[-1] / part)
    try:
        if not os.path.lexists(root):
            root.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"{root.parent} cannot be made ({exc.strerror or exc})"
    for folder in chain:
        try:
            os.mkdir(folder, 0o700)
        except FileExistsError:
            pass
        except OSError as exc:
            return f"{folder} cannot be made ({exc.strerror or exc})"
        why = unsafe(folder)
        if why is not None:
            return f"{folder} {why}"
    try:
        fd, probe = tempfile.mkstemp(dir=chain[-1], prefix=".probe.")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        return f"{chain[-1]} cannot be written ({exc.strerror or exc})"
    return None


def _private_root() -> Path | None:
    """This process's private temporary cache root (made once, removed at exit), or None."""
    pid = os.getpid()
    for owner, folder in _PRIVATE:
        if owner == pid:
            return folder
    try:
        folder = Path(tempfile.mkdtemp(prefix="odelab-cache-"))  # mode 0700
    except OSError:
        return None
    _PRIVATE.append((pid, folder))
    import multiprocessing
    from multiprocessing import util

    if multiprocessing.parent_process() is not None:  # a worker: it leaves by os._exit, after its finalizers
        util.Finalize(None, _remove_private, args=(pid, folder), exitpriority=0)
    else:
        atexit.register(_remove_private, pid, folder)
    return folder


def _remove_private(pid: int, folder: Path) -> None:
    if os.getpid() == pid:  # not in a forked worker, which shares it with its parent

        shutil.rmtree(folder, ignore_errors=True)


def cache_folder(kind: str) -> Path | None:
    """The folder of cache ``kind`` ("compiled", "figures", "templates/html-..."), checked.

    The folder under the cache root if it can be trusted; else, with a note, the same folder
    under a private temporary cache; else None (no cache). Checked once per process.
    """
    root = cache_root()
    key = (str(root), kind)
    if key in _FOLDERS:
        return _FOLDERS[key]
    why = folder_problem(root, kind)
    folder: Path | None = root / kind
    if why is not None:
        private = _private_root()
        if private is not None and folder_problem(private, kind) is None:
            folder = private / kind
            note(f"the cache folder is not used: {why}; a private temporary cache is used for this run "
                 f"(set ODELAB_CACHE_DIR to a folder of your own, or fix its permissions)")
        else:
            folder = None
            note(f"the cache folder is not used: {why}; nothing is cached in this run")
    _FOLDERS[key] = folder
    return folder


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _seal_path(path: Path) -> Path:
    return path.with_name(path.name + SEAL_SUFFIX)


def _write_atomic(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def seal(path: Path, data: bytes | None = None) -> None:
    """Record the SHA-256 of the entry at ``path`` (of ``data``, its bytes, if given)."""
    path = Path(path)
    if data is None:
        data = path.read_bytes()
    _write_atomic(_seal_path(path), (_digest(data) + "\n").encode())


def _discard(path: Path) -> None:
    for p in (path, _seal_path(path)):
        try:
            p.unlink()
        except OSError:
            pass


def verify(path: Path, what: str = "cache entry") -> bytes | None:
    """The bytes of the entry at ``path`` if they match its seal; else None, and a damaged or
    unsealed entry is deleted (with a note) so that it is built again."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        _discard(path)  # a seal without its entry
        return None
    except OSError as exc:
        note(f"the cached {what} {path.name} could not be read ({exc.strerror or exc}): made again")
        return None
    try:
        sealed = _seal_path(path).read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError):
        sealed = None
    if sealed != _digest(data):
        _discard(path)
        why = "has no seal (odelab did not write it)" if sealed is None else "does not match its seal (damaged)"
        note(f"the cached {what} {path.name} {why}: deleted and made again")
        return None
    return data


def read_entry(folder: Path | None, name: str, what: str = "cache entry") -> bytes | None:
    """The checked bytes of entry ``name`` in ``folder`` (a :func:`cache_folder`), or None."""
    if folder is None:
        return None
    return verify(Path(folder) / name, what)


def write_entry(folder: Path | None, name: str, data: bytes) -> None:
    """Write entry ``name`` and its seal (atomically; a cache that cannot be written is skipped)."""
    if folder is None:
        return
    path = Path(folder) / name
    try:
        _write_atomic(path, data)
        seal(path, data)
    except OSError:
        _discard(path)
