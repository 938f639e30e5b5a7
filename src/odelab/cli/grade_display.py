"""The class's grades on a terminal (the CLI's table): one row a student, what they lost."""

from __future__ import annotations

from odelab.grading.grade import ClassGrade
from odelab.grading.writers import score_text
from odelab.terminal import shown

__all__ = ["print_grades"]


def print_grades(console, grades: ClassGrade) -> None:
    from rich.table import Table

    rubric = grades.rubric
    table = Table(title=f"{shown(rubric.title)}: {len(grades.students)} student"
                  f"{'s' if len(grades.students) != 1 else ''}", title_justify="left")
    table.add_column("student")
    table.add_column("score", justify="right")
    table.add_column("lost points on")
    for s in grades.students:
        lost = [o.check.name for o in s.outcomes if not o.passed and o.check.points > 0]
        table.add_row(shown(s.name), f"{score_text(s.score)} / {score_text(s.max_score)}",
                      shown("; ".join(lost)) if lost else "-")
    console.print(table)
