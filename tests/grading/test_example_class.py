"""The example class of examples/grading: its expected summary, the feedback naming each mistake,
reproducibility, Gradescope's format, and the CLI."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from odelab.grading import class_document, grade_class, write_grades

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "grading"

EXPECTED_SUMMARY = """\
student,Exercise 1a: ode23's maximum relative error,Exercise 1c: ode23 with RelTol 1e-3 as asked,\
Exercise 2: step response,Exercise 2: settling time,Exercise 2: steady state with ode23,total
broken-toml,2,1,0,0,0,3
correct,2,1,3,1,1,8
ode45-for-ode23,0,0,3,1,1,5
python-function,0,0,3,1,1,5
wrong-sign,0,1,3,1,1,6
wrong-tolerance,0,0,3,1,1,5
"""


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """The example class copied (so that nothing is written next to it) and graded once."""
    where = tmp_path_factory.mktemp("class")
    shutil.copytree(EXAMPLE, where / "grading")
    grades = grade_class(where / "grading" / "rubric.toml")
    out = where / "grades"
    write_grades(grades, out)
    return where, grades, out


def feedback(out: Path, student: str) -> str:
    return (out / student / "feedback.md").read_text()


def test_expected_summary(graded):
    _, _, out = graded
    assert (out / "summary.csv").read_text() == EXPECTED_SUMMARY


def test_feedback_names_each_mistake(graded):
    _, grades, out = graded
    assert "**Score: 8 / 8**" in feedback(out, "correct")
    assert "failed" not in feedback(out, "correct")
    assert "exercise2: found by its title: lab5_exercise2.toml" in feedback(out, "correct")

    text = feedback(out, "wrong-tolerance")
    assert "solver.rtol is 1e-06 where the lab asks for rtol = 0.001" in text
    assert "solver.rtol is 1e-06 where the reference has 0.001" in text  # under the failed headline check

    assert "the equation of y is '-cos(t)' where the reference has 'cos(t)'" in feedback(out, "wrong-sign")

    text = feedback(out, "ode45-for-ode23")
    assert "solver.method is 'ode45' where the lab asks for 'ode23'" in text
    assert "solver.method is 'ode45' where the reference has 'ode23'" in text

    text = feedback(out, "broken-toml")
    assert "exercise2.toml: TOML syntax error" in text and "line 10" in text
    assert "Exercise 1a: ode23's maximum relative error: passed (2 / 2)" in text  # its other file still counts
    assert "exercise2: found by its name: exercise2.toml, which could not be used (TOML syntax error)" in text

    text = feedback(out, "python-function")
    assert "`system.function` is 'eq1.py:eq1', a Python function; grading never runs a submission's code" in text
    assert "--allow-python" in text


def test_the_python_submission_was_never_imported(graded):
    where, _, _ = graded
    assert not (where / "grading" / "submissions" / "python-function" / "IMPORTED").exists()


def test_headline_values_are_the_labs(graded):
    """The correct student's ode23 error is the reference's; the ode45 one is far smaller (order 5 vs 3)."""
    _, grades, _ = graded
    by = {s.name: s for s in grades.students}
    correct = by["correct"].outcomes[0]
    assert correct.passed and correct.student == correct.reference
    # |f - y| / |f| of ode23 at RelTol 1e-3 on [0, pi]: about 1e-4, a tenth of RelTol
    assert 3e-5 < float(correct.reference) < 3e-4
    assert float(by["ode45-for-ode23"].outcomes[0].student) < 0.01 * float(correct.reference)
    # a wrong sign: y = 2 - sin t against sin t + 2, relative error 2 sin t / (2 + sin t) up to 2/3
    assert float(by["wrong-sign"].outcomes[0].student) == pytest.approx(2 / 3, rel=0.02)


def test_grading_is_reproducible(graded, tmp_path):
    """Graded again (and with a process pool of two), the files are byte-identical."""
    where, _, out = graded
    again = tmp_path / "again"
    write_grades(grade_class(where / "grading" / "rubric.toml", jobs=2), again)
    for name in ("summary.csv", "results.json", "summary.html", "wrong-sign/feedback.md"):
        assert (again / name).read_bytes() == (out / name).read_bytes(), name


def test_results_json_is_gradescopes_format(graded):
    _, grades, out = graded
    doc = json.loads((out / "results.json").read_text())
    assert doc == class_document(grades)
    assert doc["score"] == 3 + 8 + 5 + 5 + 6 + 5
    assert len(doc["tests"]) == 6 * 5
    for test in doc["tests"]:
        assert set(test) >= {"name", "score", "max_score", "output"}
        assert 0 <= test["score"] <= test["max_score"]
        assert test["status"] in ("passed", "failed")
    first = doc["tests"][0]
    assert first["name"] == "broken-toml: Exercise 1a: ode23's maximum relative error"
    students = {s["name"]: s["score"] for s in doc["extra_data"]["students"]}
    assert students == {"broken-toml": 3, "correct": 8, "ode45-for-ode23": 5, "python-function": 5,
                        "wrong-sign": 6, "wrong-tolerance": 5}
    one = json.loads((out / "wrong-sign" / "results.json").read_text())
    assert one["score"] == 6 and [t["score"] for t in one["tests"]] == [0, 1, 3, 1, 1]
    assert "the equation of y is '-cos(t)'" in one["tests"][0]["output"]


def test_html_summary(graded):
    _, _, out = graded
    html = (out / "summary.html").read_text()
    assert "Lab 5: class summary" in html and "6 students" in html
    # the only failure of Exercise 2's checks, counted
    assert html.count("<td>TOML syntax error (1)</td>") == 3
    assert 'href="wrong-sign/feedback.md"' in html


def test_one_student_submission_is_gradescopes_layout(tmp_path):
    """A folder with experiment files in it (Gradescope's /autograder/submission) is one student."""
    shutil.copytree(EXAMPLE / "submissions" / "wrong-tolerance", tmp_path / "submission")
    grades = grade_class(EXAMPLE / "rubric.toml", tmp_path / "submission")
    write_grades(grades, tmp_path / "grades")
    doc = json.loads((tmp_path / "grades" / "results.json").read_text())
    assert doc["score"] == 5
    assert [t["name"] for t in doc["tests"]][0] == "Exercise 1a: ode23's maximum relative error"
    assert "solver.rtol is 1e-06" in doc["tests"][1]["output"]


def test_cli_grade_and_json(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from odelab.cli import app

    shutil.copytree(EXAMPLE, tmp_path / "grading")
    monkeypatch.chdir(tmp_path)  # the grades folder defaults to ./grades
    args = ["grade", str(tmp_path / "grading" / "rubric.toml"), "--json"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout) == json.loads((tmp_path / "grades" / "results.json").read_text())
    rows = list(csv.DictReader((tmp_path / "grades" / "summary.csv").open()))
    assert {r["student"]: r["total"] for r in rows}["correct"] == "8"
    result = CliRunner().invoke(app, args[:-1] + ["--out", str(tmp_path / "elsewhere")], terminal_width=80)
    assert result.exit_code == 0 and "wrong-sign" in result.stdout and "6 / 8" in result.stdout
    assert (tmp_path / "elsewhere" / "summary.csv").read_text() == EXPECTED_SUMMARY
