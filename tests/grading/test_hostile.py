"""Submissions are hostile input: each rule of issue 23, with a test.

- no code runs (a Python `function` is refused unless allow_python);
- every budget of `odelab run` applies to each student (and the class is graded within them);
- one student's broken or malicious file costs that student's checks only, with the message;
- a student's file never reads outside its folder (.., absolute paths, symbolic links);
- a missing experiment scores 0 with "not found: expected exercise1".
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from grading_support import EXERCISE1, by_name

from odelab.experiment.limits import DEFAULT_LIMITS
from odelab.grading import grade_class, write_grades

PYTHON_EXERCISE1 = EXERCISE1.replace('[system.equations]      # d(state)/dt, in the expression language\ny = "cos(t)"',
                                     'function = "eq1.py:eq1"')
EQ1 = '''import math
from pathlib import Path
Path(__file__).with_name("IMPORTED").write_text("imported")
def eq1(t, y):
    return [math.cos(t)]
'''


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def feedback_text(student) -> str:
    return "\n".join(o.summary for o in student.outcomes)


def test_python_function_is_refused_unless_allowed(make_class, tmp_path):
    assert PYTHON_EXERCISE1 != EXERCISE1
    rubric = make_class({"alice": {"exercise1.toml": PYTHON_EXERCISE1, "eq1.py": EQ1}, "bob": {"exercise1.toml": EXERCISE1}})
    grades = by_name(grade_class(rubric))
    assert not (tmp_path / "submissions" / "alice" / "IMPORTED").exists()
    assert grades["alice"].score == 0 and grades["bob"].score == 3
    assert "`system.function` is 'eq1.py:eq1', a Python function; grading never runs" in feedback_text(grades["alice"])

    grades = by_name(grade_class(rubric, allow_python=True))
    assert (tmp_path / "submissions" / "alice" / "IMPORTED").exists()
    assert grades["alice"].score == 3, feedback_text(grades["alice"])


def test_python_function_in_a_case_is_refused_too(make_class, tmp_path):
    sneaky = EXERCISE1 + '\n[[case]]\nname = "sneaky"\nsystem.function = "eq1.py:eq1"\n'
    rubric = make_class({"alice": {"exercise1.toml": sneaky, "eq1.py": EQ1}})
    grades = by_name(grade_class(rubric))
    assert not (tmp_path / "submissions" / "alice" / "IMPORTED").exists()
    assert "`case[2].system.function`" in feedback_text(grades["alice"])


DRIVEN = """\
title = "A first-order lag driven by a measured force"
[system]
states = ["x"]
inputs = ["f"]
[system.equations]
x = "-x + f"
[initial]
x = 0
[time]
stop = 2
[inputs]
f = { type = "table", file = "FILE" }
"""
DRIVEN_RUBRIC = """\
reference = "reference/"
submissions = "submissions/"
[[check]]
name = "x(2)"
experiment = "driven"
kind = "final"
quantity = "x"
tolerance = { rel = 1e-3 }
"""
FORCE = "t,f\n0,1\n1,1\n2,1\n"


def test_input_tables_must_stay_in_the_students_folder(make_class, tmp_path):
    secret = tmp_path / "secret.csv"
    secret.write_text(FORCE)
    students = {
        "good": {"driven.toml": DRIVEN.replace("FILE", "data/force.csv"), "data/force.csv": FORCE},
        "dotdot": {"driven.toml": DRIVEN.replace("FILE", "../../secret.csv")},
        "absolute": {"driven.toml": DRIVEN.replace("FILE", str(secret))},
        "symlink": {"driven.toml": DRIVEN.replace("FILE", "force.csv")},
        "neighbour": {"driven.toml": DRIVEN.replace("FILE", "../good/data/force.csv")},
    }
    rubric = make_class(students, reference={"driven.toml": DRIVEN.replace("FILE", "force.csv"), "force.csv": FORCE},
                        rubric=DRIVEN_RUBRIC)
    os.symlink(secret, tmp_path / "submissions" / "symlink" / "force.csv")
    grades = by_name(grade_class(rubric))
    assert grades["good"].score == 1, feedback_text(grades["good"])
    for name, how in (("dotdot", "a path that leaves it with '..'"), ("absolute", "an absolute path"),
                      ("symlink", "a symbolic link to a file outside it"),
                      ("neighbour", "a path that leaves it with '..'")):
        text = feedback_text(grades[name])
        assert grades[name].score == 0, name
        assert f"`inputs.f.file` is" in text and how in text, (name, text)
        assert "a graded submission may only read files inside its own folder" in text


def test_symbolic_links_to_files_or_folders_outside_are_not_followed(make_class, tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "exercise1.toml").write_text(EXERCISE1)
    rubric = make_class({"linked-file": {}, "bob": {"exercise1.toml": EXERCISE1}})
    os.symlink(outside / "exercise1.toml", tmp_path / "submissions" / "linked-file" / "exercise1.toml")
    os.symlink(outside, tmp_path / "submissions" / "linked-folder")
    grades = by_name(grade_class(rubric))
    assert grades["bob"].score == 3
    assert grades["linked-file"].score == 0
    assert "symbolic link to a file outside the submission's folder" in feedback_text(grades["linked-file"])
    assert grades["linked-folder"].score == 0
    assert "is a symbolic link" in " ".join(grades["linked-folder"].notes)


def test_grading_writes_only_the_grades_folder(make_class, tmp_path):
    rubric = make_class({"alice": {"exercise1.toml": EXERCISE1}, "eve": {"exercise1.toml": PYTHON_EXERCISE1,
                                                                        "eq1.py": EQ1}})
    before = snapshot(tmp_path)
    write_grades(grade_class(rubric), tmp_path / "grades")
    after = snapshot(tmp_path)
    assert {k: v for k, v in after.items() if not k.startswith("grades/")} == before
    assert sorted(k for k in after if k.startswith("grades/")) == [
        "grades/alice/feedback.md", "grades/alice/results.json", "grades/eve/feedback.md", "grades/eve/results.json",
        "grades/results.json", "grades/summary.csv", "grades/summary.html"]


def test_broken_and_malicious_files_cost_their_students_only(make_class):
    nested = "x = " + "[" * 40 + "]" * 40 + "\n"
    students = {
        "ok": {"exercise1.toml": EXERCISE1},
        "binary": {"exercise1.toml": b"\x7fELF\x00\x00\x01" * 100},
        "huge": {"exercise1.toml": "# " + "x" * 1_100_000 + "\n"},
        "nested": {"exercise1.toml": nested},
        "injection": {"exercise1.toml": EXERCISE1.replace('y = "cos(t)"', 'y = "__import__(\'os\').getcwd()"')},
        "utf16": {"exercise1.toml": EXERCISE1.encode("utf-16")},
        "wrong-types": {"exercise1.toml": EXERCISE1.replace('stop = "pi"', 'stop = [1, 2]')},
        "nan": {"exercise1.toml": EXERCISE1.replace('stop = "pi"', 'stop = nan')},
    }
    grades = by_name(grade_class(make_class(students)))
    assert grades["ok"].score == 3
    for name in students:
        if name == "ok":
            continue
        assert grades[name].score == 0, name
        text = feedback_text(grades[name])
        assert text.startswith("exercise1.toml: "), (name, text)  # the file named, then why
    assert "binary file" in feedback_text(grades["binary"])
    assert "1,000,000 bytes" in feedback_text(grades["huge"])
    assert "nest" in feedback_text(grades["nested"])
    assert "system.equations.y" in feedback_text(grades["injection"])
    assert "UTF-16" in feedback_text(grades["utf16"])
    assert "`time.stop`" in feedback_text(grades["wrong-types"])


def test_budgets_apply_to_each_student(make_class):
    students = {
        "ok": {"exercise1.toml": EXERCISE1},
        # a minimum of 3e9 steps: refused before it runs, as odelab run refuses it
        "tiny-step": {"exercise1.toml": EXERCISE1.replace('method = "ode23"', 'method = "ode23"\nmax_step = 1e-9')},
        # 5 million output points: over the points budget
        "points": {"exercise1.toml": EXERCISE1.replace('stop = "pi"', 'stop = "pi"\npoints = 5000000')},
        # RelTol and AbsTol 1e-12 take thousands of steps: stopped by --max-steps 300 (the reference needs 11)
        "long": {"exercise1.toml": EXERCISE1.replace('method = "ode23"', 'method = "ode23"\nRelTol = 1e-12\nAbsTol = 1e-12')},
    }
    rubric = make_class(students)
    grades = by_name(grade_class(rubric, max_steps=300))
    assert grades["ok"].score == 3
    tiny = feedback_text(grades["tiny-step"])
    assert "`solver.max_step`" in tiny and "the budget is 1,000,000 steps per solve" in tiny
    assert "`time.points` is 5,000,000; the budget is 2,000,000 output points per case" in feedback_text(
        grades["points"])
    long = grades["long"].outcomes[0]
    assert not long.passed and "step budget" in long.summary and "--max-steps 300" in long.summary
    # the run's --limit budgets too: with room for 100 points, the points student is still refused
    limits = replace(DEFAULT_LIMITS, points=100)
    grades = by_name(grade_class(rubric, limits=limits, max_steps=300))
    assert grades["ok"].score == 3 and grades["points"].score == 0
    assert "the budget is 100 output points per case" in feedback_text(grades["points"])


def test_missing_experiment_scores_zero_with_not_found(make_class):
    grades = by_name(grade_class(make_class({"alice": {"notes.toml": 'title = "my notes"\n'}, "bob": {}})))
    for name in ("alice", "bob"):
        assert grades[name].score == 0
        assert [o.summary for o in grades[name].outcomes] == ["not found: expected exercise1"] * 2


def test_one_case_that_breaks_odelab_costs_that_case_only(make_class, monkeypatch):
    """An unexpected error inside a run (a bug, not a bad file) fails that student's checks of that case."""
    import odelab.run.runner as runner

    real = runner.run_case

    def run_case(case, **kw):
        if "eve" in str(case.source):
            raise ZeroDivisionError("float division by zero")
        return real(case, **kw)

    monkeypatch.setattr(runner, "run_case", run_case)
    grades = by_name(grade_class(make_class({"alice": {"exercise1.toml": EXERCISE1},
                                             "eve": {"exercise1.toml": EXERCISE1},
                                             "zoe": {"exercise1.toml": EXERCISE1}}), executor="serial"))
    assert grades["alice"].score == 3 and grades["zoe"].score == 3
    eve = grades["eve"].outcomes
    assert eve[0].score == 0 and "odelab could not run this case: ZeroDivisionError" in eve[0].summary
    assert eve[1].passed  # the solver check reads the file, it needs no run


def test_a_student_name_is_never_a_spreadsheet_formula(make_class, tmp_path):
    import csv

    rubric = make_class({'=HYPERLINK("x")': {"exercise1.toml": EXERCISE1}, "ann": {}})
    write_grades(grade_class(rubric), tmp_path / "grades")
    rows = list(csv.reader((tmp_path / "grades" / "summary.csv").open()))
    assert [r[0] for r in rows[1:]] == ["'=HYPERLINK(\"x\")", "ann"]
    assert (tmp_path / "grades" / "HYPERLINK-x" / "feedback.md").is_file()  # a folder name that stays put


def test_a_stray_experiment_file_beside_the_students_folders_is_not_a_student(make_class, tmp_path):
    rubric = make_class({"alice": {"exercise1.toml": EXERCISE1}, "bob": {"exercise1.toml": EXERCISE1}})
    (tmp_path / "submissions" / "exercise1.toml").write_text(EXERCISE1)
    (tmp_path / "submissions" / "notes.txt").symlink_to(tmp_path / "rubric.toml")
    assert sorted(by_name(grade_class(rubric))) == ["alice", "bob"]


def test_feedback_never_shows_the_grading_machines_folders(make_class, tmp_path):
    driven = DRIVEN.replace("FILE", "missing.csv")
    rubric = make_class({"ann": {"driven.toml": driven}},
                        reference={"driven.toml": DRIVEN.replace("FILE", "force.csv"), "force.csv": FORCE},
                        rubric=DRIVEN_RUBRIC)
    text = feedback_text(by_name(grade_class(rubric))["ann"])
    assert "'missing.csv' does not exist (looked for missing.csv)" in text, text
    assert str(tmp_path) not in text
