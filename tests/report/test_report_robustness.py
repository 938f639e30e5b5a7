"""Broken, hostile and failed runs; options; templates; atomic output."""

from __future__ import annotations

import re
import shutil

import pytest
from report_support import build, markdown_cells, markdown_tables, parse_html

from odelab.exceptions import InputError
from odelab.report import build_report


def test_unreadable_runs_are_skipped_with_a_warning(special_report, special_runs):
    warnings = special_report.result.warnings
    for folder in ("broken/json", "foreign/thing", "notraj/ode23", "badcsv/ode23"):
        assert any(str(special_runs / folder) in w and w.startswith("skipped") for w in warnings), folder
    assert any("not valid JSON" in w for w in warnings)
    assert any("is not an odelab result" in w for w in warnings)
    assert any("trajectory.csv" in w for w in warnings)
    # ... shown in the report's header, and the good runs are still reported
    root, errors, _ = parse_html(special_report.html)
    assert errors == []
    problems = root.find("div", id="problems").text()
    assert str(special_runs / "broken" / "json") in problems
    assert root.find("section", id="exercise1") is not None
    assert "skipped" in special_report.md and str(special_runs / "foreign" / "thing") in special_report.md


def test_failed_runs_are_listed_with_their_message(special_report):
    root, _, _ = parse_html(special_report.html)
    failed = root.find("div", id="failed").text()
    assert "failing / ode45" in failed and "max_steps = 3" in failed
    row = root.find("tr", data_experiment="failing", data_case="ode45")
    assert row.find("span", cls="status").text() == "FAILED"
    assert "1 failed" in root.find("header").text()
    assert "## Failed runs" in special_report.md and "**FAILED**" in special_report.md


def test_titles_and_case_names_are_escaped_in_html(special_report):
    html = special_report.html
    root, errors, _ = parse_html(html)
    assert errors == []
    assert "<script>alert" not in html and "<img src=x" not in html and "<b>tags</b>" not in html
    assert "&lt;script&gt;alert(&#39;title&#39;)&lt;/script&gt;" in html
    assert "&lt;img src=x onerror=alert(1)&gt;|a" in html
    # the only <script> is the report's own print helper; the only images are the embedded figures
    assert len(root.find_all("script")) == 1
    assert all(img.attrs["src"].startswith("data:image/png;base64,") for img in root.find_all("img"))
    section = root.find("section", id="hostile")
    assert re.match(r"\d+\. <script>alert\('title'\)</script> \| \*not bold\*", section.find("h2").text())


def test_titles_and_case_names_are_escaped_in_markdown(special_report):
    # fenced code (the resolved settings) shows text as it is: leave it out of the check
    md = re.sub(r"^(`{3,})toml\n.*?^\1$", "", special_report.md, flags=re.S | re.M)
    assert "```toml" in special_report.md and "```toml" not in md
    assert not re.search(r"(?<!\\)<(script|/script|img|b>|/b>)", md), "unescaped markup from a user string"
    assert r"\<script\>alert('title')\</script\> \| \*not bold\* [link\](http://example.com)" in md
    assert r"\<img src=x onerror=alert(1)\>\|a" in md
    assert r"\<b\>tags\</b\> \& ampersands \| pipes" in md
    for table in markdown_tables(md):  # an escaped | does not add a column
        assert len({len(markdown_cells(line)) for line in table}) == 1, table[:3]


def test_experiment_filter(lab_runs, tmp_path):
    report = build(lab_runs, tmp_path, experiments=["rigid_body", "no_such_experiment"])
    root, _, _ = parse_html(report.html)
    assert [s.attrs["id"] for s in root.find_all("section", cls="experiment")] == ["rigid_body"]
    assert any("no_such_experiment" in w for w in report.result.warnings)
    assert "no_such_experiment" in root.find("div", id="problems").text()



def test_a_study_is_asked_for_by_its_files_name(lab_runs, tmp_path):
    # work-precision.toml stores one record per target: work-precision_exercise1, _exercise2, _rigid_body
    report = build(lab_runs, tmp_path, experiments=["work-precision", "exercise1"])
    root, _, _ = parse_html(report.html)
    assert report.result.warnings == ()
    assert [s.attrs["id"] for s in root.find_all("section", cls="experiment")] == ["exercise1"]
    assert sorted(s.attrs["id"] for s in root.find_all("section", cls="study")) == [
        f"work-precision_{t}" for t in ("exercise1", "exercise2", "rigid_body")]
    # a name matches a study by its whole file name, never by a piece of it
    with pytest.raises(InputError, match="no stored runs of 'work'"):
        build(lab_runs, tmp_path / "piece", experiments=["work"])


@pytest.mark.parametrize("formats", [("md",), ("html",), "html", "both"])
def test_formats(lab_runs, tmp_path, formats):
    result = build_report(lab_runs, tmp_path, formats=formats, experiments=["exercise1"])
    names = {p.relative_to(tmp_path).as_posix() for p in result.paths}
    figures = {"figures/exercise1-solution.png"}  # the solution and its error, side by side
    if formats == "both":
        assert names == {"index.html", "report.md", *figures}
    elif "md" in formats:
        assert names == {"report.md", *figures}
    else:
        assert names == {"index.html"}
        assert not (tmp_path / "figures").exists()


def test_bad_arguments_are_input_errors(lab_runs, tmp_path):
    with pytest.raises(InputError, match="`formats`"):
        build_report(lab_runs, tmp_path, formats=("pdf",))
    with pytest.raises(InputError, match="`runs`"):
        build_report(tmp_path / "missing", tmp_path / "out")
    with pytest.raises(InputError, match="`template_dir`"):
        build_report(lab_runs, tmp_path, template_dir=tmp_path / "no-templates")


def test_empty_runs_folder_gives_a_report_that_says_so(tmp_path):
    (tmp_path / "runs").mkdir()
    report = build(tmp_path / "runs", tmp_path / "out")
    assert any("no stored runs" in w for w in report.result.warnings)
    assert "No stored runs to report" in report.html and "No stored runs to report" in report.md
    assert parse_html(report.html)[1] == []


def test_course_templates_replace_the_package_ones_name_by_name(lab_runs, tmp_path):
    course = tmp_path / "course"
    course.mkdir()
    (course / "report.css").write_text("/* ENGM 541 house style */ body { color: #123456; }\n")
    (course / "report.md.j2").write_text(
        "# {{ report.title }} for ENGM 541\n"
        "{% for s in sections %}\n- {{ s.title }}: {{ s.cases|length }} cases\n{% endfor %}\n")
    report = build(lab_runs, tmp_path / "out", template_dir=course, experiments=["exercise1", "rigid_body"])
    assert "ENGM 541 house style" in report.html and 'id="summary"' in report.html  # package HTML, course CSS
    assert report.md.startswith("# odelab lab report for ENGM 541")
    assert "- Exercise 1: dy/dt = cos(t), y(0) = 2: 2 cases" in report.md


def test_a_broken_template_leaves_the_previous_report_untouched(lab_runs, tmp_path):
    out = tmp_path / "out"
    first = build(lab_runs, out, experiments=["exercise1"])
    course = tmp_path / "course"
    course.mkdir()
    (course / "report.md.j2").write_text("{{ sections[0].no_such_field }}\n")
    with pytest.raises(InputError, match=r"report\.md\.j2"):
        build_report(lab_runs, out, template_dir=course, experiments=["rigid_body"])
    assert (out / "index.html").read_text(encoding="utf-8") == first.html  # rendered before anything is written
    assert (out / "report.md").read_text(encoding="utf-8") == first.md
    assert not [p for p in out.rglob("*") if p.name.startswith(".")], "temporary files left behind"


def test_report_files_are_readable_by_others(lab_runs, tmp_path):
    result = build_report(lab_runs, tmp_path, experiments=["exercise1"])
    for path in result.paths:
        assert path.stat().st_mode & 0o044 == 0o044, path


def test_a_malformed_linearisation_study_is_reported_not_fatal(lab_runs, tmp_path):
    import json

    runs = tmp_path / "runs"
    shutil.copytree(lab_runs / "nonlinear_spring", runs / "nonlinear_spring")
    path = runs / "nonlinear_spring" / "ode45" / "result.json"
    record = json.loads(path.read_text())
    record["extra"]["linearization"]["errors"] = {"y": [0.1]}  # one value for five amplitudes
    path.write_text(json.dumps(record))
    report = build(runs, tmp_path / "out")
    assert any("linearisation study cannot be shown" in w and "5 amplitudes" in w for w in report.result.warnings)
    root, errors, _ = parse_html(report.html)
    assert errors == [] and root.find("figure", id="fig-nonlinear_spring-solution") is not None


def test_same_data_gives_the_same_figures(lab_runs, tmp_path):
    a = build_report(lab_runs, tmp_path / "a", formats=("md",), experiments=["exercise1"])
    b = build_report(lab_runs, tmp_path / "b", formats=("md",), experiments=["exercise1"])
    for pa, pb in zip(sorted(p for p in a.paths if p.suffix == ".png"), sorted(p for p in b.paths if p.suffix == ".png")):
        assert pa.read_bytes() == pb.read_bytes()
    text_a = re.sub(r"Generated .*? by", "", (tmp_path / "a" / "report.md").read_text())
    text_b = re.sub(r"Generated .*? by", "", (tmp_path / "b" / "report.md").read_text())
    assert text_a == text_b


def rendered_markdown(md: str) -> str:
    """The Markdown as CommonMark with GitHub's tables renders it (markdown-it-py comes with rich)."""
    from markdown_it import MarkdownIt

    return MarkdownIt("commonmark").enable("table").render(md)


def test_markdown_renders_user_strings_as_text(special_report):
    html = rendered_markdown(special_report.md)
    assert "<script>" not in html and "<img src=x" not in html and "<b>tags</b>" not in html
    assert "&lt;script&gt;alert('title')&lt;/script&gt; | *not bold* [link](http://example.com)" in html
    assert '<a href="http://example.com"' not in html  # no link was made from the title
    assert "&lt;img src=x onerror=alert(1)&gt;|a" in html


def test_markdown_renders_every_table(lab_report):
    from report_support import markdown_tables

    html = rendered_markdown(lab_report.md)
    assert html.count("<table>") == len(markdown_tables(lab_report.md))
    assert html.count("<img ") == len(re.findall(r"!\[", lab_report.md))


def test_infinity_in_one_result_json_skips_that_run_only(lab_runs, tmp_path):
    runs = tmp_path / "runs"
    shutil.copytree(lab_runs, runs)
    path = runs / "exercise1" / "ode23" / "result.json"
    path.write_text(re.sub(r'"points": \d+', '"points": Infinity', path.read_text()))
    report = build(runs, tmp_path / "out", experiments=["exercise1"])
    assert [w for w in report.result.warnings if "Infinity" in w] == [
        f"skipped {runs / 'exercise1' / 'ode23'}: result.json holds Infinity, which odelab never writes "
        "(it stores null)"]
    assert "ode45" in report.md  # the other case of the experiment is still reported


def test_report_out_pointing_at_a_file_is_one_message(lab_runs, tmp_path):
    from typer.testing import CliRunner

    from odelab.cli import app

    target = tmp_path / "notes.txt"
    target.write_text("keep me")
    for out, shown in ((target, f"`out` '{target}' is a file, not a folder"),
                       (target / "report", f"`out` '{target / 'report'}' is inside '{target}', which is a file")):
        result = CliRunner().invoke(app, ["report", "--runs", str(lab_runs), "--out", str(out), "exercise1"])
        assert result.exit_code == 2, result.output
        assert shown in result.output and "give a folder for the report" in result.output
        assert "Traceback" not in result.output
    assert target.read_text() == "keep me"


def test_report_on_a_full_disk_is_one_message(lab_runs, tmp_path, monkeypatch):
    import odelab.report.build as report_build

    def full(path, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(report_build, "atomic_write", full)
    with pytest.raises(InputError, match=r"^`out`: cannot write .*index\.html: No space left on device; free some "
                                         r"space or give another folder with --out"):
        build_report(lab_runs, tmp_path / "out", formats="html", experiments=["exercise1"])


def test_report_accepts_experiment_files_and_refuses_to_empty_itself(lab_runs, tmp_path):
    """`odelab report pendulum.toml`: a file stands for its experiment; no match leaves the report alone."""
    from typer.testing import CliRunner

    from odelab.cli import app

    out = tmp_path / "report"
    runner = CliRunner()
    ok = runner.invoke(app, ["report", "experiments/exercise1.toml", "--runs", str(lab_runs), "--out", str(out)])
    assert ok.exit_code == 0, ok.output
    html = (out / "index.html").read_text()
    assert 'id="exercise1"' in html and 'id="rigid_body"' not in html
    before = html
    (out / "figures" / "old-figure.png").write_bytes(b"\x89PNG stale")
    bad = runner.invoke(app, ["report", "pendulum.toml", "--runs", str(lab_runs), "--out", str(out)])
    assert bad.exit_code == 2
    assert "no stored runs of 'pendulum'" in bad.output and "was left as it was" in bad.output
    assert (out / "index.html").read_text() == before
    # a report that no longer shows a figure removes it from figures/
    again = runner.invoke(app, ["report", "exercise1", "--runs", str(lab_runs), "--out", str(out)])
    assert again.exit_code == 0
    assert sorted(p.name for p in (out / "figures").iterdir()) == ["exercise1-solution.png"]
