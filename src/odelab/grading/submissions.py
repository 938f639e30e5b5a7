"""A class's submissions: one folder per student, read as hostile input.

Nothing a submission holds is run as code: a file whose system is a Python ``function`` is
refused (unless the instructor passes ``allow_python``), and a file it names (an input table)
must resolve inside the student's own folder (see
:func:`odelab.experiment.userfiles.confined_to`). Symbolic links that leave the folder are not
followed; a student's folder holds at most :data:`MAX_FILES` experiment files, each within the
size and nesting limits of any experiment file. Every problem is recorded against that student
only, as a message for their feedback.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from odelab.exceptions import ExperimentError, InputError

__all__ = ["MAX_FILES", "StudentFile", "Student", "find_students", "python_keys"]

MAX_FILES = 100
"""Experiment files read per student (a lab hands in a few)."""

_MAX_DEPTH = 4  # folders below the student's (an unzipped "lab5/" folder inside it is common)


@dataclass
class StudentFile:
    path: Path  # as found, inside the student's folder
    data: dict | None = None  # the parsed TOML
    error: InputError | None = None  # why it cannot be read or is refused

    @property
    def relative(self) -> str:
        return self.path.name

    def experiment_names(self) -> list[tuple[str, str | None]]:
        """(name, title) of each experiment the file holds, read from its TOML alone."""
        data = self.data or {}
        name = data.get("name") if isinstance(data.get("name"), str) else self.path.stem
        title = data.get("title") if isinstance(data.get("title"), str) else None
        problems = data.get("problem")
        if isinstance(problems, list) and all(isinstance(p, dict) for p in problems):
            return [(f"{name}_{p.get('name')}", p.get("title") if isinstance(p.get("title"), str) else title)
                    for p in problems]
        return [(name, title)]


@dataclass
class Student:
    name: str
    folder: Path
    files: list[StudentFile] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # problems with the submission as a whole


def find_students(submissions: Path) -> list[Student]:
    """The students of a submissions folder, sorted by name.

    Each sub-folder is a student. A folder with experiment files directly in it and no
    sub-folder that has any (Gradescope's ``/autograder/submission``) is one student's
    submission, named after the folder.
    """
    submissions = Path(submissions)
    if not submissions.is_dir():
        raise InputError(f"{submissions}: the submissions folder does not exist; give the folder that holds one "
                         "folder per student.", key="submissions")
    entries = sorted(os.scandir(submissions), key=lambda e: e.name)
    subfolders = [e for e in entries if not e.name.startswith(".") and e.is_dir()]  # symbolic links too: refused
    if any(_is_toml(e) for e in entries) and not any(_has_toml(e) for e in subfolders):
        folders = [(submissions.resolve().name or "student", submissions)]
    else:
        folders = [(e.name, Path(e.path)) for e in subfolders]
    students = []
    for name, folder in folders:
        student = Student(name=name, folder=folder)
        if folder.is_symlink():
            student.notes.append(f"the submission folder {name!r} is a symbolic link; a submission must be a "
                                 "folder of its own, so nothing in it was graded.")
        else:
            _collect(student)
        students.append(student)
    return students


def _is_toml(entry) -> bool:
    """An experiment file of a format odelab reads (.toml, a MATLAB driver .m, a Simulink model)."""
    from odelab.formats import is_experiment

    return (not entry.name.startswith(".") and entry.is_file(follow_symlinks=False)
            and is_experiment(Path(entry.path)))


def _has_toml(entry) -> bool:
    if entry.is_symlink():
        return True  # a student's folder (refused as a link), not files of one submission
    try:
        return any(_is_toml(e) for e in os.scandir(entry.path))
    except OSError:
        return False


def _collect(student: Student) -> None:
    root = student.folder.resolve()
    found: list[Path] = []
    for here, dirs, files in os.walk(student.folder, followlinks=False):
        depth = len(Path(here).relative_to(student.folder).parts)
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and depth < _MAX_DEPTH)
        found.extend(Path(here) / f for f in sorted(files) if not f.startswith(".") and _is_experiment(Path(here) / f))
    found.sort(key=lambda p: p.relative_to(student.folder).as_posix())
    if len(found) > MAX_FILES:
        student.notes.append(f"the submission has {len(found)} experiment files; only the first {MAX_FILES} (by "
                             "name) were read.")
        found = found[:MAX_FILES]
    for path in found:
        item = StudentFile(path=path)
        student.files.append(item)
        shown = path.relative_to(student.folder).as_posix()
        try:
            target = path.resolve()
        except (OSError, RuntimeError) as exc:
            item.error = ExperimentError(f"cannot be resolved: {exc}.", source=shown)
            continue
        if not target.is_relative_to(root):
            item.error = ExperimentError("is a symbolic link to a file outside the submission's folder; it was not "
                                         "read. Hand in the file itself.", source=shown)
            continue
        from odelab.experiment.userfiles import confined_to
        from odelab.formats import read

        try:
            with confined_to(student.folder):
                doc = read(path)
        except InputError as exc:
            item.error = ExperimentError(exc.message, source=shown, key=exc.key)
            continue
        item.data = doc.data
        if doc.gaps:
            item.error = ExperimentError(doc.gaps_message(), source=shown)


def _is_experiment(path: Path) -> bool:
    from odelab.formats import is_experiment

    return not path.is_symlink() and is_experiment(path) if path.suffix.lower() != ".toml" else True


def python_keys(data: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """Every ``function`` key in a parsed experiment file (a Python system, wherever it is set), with its value."""
    found = []
    if isinstance(data, dict):
        for key, value in data.items():
            path = f"{prefix}.{key}" if prefix else str(key)
            if key == "function":
                found.append((path, value))
            found.extend(python_keys(value, path))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            found.extend(python_keys(value, f"{prefix}[{i}]"))
    return found
