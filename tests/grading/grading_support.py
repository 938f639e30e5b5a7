"""Helpers of the grading tests: small classes (a reference, a rubric, students' folders) in a folder."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXERCISE1 = (ROOT / "experiments" / "exercise1.toml").read_text()
EXERCISE2 = (ROOT / "experiments" / "exercise2.toml").read_text()

EXERCISE1_RUBRIC = """\
title = "Lab 5"
reference = "reference/"
submissions = "submissions/"

[[check]]
name = "1a"
experiment = "exercise1"
case = "ode23"
kind = "headline"
quantity = "y"
tolerance = { rel = 0.01 }
points = 2

[[check]]
name = "1c"
experiment = "exercise1"
case = "ode23"
kind = "solver"
method = "ode23"
RelTol = 1e-3
points = 1
"""


def write_class(root: Path, reference: dict[str, str], students: dict[str, dict[str, str | bytes]],
                rubric: str) -> Path:
    """The class's files under ``root``; returns the rubric's path."""
    (root / "reference").mkdir(parents=True)
    for name, text in reference.items():
        (root / "reference" / name).write_text(text)
    for student, files in students.items():
        folder = root / "submissions" / student
        folder.mkdir(parents=True)
        for name, content in files.items():
            path = folder / name
            path.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(content, bytes):
                path.write_bytes(content)
            else:
                path.write_text(content)
    (root / "rubric.toml").write_text(rubric)
    return root / "rubric.toml"


def by_name(grades):
    return {s.name: s for s in grades.students}
