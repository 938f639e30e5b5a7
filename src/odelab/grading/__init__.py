"""Grading a class's experiment files against a reference (``odelab grade rubric.toml``).

:func:`grade_class` matches each student's experiments to the reference's, runs them as
``odelab run`` does and evaluates the rubric's checks; :func:`write_grades` writes the grades
folder (summary.csv, per-student feedback.md and results.json, Gradescope's results.json, an
HTML class summary). See docs/grading.md.
"""

from odelab.grading.grade import ClassGrade, StudentGrade, grade_class
from odelab.grading.rubric import CHECK_KINDS, Rubric, RubricError, load_rubric
from odelab.grading.writers import class_document, write_grades

__all__ = ["CHECK_KINDS", "ClassGrade", "Rubric", "RubricError", "StudentGrade", "class_document", "grade_class",
           "load_rubric", "write_grades"]
