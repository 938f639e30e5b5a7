"""Files named inside an experiment file: a Python function file, an input table's CSV.

One place checks the name before anything touches the file system: no NUL byte or other
control character (``os.stat`` raises a bare ValueError on a NUL), resolved relative to the
experiment file, and for ``function`` only Python source. A shared library (``model.so:f``)
would run its constructor as soon as it is loaded, and a ``.pyc`` is code nobody can read:
the README's trust rule is about *your Python files*, so only ``.py`` source is accepted.
"""

from __future__ import annotations

import re
from pathlib import Path

from odelab.exceptions import ExperimentError

__all__ = ["PYTHON_SUFFIXES", "resolve_user_file", "check_python_source"]

PYTHON_SUFFIXES = (".py",)
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")
_NATIVE = {".so": "a shared library", ".pyd": "a compiled Python extension", ".dll": "a Windows library",
           ".dylib": "a macOS library", ".pyc": "compiled Python bytecode", ".pyo": "compiled Python bytecode"}


def resolve_user_file(name: str, key: str, experiment_path: Path) -> Path:
    """``name`` resolved relative to the experiment file's folder (it need not exist)."""
    bad = _CONTROL.search(name)
    if bad:
        what = "a NUL byte" if bad.group() == "\x00" else f"the control character \\x{ord(bad.group()):02x}"
        raise ExperimentError(f"`{key}` is {name!r}, which contains {what}; a file name cannot. Write the "
                              "file's name as it appears in the folder.", key=key)
    try:
        return (Path(experiment_path).parent / name).resolve()
    except (OSError, ValueError, RuntimeError) as exc:  # RuntimeError: a symlink loop (Python < 3.13)
        raise ExperimentError(f"`{key}` is {name!r}, which cannot be resolved: {exc}.", key=key) from None


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
