"""Students may hand in MATLAB files: the driver is graded, the function files it calls are read with it."""

from __future__ import annotations

from grading_support import EXERCISE1, by_name, write_class

from odelab.grading import grade_class

RUBRIC = """\
title = "Lab 5"
reference = "reference/"
submissions = "submissions/"

[[check]]
name = "trajectory"
experiment = "exercise1"
case = "ode23"
kind = "trajectory"
quantity = "y"
tolerance = { abs = 1e-12 }
points = 2

[[check]]
name = "solver"
experiment = "exercise1"
case = "ode23"
kind = "solver"
method = "ode23"
RelTol = 1e-3
points = 1
"""

EQ1 = "function ydot = eq1(t, y)\nydot = cos(t);\n"


def test_a_matlab_driver_and_its_function_file_are_graded_as_the_toml_would_be(tmp_path):
    students = {
        "ada": {"exercise1.m": "[t, y] = ode23(@eq1, [0 pi], 2);\nplot(t, y)\n", "eq1.m": EQ1},
        "bob": {"exercise1.m": "[t, y] = ode45(@eq1, [0 pi], 2);\n", "eq1.m": EQ1},
        "cy": {"exercise1.m": "[t, y] = ode23(@eq1, [0 pi], 2);\nsystem('ls')\n", "eq1.m": EQ1},
    }
    rubric = write_class(tmp_path, {"exercise1.toml": EXERCISE1}, students, RUBRIC)
    grades = by_name(grade_class(rubric, jobs=1))
    assert grades["ada"].score == grades["ada"].max_score == 3
    assert "exercise1.m" in grades["ada"].matched["exercise1"] and not grades["ada"].notes
    assert grades["bob"].score < 3  # ode45, not the ode23 the rubric asks for
    assert grades["cy"].score == 0
    feedback = " ".join([o.summary for o in grades["cy"].outcomes] + list(grades["cy"].matched.values()))
    assert "`system` runs a shell command" in feedback
