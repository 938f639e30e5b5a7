"""File formats: a file's bytes to the plain dict an experiment file holds, one reader per format.

The reader is chosen by the file's suffix (:data:`READERS`): ``.toml`` experiment files,
``.m`` MATLAB ODE code and ``.slx``/``.mdl`` Simulink models; a file with another suffix is
read as TOML, as it always was. Each reader is a module with
``read(path, options) -> Document`` (:mod:`odelab.formats.base`), imported only when a file of
its format is read. This package is the only place that knows a file's syntax; adding a format
is one module here and one entry in :data:`READERS`.
"""

from __future__ import annotations

import importlib
from pathlib import Path

from odelab.formats.base import GAP, IGNORED, TRANSLATED, Document, ImportOptions, Note

__all__ = ["READERS", "FOLDER_SUFFIXES", "Document", "ImportOptions", "Note", "TRANSLATED", "IGNORED", "GAP",
           "read", "reader_name", "is_experiment_file", "is_experiment"]

#: suffix -> (the reader's module, what the format is called in messages)
READERS: dict[str, tuple[str, str]] = {
    ".toml": ("odelab.formats.toml", "an experiment file"),
    ".m": ("odelab.formats.matlab", "a MATLAB file"),
    ".slx": ("odelab.formats.simulink", "a Simulink model"),
    ".mdl": ("odelab.formats.simulink", "a Simulink model"),
}

#: What ``odelab run FOLDER`` picks up in a folder: experiment files only (a MATLAB folder holds
#: function files and plotting scripts that are not experiments; name those files explicitly).
FOLDER_SUFFIXES: tuple[str, ...] = (".toml",)


def reader_name(path: Path) -> str:
    """The module that reads ``path`` (by its suffix; TOML for an unknown suffix)."""
    entry = READERS.get(Path(path).suffix.lower())
    return entry[0] if entry else READERS[".toml"][0]


def is_experiment_file(path: Path) -> bool:
    """A file whose suffix names a format odelab reads."""
    return Path(path).suffix.lower() in READERS


def is_experiment(path: Path) -> bool:
    """Whether a file of a format odelab reads describes an experiment by itself (for ``odelab grade``, which
    finds a student's files in a folder): every ``.toml``; a MATLAB file that calls a solver (not a function file
    another one calls). A reader module decides with its own ``is_experiment(path)``, if it has one."""
    path = Path(path)
    if not is_experiment_file(path):
        return False
    module = importlib.import_module(reader_name(path))
    check = getattr(module, "is_experiment", None)
    return True if check is None else bool(check(path))


def read(path: str | Path, options: ImportOptions | None = None) -> Document:
    """Read ``path`` with the reader of its format.

    Raises
    ------
    ExperimentError
        One message naming the file (and the line or block), what is wrong and the fix.
    """
    path = Path(path)
    module = importlib.import_module(reader_name(path))
    return module.read(path, options or ImportOptions())
