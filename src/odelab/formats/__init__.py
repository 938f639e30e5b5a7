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
           "read", "reader_name", "is_experiment_file", "is_experiment", "explain_import"]

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


IMPORT_TOPIC = (
    "import  (odelab import FILE... [-o DIR] [--workspace SCRIPT.m]... [--set NAME=VALUE]... [--call CALL])\n"
    "  Writes the experiment file (NAME.toml) of a file in another format, commented with where each part came\n"
    "  from, and prints what was translated, what was ignored and what could not be (the gaps, each with what\n"
    "  to write instead). Exit 0: everything translated; 1: written with gaps marked GAP: (it runs once they\n"
    "  are filled in); 2: nothing usable (unreadable, hostile). Nothing in the file is ever run. `odelab run`\n"
    "  takes the same files and options directly; the written file runs bit for bit as the source does.")


def explain_import(topic: str = "import") -> str:
    """``odelab explain import`` (and ``import.m``, ``import.slx``...): what ``odelab import`` reads, from each
    reader's own ``EXPLAIN`` text."""
    parts = topic.split(".", 1)
    suffixes = [s for s in READERS if s != ".toml"]
    if len(parts) == 2:
        wanted = [s for s in suffixes if s.lstrip(".") == parts[1].lower().lstrip(".")
                  or READERS[s][1].lower().endswith(parts[1].lower())]
        if not wanted:
            raise LookupError(f"no import topic `{topic}`; the formats are "
                              f"{', '.join('import.' + s.lstrip('.') for s in suffixes)}.")
        suffixes = wanted
    texts = [IMPORT_TOPIC] if len(parts) == 1 else []
    seen = set()
    for suffix in suffixes:
        module = READERS[suffix][0]
        if module in seen:
            continue
        seen.add(module)
        text = getattr(importlib.import_module(module), "EXPLAIN", None)
        if text:
            texts.append(text)
    return "\n\n".join(texts)


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
