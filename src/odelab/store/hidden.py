"""The store's hidden temporary folders: made held by their owner, found stale when it is dead, removed.

A case is written into a hidden sibling of its folder, ``runs/<experiment>/.<case>.XXXX.<pid>.tmp``
(:func:`odelab.store.results.commit_folder`), where a long run also spools its rows
(:mod:`odelab.store.spool`); a replaced case waits for removal as ``.<case>.old.XXXX.<pid>.tmp``.
Each such folder is held by the process that made it: an exclusive ``flock`` on the folder itself,
from the moment it is made until it is renamed into place or removed. The kernel drops the lock when
the process dies, however it dies (SIGKILL, the OOM killer), and a reused pid cannot inherit it. So a
folder whose lock another process can take was left by a dead owner and is stale
(:func:`remove_stale`, which a later ``odelab run`` calls); a live run's folder is never taken.

A folder is made while its experiment folder is locked shared and tested while it is locked exclusive,
so no folder is seen between its ``mkdir`` and its owner's lock. The pid in the name is the owner's,
to say whose folder was removed; the lock, not the pid, decides. Where folders cannot be locked (no
``fcntl``; some network filesystems) nothing is ever taken, so nothing is removed. A hidden folder
named as before the locks (``.<case>.XXXX.tmp``) has an owner nobody can test and is left alone.

An experiment folder left empty (a run failed or was interrupted before storing anything, or its
only leftovers were removed) is removed with ``os.rmdir`` (:func:`remove_if_empty`), which refuses a
folder holding anything: another run's case, or a hidden folder another run is making at that moment.
A writer whose experiment folder vanished between its ``mkdir`` and its own folder's makes it again
(:func:`new_hidden_folder`). Nothing here prints: what was removed is returned, for the caller to say.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import shutil
from dataclasses import dataclass
from pathlib import Path

__all__ = ["HiddenFolder", "Stale", "hold", "locked", "new_hidden_folder", "remove_if_empty", "remove_stale"]

_TMP_SUFFIX = ".tmp"
#: A held hidden folder's name: ``.<case>.<12 hex digits>.<pid>.tmp`` (a replaced case: ``<case>.old``).
_HELD_NAME = re.compile(r"\.(?P<case>.+)\.[0-9a-f]{12}\.(?P<pid>[0-9]{1,10})\.tmp")
#: Tries at making a hidden folder in an experiment folder that another run removes as empty meanwhile.
_ATTEMPTS = 100
_DIRECTORY = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_NOFOLLOW", 0)


@contextlib.contextmanager
def locked(folder: Path, *, shared: bool = False):
    """An advisory lock on a folder itself (no lock file): exclusive to swap a case or look for stale
    folders, shared to read a case or make a hidden folder.

    Yields the folder's file descriptor (None where folders cannot be opened), so that the
    caller can flush the folder's renames through it."""
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:  # a folder that cannot be opened (or a platform without directory fds)
        fd = None
    try:
        if fd is not None:
            try:
                import fcntl

                fcntl.flock(fd, fcntl.LOCK_SH if shared else fcntl.LOCK_EX)
            except (ImportError, OSError):  # pragma: no cover - non-POSIX: the renames still hold
                pass
        yield fd
    finally:
        if fd is not None:
            os.close(fd)


def _take(path: Path) -> int | None:
    """An open descriptor of the folder ``path`` holding its exclusive lock, or None if the lock is held by
    another (a live owner), cannot be had here, or ``path`` is not a folder (a symlink is never followed)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - non-POSIX
        return None
    try:
        fd = os.open(path, _DIRECTORY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:  # BlockingIOError: its owner lives; anything else: locks do not work here
        os.close(fd)
        return None
    return fd


def hold(path: Path) -> int | None:
    """Hold the folder ``path`` just made (or renamed away under the experiment folder's lock): the
    descriptor whose lock says its owner lives, until it is closed (None where folders cannot be locked)."""
    return _take(path)


@dataclass(eq=False)
class HiddenFolder:
    """A hidden temporary folder and its owner's lock on it (``fd``; released by :meth:`release` or the
    owner's death)."""

    path: Path
    fd: int | None

    def release(self) -> None:
        fd, self.fd = self.fd, None
        if fd is not None:
            with contextlib.suppress(OSError):
                os.close(fd)

    def remove(self) -> None:
        """Remove the folder and what is in it, then its lock, then its experiment folder if that is empty."""
        shutil.rmtree(self.path, ignore_errors=True)
        self.release()
        remove_if_empty(self.path.parent)


def new_hidden_folder(parent: Path, name: str) -> HiddenFolder:
    """A new hidden temporary folder ``parent/.name.XXXX.<pid>.tmp``, held, with the usual permissions (the
    umask's); ``parent`` is made if it is not there (again, if another run removes it as empty meanwhile)."""
    parent = Path(parent)
    for attempt in range(_ATTEMPTS):
        parent.mkdir(parents=True, exist_ok=True)
        path = parent / f".{name}.{secrets.token_hex(6)}.{os.getpid()}{_TMP_SUFFIX}"
        try:
            with locked(parent, shared=True):  # no stale-folder search sees it before it is held
                os.mkdir(path, 0o777)  # the umask applies, as for any folder the user makes
                return HiddenFolder(path, hold(path))
        except FileExistsError:  # pragma: no cover - 48 random bits
            continue
        except FileNotFoundError:  # the experiment folder, empty, was removed by another run's cleanup
            if attempt == _ATTEMPTS - 1:
                raise
    raise FileExistsError(f"no free hidden folder name in {parent}")  # pragma: no cover


def remove_if_empty(folder: Path) -> bool:
    """Remove ``folder`` if it is empty (``os.rmdir``: never a folder holding anything, whoever is writing
    into it). True if it was removed."""
    try:
        os.rmdir(folder)
    except OSError:  # not empty, not there, or not ours to remove
        return False
    return True


@dataclass(frozen=True)
class Stale:
    """A hidden folder removed because its owner was dead: where it was, the bytes of its files, the
    owner's pid (from its name)."""

    path: Path
    size: int
    pid: int


def remove_stale(runs: Path) -> list[Stale]:
    """Remove the hidden temporary folders under ``runs/<experiment>/`` whose owners are dead (a run killed
    with SIGKILL or by the OOM killer mid-write), and the experiment folders that leaves empty; returns
    what was removed. A folder held by a live run, even one of this process, is left alone."""
    try:
        with os.scandir(runs) as entries:
            experiments = sorted(e.name for e in entries
                                 if not e.name.startswith(".") and e.is_dir(follow_symlinks=False))
    except OSError:  # no results folder yet
        return []
    removed: list[Stale] = []
    for name in experiments:
        removed += _remove_stale_in(Path(runs) / name)
    return removed


def _remove_stale_in(folder: Path) -> list[Stale]:
    try:
        with os.scandir(folder) as entries:
            names = sorted(e.name for e in entries if _HELD_NAME.fullmatch(e.name) and e.is_dir(follow_symlinks=False))
    except OSError:
        return []
    if not names:
        return []
    taken: list[tuple[Path, int]] = []
    with locked(folder):  # no hidden folder is being made (locked shared) while its owner is tested
        for name in names:
            fd = _take(folder / name)
            if fd is not None:
                taken.append((folder / name, fd))
    removed = []
    for path, fd in taken:  # ours now: its owner is dead and no other run takes a folder we hold
        try:
            size = _size(path)
            shutil.rmtree(path, ignore_errors=True)
            gone = not os.path.lexists(path)
        finally:
            os.close(fd)
        if gone:
            removed.append(Stale(path, size, int(_HELD_NAME.fullmatch(path.name)["pid"])))
    if removed:
        remove_if_empty(folder)
    return removed


def _size(folder: Path, limit: int = 10_000) -> int:
    """The bytes of the files in ``folder`` (its first ``limit`` entries; subfolders are not walked)."""
    total = 0
    with os.scandir(folder) as entries:
        for count, entry in enumerate(entries):
            if count >= limit:
                break
            with contextlib.suppress(OSError):
                if entry.is_file(follow_symlinks=False):
                    total += entry.stat(follow_symlinks=False).st_size
    return total
