"""A long run's rows on disk as the compiled loop fills its blocks: the spool.

The compiled adaptive loop writes Refine output into blocks of 2 MiB
(:mod:`odelab.solvers.compiled.rows`). Given a :class:`Spool`, it appends each full block to two raw
files (``t.f64``, the times; ``x.f64``, the states row by row: float64, native order, no header) and
fills the same block again, so a run holds one block of its rows, not its trajectory. At the end the
run's ``t`` and ``x`` are read-only maps of the two files (``np.memmap``).

The spool's folder is the hidden temporary sibling of the case's folder that the store writes a case
into (``runs/<experiment>/.<case>.XXXX.<pid>.tmp``, :func:`odelab.store.results.commit_folder`): the
store writes the case's files next to the raw files, streaming ``trajectory.npz`` from them, removes
them and renames the folder into place. So nothing half-written is ever visible, and nothing is copied.
The folder is made only when the first block fills (a short run never touches the disk); a run that
fails or is interrupted removes it, and its experiment folder if that is left empty
(:meth:`Spool.discard`, and a finaliser when the spool is dropped or the process exits). A process
killed outright (SIGKILL, the OOM killer) leaves its hidden folder, as a store killed while writing a
case does: :func:`odelab.store.results.list_runs` never reads one, and the next ``odelab run`` into
the same results folder removes it (the folder is held by its owner's lock until then,
:mod:`odelab.store.hidden`).

Reading a map brings its pages into the process (they count in its resident memory until they are
unmapped), so whoever walks a whole column walks it with :func:`blocks` or gathers rows with
:func:`take`, which hand the pages back after each block (``madvise(MADV_DONTNEED)``: the pages
of a read-only shared map are read again from the file, or the page cache, when next touched).
"""

from __future__ import annotations

import contextlib
import mmap
import os
import weakref
from pathlib import Path

import numpy as np

from odelab.store.hidden import HiddenFolder, new_hidden_folder

__all__ = ["BLOCK", "Spool", "SpoolFailed", "blocks", "release", "take"]

#: Values of a column looked at a time by :func:`blocks` and :func:`take` (512 kB).
BLOCK = 65536


class SpoolFailed(OSError):
    """The spool's folder or files could not be made or written (a folder that cannot be written, a full disk)."""


class Spool:
    """The rows of one run, written to a hidden folder beside ``folder`` (the case's folder) as they come.

    ``append(t, y)`` writes a block of rows (the folder is made at the first); ``arrays()`` gives the
    rows written as read-only maps ``(t, x)``; ``discard()`` removes the folder; the store takes the
    folder over with ``handover()``."""

    T_FILE = "t.f64"
    X_FILE = "x.f64"

    def __init__(self, folder: Path):
        self.target = Path(folder)
        self.folder: Path | None = None
        self._held: HiddenFolder | None = None
        self.rows = 0
        self.width: int | None = None
        self._fds: list[int] = []
        self._cleanup = None

    def append(self, t: np.ndarray, y: np.ndarray) -> None:
        """Write ``t`` (rows,) and ``y`` (rows, n) after the rows already written."""
        try:
            if self.folder is None:
                self._open(y.shape[1])
            _write_all(self._fds[0], np.ascontiguousarray(t, dtype=float))
            _write_all(self._fds[1], np.ascontiguousarray(y, dtype=float))
        except OSError as exc:
            self.discard()
            raise SpoolFailed(exc.errno, exc.strerror or str(exc), exc.filename) from None
        self.rows += int(t.size)

    def _open(self, width: int) -> None:
        self._held = new_hidden_folder(self.target.parent, self.target.name)
        self.folder = self._held.path
        self.width = width
        self._cleanup = weakref.finalize(self, _remove_spool, self._held, self._fds)
        for name in (self.T_FILE, self.X_FILE):
            self._fds.append(os.open(self.folder / name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The rows written, as read-only maps of the files: ``t`` (rows,) and ``x`` (rows, n)."""
        _close(self._fds)
        if not self.rows:
            return np.zeros(0), np.zeros((0, self.width or 0))
        t = np.memmap(self.folder / self.T_FILE, dtype=float, mode="r", shape=(self.rows,))
        x = np.memmap(self.folder / self.X_FILE, dtype=float, mode="r", shape=(self.rows, self.width))
        return t, x

    def handover(self) -> HiddenFolder | None:
        """The spool's folder, held, for the store to write the case into (the raw files still in it): from now
        on the store removes it if the case cannot be written. None if there is none (nothing spooled, or the
        folder was already handed over or discarded)."""
        held, self._held, self.folder = self._held, None, None
        if self._cleanup is not None:
            self._cleanup.detach()
            self._cleanup = None
        _close(self._fds)
        return held

    def discard(self) -> None:
        """Remove the folder and what is in it (the maps already given out stay readable until dropped)."""
        if self._cleanup is not None:
            self._cleanup()
            self._cleanup = None
        _close(self._fds)
        self.folder = self._held = None


def _remove_spool(held: HiddenFolder, fds: list[int]) -> None:
    _close(fds)
    held.remove()  # and the experiment folder, if the spool was all it held


def _close(fds: list[int]) -> None:
    while fds:
        with contextlib.suppress(OSError):
            os.close(fds.pop())


def _write_all(fd: int, values: np.ndarray) -> None:
    view = memoryview(values).cast("B")
    while view:
        view = view[os.write(fd, view):]


def release(values) -> None:
    """Hand back the pages of the file map under ``values`` (an array or a view of one): they are read again
    from the file when next touched. Nothing for an array in memory."""
    base = values
    while base is not None:
        mapped = getattr(base, "_mmap", None)
        if isinstance(mapped, mmap.mmap):
            with contextlib.suppress(ValueError, OSError, AttributeError):  # closed, or no madvise here
                mapped.madvise(mmap.MADV_DONTNEED)
            return
        base = getattr(base, "base", None)


def blocks(values, size: int = BLOCK):
    """``values[lo:lo + size]`` for lo = 0, size, 2 size...: a map's pages handed back after each block."""
    for lo in range(0, len(values), size):
        yield values[lo:lo + size]
        release(values)


def take(values, rows) -> np.ndarray:
    """``values[rows]`` (an array of its own), gathered :data:`BLOCK` rows at a time from a map: its
    pages handed back after each block."""
    rows = np.asarray(rows)
    if rows.dtype == bool or rows.ndim != 1 or not _mapped(values):
        return np.asarray(values)[rows]
    out = np.empty((rows.size, *np.shape(values)[1:]), dtype=np.asarray(values[:0]).dtype)
    for lo in range(0, rows.size, BLOCK):
        out[lo:lo + BLOCK] = values[rows[lo:lo + BLOCK]]
        release(values)
    return out


def _mapped(values) -> bool:
    base = values
    while base is not None:
        if isinstance(getattr(base, "_mmap", None), mmap.mmap):
            return True
        base = getattr(base, "base", None)
    return False
