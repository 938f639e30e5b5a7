"""The grades folder: summary.csv, <student>/feedback.md, results.json (Gradescope's format), summary.html.

Everything written is a function of the inputs alone: students sorted by name, checks in the
rubric's order, numbers in fixed formats, no time stamps, no timings; so grading the same class
twice gives byte-identical files. Each file is written to a temporary name and renamed into
place, so a file is never left half-written.

``results.json`` follows Gradescope's autograder specification
(https://gradescope-autograders.readthedocs.io/en/latest/specs/): ``{"score", "output",
"tests": [{"name", "score", "max_score", "status", "output"}], "extra_data"}``. For one
student's submission (the layout of Gradescope's ``/autograder/submission``) it is that
student's; for a class it holds every student's tests, named ``"student: check"``, with each
student's total in ``extra_data.students``; every ``<student>/results.json`` is that student's alone.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections import Counter
from pathlib import Path

from odelab.grading.grade import ClassGrade, StudentGrade
from odelab.terminal import visible

__all__ = ["class_document", "student_document", "summary_csv", "feedback_md", "summary_html", "write_grades",
           "score_text", "student_folder"]


def score_text(x: float) -> str:
    """A score as written everywhere: ``2``, ``1.5``, ``0.3333`` (no float noise)."""
    x = round(float(x), 4)
    return str(int(x)) if x == int(x) else f"{x:g}"


def _score(x: float):
    x = round(float(x), 4)
    return int(x) if x == int(x) else x


def student_folder(name: str) -> str:
    """The student's folder under the grades folder (a name that cannot leave it)."""
    from odelab.experiment.naming import slug

    return slug(name)


def _folders(grades: ClassGrade) -> dict[str, str]:
    out, taken = {}, set()
    for student in grades.students:
        base = student_folder(student.name)
        name, k = base, 2
        while name.casefold() in taken:
            name, k = f"{base}-{k}", k + 1
        taken.add(name.casefold())
        out[student.name] = name
    return out


def summary_csv(grades: ClassGrade) -> str:
    """One row a student, one column a check (its score), then the total; the first row names the checks."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["student", *(c.name for c in grades.rubric.checks), "total"])
    for student in grades.students:
        writer.writerow([_cell(visible(student.name)), *(score_text(o.score) for o in student.outcomes),
                         score_text(student.score)])
    return buf.getvalue()


def _cell(text: str) -> str:
    """A name as a spreadsheet cell: one starting with = + - @ would be read as a formula (OWASP's CSV
    injection), so it gets a leading apostrophe, which spreadsheets show as text."""
    return "'" + text if text[:1] in ("=", "+", "-", "@") else text


def _test_output(outcome) -> str:
    lines = [("passed: " if outcome.passed else "failed: ") + outcome.summary]
    if not outcome.passed and outcome.differences:
        lines.append("What differs in your file from the reference's:")
        lines.extend(f"- {d}" for d in outcome.differences)
    return visible("\n".join(lines), lines=True)


def _tests(student: StudentGrade, prefix: str = "") -> list[dict]:
    return [{"name": prefix + o.check.name, "score": _score(o.score), "max_score": _score(o.check.points),
             "status": "passed" if o.passed else "failed", "output": _test_output(o)}
            for o in student.outcomes]


def _student_output(grades: ClassGrade, student: StudentGrade) -> str:
    lines = [f"{grades.rubric.title}: {score_text(student.score)} / {score_text(student.max_score)}"]
    lines.extend(f"{e}: {how}" for e, how in student.matched.items())
    lines.extend(student.notes)
    return visible("\n".join(lines), lines=True)


def student_document(grades: ClassGrade, student: StudentGrade) -> dict:
    """One student's results.json, as Gradescope reads it from /autograder/results/results.json."""
    return {"score": _score(student.score), "output": _student_output(grades, student), "tests": _tests(student)}


def class_document(grades: ClassGrade) -> dict:
    """grades/results.json: the one student's document, or the class's (every student's tests)."""
    if grades.single and grades.students:
        return student_document(grades, grades.students[0])
    tests = [t for s in grades.students for t in _tests(s, prefix=f"{visible(s.name)}: ")]
    total = sum(s.score for s in grades.students)
    return {"score": _score(total),
            "output": f"{visible(grades.rubric.title)}: {len(grades.students)} students graded",
            "tests": tests,
            "extra_data": {"title": visible(grades.rubric.title), "max_score": _score(grades.rubric.max_score),
                           "students": [{"name": visible(s.name), "score": _score(s.score),
                                         "max_score": _score(s.max_score)} for s in grades.students]}}


def _json(document: dict) -> str:
    return json.dumps(document, indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def _md(text: str) -> str:
    """User text (names, equations, messages quoting them) inside Markdown: no HTML, no controls."""
    return visible(str(text), lines=True).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def feedback_md(grades: ClassGrade, student: StudentGrade) -> str:
    rubric = grades.rubric
    out = [f"# {_md(rubric.title)}: feedback for {_md(student.name)}", "",
           f"**Score: {score_text(student.score)} / {score_text(student.max_score)}**", ""]
    for note in student.notes:
        out += [f"- {_md(note)}"]
    if student.matched:
        out += ["Your experiments:", ""]
        out += [f"- {_md(e)}: {_md(how)}" for e, how in student.matched.items()]
    out.append("")
    for o in student.outcomes:
        verdict = "passed" if o.passed else "failed"
        out += [f"## {_md(o.check.name)}: {verdict} ({score_text(o.score)} / {score_text(o.check.points)})", "",
                _md(o.summary), ""]
        if not o.passed and o.differences:
            out += ["What differs in your file from the reference's:", ""]
            out += [f"- {_md(d)}" for d in o.differences]
            out.append("")
    return "\n".join(out).rstrip("\n") + "\n"


def _most_common(reasons: list[str]) -> tuple[str, int] | None:
    if not reasons:
        return None
    counts = Counter(reasons)
    return min(counts.items(), key=lambda kv: (-kv[1], kv[0]))


def class_table(grades: ClassGrade) -> dict:
    """What the HTML summary shows: the distribution of totals and, per check, passes and the commonest failure."""
    students = grades.students
    totals = Counter(score_text(s.score) for s in students)
    distribution = sorted(totals.items(), key=lambda kv: float(kv[0]))
    most = max(totals.values(), default=1)
    checks = []
    for j, check in enumerate(grades.rubric.checks):
        outcomes = [s.outcomes[j] for s in students]
        passed = sum(o.passed for o in outcomes)
        common = _most_common([o.failure or o.summary for o in outcomes if not o.passed])
        checks.append({"name": check.name, "points": score_text(check.points), "passed": passed,
                       "failed": len(outcomes) - passed,
                       "mean": score_text(sum(o.score for o in outcomes) / len(outcomes)) if outcomes else "-",
                       "common": common[0] if common else "", "common_count": common[1] if common else 0})
    mean = sum(s.score for s in students) / len(students) if students else 0.0
    return {"title": grades.rubric.title, "count": len(students), "max": score_text(grades.rubric.max_score),
            "mean": score_text(mean), "distribution": [{"score": k, "count": v, "width": round(100 * v / most)}
                                                       for k, v in distribution],
            "checks": checks,
            "students": [{"name": s.name, "total": score_text(s.score),
                          "scores": [score_text(o.score) for o in s.outcomes],
                          "passed": [o.passed for o in s.outcomes]} for s in students]}


def summary_html(grades: ClassGrade, folders: dict[str, str] | None = None) -> str:
    from jinja2 import Environment, FileSystemLoader, StrictUndefined

    env = Environment(loader=FileSystemLoader(Path(__file__).parent / "templates"), autoescape=True,
                      undefined=StrictUndefined, keep_trailing_newline=True)
    table = class_table(grades)
    folders = folders or _folders(grades)
    for row, s in zip(table["students"], grades.students):
        row["folder"] = folders[s.name]
    return env.get_template("summary.html.j2").render(**table)


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(text)
    os.replace(tmp, path)


def write_grades(grades: ClassGrade, out: Path) -> list[Path]:
    """Write the grades folder; returns the files written (summary.csv first)."""
    out = Path(out)
    folders = _folders(grades)
    written = []
    for name, text in (("summary.csv", summary_csv(grades)), ("results.json", _json(class_document(grades))),
                       ("summary.html", summary_html(grades, folders))):
        _write(out / name, text)
        written.append(out / name)
    for student in grades.students:
        folder = out / folders[student.name]
        _write(folder / "feedback.md", feedback_md(grades, student))
        _write(folder / "results.json", _json(student_document(grades, student)))
        written += [folder / "feedback.md", folder / "results.json"]
    return written
