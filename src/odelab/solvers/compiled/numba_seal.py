"""The numba cache seal: numba's index and data files of odelab's compiled modules are sealed
when numba writes them and checked against the seal before numba reads them.

numba unpickles its cache files (``.nbi`` index, ``.nbc`` machine code); a file odelab did not
write must never reach that. :func:`guard_numba_cache` wraps numba's
``IndexDataCacheFile`` once per process: for the files of odelab's own modules (named
``odelab_compiled_*`` and ``odelab_kernels_*`` by :mod:`odelab.solvers.compiled.cache`) a save
writes the file's SHA-256 beside it (:func:`odelab.cachedir.seal`) and a load reads it only if it
lies in a folder of the user's own and matches its seal (:func:`odelab.cachedir.verify`); a
damaged, foreign or unsealed entry is deleted and compiled again, with a note. numba's other
caches are left as they are. This is the one place that touches numba's cache internals.
"""

from __future__ import annotations

import os
import pickle
from pathlib import Path

from odelab import cachedir

__all__ = ["guard_numba_cache"]


def _ours(path: str) -> bool:
    """An entry of one of odelab's compiled modules (numba names them after the module)."""
    return os.path.basename(path).startswith(("odelab_compiled_", "odelab_kernels_"))


def _trusted(path: str) -> bool:
    return cachedir.unsafe(Path(os.path.dirname(path))) is None


def guard_numba_cache() -> None:
    """Make numba seal the index and data files of odelab's modules when it writes them, and
    load them only if they match their seal and lie in a folder of the user's own (else it
    compiles again, as for an empty cache). Installed once per process; numba's other caches
    are left as they are."""
    from numba.core import caching

    cls = caching.IndexDataCacheFile
    if getattr(cls, "_odelab_guarded", False):
        return
    load_index, save_index = cls._load_index, cls._save_index
    load_data, save_data = cls._load_data, cls._save_data

    def _load_index(self):
        path = self._index_path
        if _ours(path) and os.path.lexists(path):
            if not _trusted(path) or cachedir.verify(Path(path), "numba index") is None:
                return {}
            try:
                return load_index(self)
            except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, ImportError):
                cachedir.note(f"the cached numba index {os.path.basename(path)} could not be read: compiled "
                              "again")
                return {}
        return load_index(self)

    def _save_index(self, overloads):
        save_index(self, overloads)
        if _ours(self._index_path):
            cachedir.seal(Path(self._index_path))

    def _load_data(self, name):
        path = self._data_path(name)
        if _ours(path):
            if not _trusted(path) or cachedir.verify(Path(path), "numba machine code file") is None:
                raise FileNotFoundError(path)  # numba's load() then compiles again
            try:
                return load_data(self, name)
            except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, ImportError):
                raise FileNotFoundError(path) from None
        return load_data(self, name)

    def _save_data(self, name, data):
        save_data(self, name, data)
        path = self._data_path(name)
        if _ours(path):
            cachedir.seal(Path(path))

    cls._load_index, cls._save_index = _load_index, _save_index
    cls._load_data, cls._save_data = _load_data, _save_data
    cls._odelab_guarded = True
