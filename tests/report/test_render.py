"""The report's Jinja environments keep their compiled templates in the cache folder."""

from odelab.report.render import environments


def test_compiled_templates_are_kept_per_environment_and_follow_the_source(tmp_path, monkeypatch):
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path / "cache"))
    course = tmp_path / "course"
    course.mkdir()
    (course / "report.md.j2").write_text("one {{ x }}\n")
    html, md = environments(course)
    assert md.get_template("report.md.j2").render(x="|") == "one \\|\n"  # the Markdown environment's escaping
    assert html.get_template("report.html.j2").name == "report.html.j2"  # the package's, compiled and kept
    folders = sorted(p.name.split("-")[0] for p in (tmp_path / "cache" / "templates").iterdir())
    assert folders == ["html", "md"]  # one folder each: the two environments compile the same text differently
    assert any((tmp_path / "cache" / "templates").glob("md-*/__jinja2_*.cache"))

    _, md = environments(course)  # a new process would do the same: the entry is read, not compiled
    compiled = []
    monkeypatch.setattr(type(md), "compile", lambda self, *a, **k: compiled.append(a) or pytest_fail())
    assert md.get_template("report.md.j2").render(x="*") == "one \\*\n" and compiled == []

    monkeypatch.undo()
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path / "cache"))
    (course / "report.md.j2").write_text("two {{ x }}\n")  # an edited template is compiled again
    _, md = environments(course)
    assert md.get_template("report.md.j2").render(x="_a_") == "two \\_a\\_\n"


def test_a_cache_folder_that_cannot_be_written_only_costs_the_compile(tmp_path, monkeypatch):
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(blocked))
    _, md = environments()
    assert md.bytecode_cache is None
    assert md.get_template("report.md.j2").filename.endswith("report.md.j2")  # compiled, not kept


def pytest_fail():
    import pytest

    pytest.fail("compiled again")
