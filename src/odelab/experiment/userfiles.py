"""Files named inside an experiment file: a Python function file, an input table's CSV.

One place checks the name before anything touches the file system: no NUL byte or other
control character (``os.stat`` raises a bare ValueError on a NUL), resolved relative to the
experiment file, and for ``function`` only Python source. A shared library (``model.so:f``)
would run its constructor as soon as it is loaded, and a ``.pyc`` is code nobody can read:
the README's trust rule is about *your Python files*, so only ``.py`` source is accepted.
"""

from __future__ import annotations

import contextlib
import re
from contextvars import ContextVar
from pathlib import Path

from odelab.exceptions import ExperimentError

__all__ = ["PYTHON_SUFFIXES", "confined_to", "resolve_user_file", "check_python_source"]

PYTHON_SUFFIXES = (".py",)
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")
_NATIVE = {".so": "a shared library", ".pyd": "a compiled Python extension", ".dll": "a Windows library",
           ".dylib": "a macOS library", ".pyc": "compiled Python bytecode", ".pyo": "compiled Python bytecode"}


# Set while grading a submission (odelab.grading): files it names must stay inside this folder.
_CONFINED: ContextVar[Path | None] = ContextVar("odelab_confined_folder", default=None)


@contextlib.contextmanager
def confined_to(folder: Path):
    """While inside, a file named by an experiment file must resolve inside ``folder`` (symbolic links
    followed): a graded submission cannot read the instructor's or another student's files."""
    token = _CONFINED.set(Path(folder).resolve())
    try:
        yield
    finally:
        _CONFINED.reset(token)


def resolve_user_file(name: str, key: str, experiment_path: Path) -> Path:
    """``name`` resolved relative to the experiment file's folder (it need not exist); inside
    :func:`confined_to`, refused unless it stays inside the confining folder."""
    bad = _CONTROL.search(name)
    if bad:
        what = "a NUL byte" if bad.group() == "\x00" else f"the control character \\x{ord(bad.group()):02x}"
        raise ExperimentError(f"`{key}` is {name!r}, which contains {what}; a file name cannot. Write the "
                              "file's name as it appears in the folder.", key=key)
    try:
        resolved = (Path(experiment_path).parent / name).resolve()
    except (OSError, ValueError, RuntimeError) as exc:  # RuntimeError: a symlink loop (Python < 3.13)
        raise ExperimentError(f"`{key}` is {name!r}, which cannot be resolved: {exc}.", key=key) from None
    root = _CONFINED.get()
    if root is not None and not resolved.is_relative_to(root):
        how = ("an absolute path" if Path(name).is_absolute() else "a path that leaves it with '..'"
               if ".." in Path(name).parts else "a symbolic link to a file outside it")
        raise ExperimentError(f"`{key}` is {name!r}, {how}; a graded submission may only read files inside its "
                              "own folder: put the file next to the experiment file and name it there.", key=key)
    return resolved


def check_python_source(file_part: str, key: str) -> None:
    """Refuse anything but a .py source file as a `function`, saying why."""
    suffix = Path(file_part).suffix.lower()
    if suffix in PYTHON_SUFFIXES:
        return
    kind = _NATIVE.get(suffix) or (f"a {suffix} file" if suffix else "a file without the .py ending")
    raise ExperimentError(
        f"`{key}` names {file_part!r}, {kind}; odelab runs only Python source files (.py) there, the "
        "files you can read and trust, as MATLAB runs a function file. Write the function in a .py file.",
        key=key)
