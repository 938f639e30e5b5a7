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


def test_a_cache_folder_that_cannot_be_used_falls_back_to_a_private_one(tmp_path, monkeypatch):
    from odelab.cachedir import take_notes

    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(blocked))
    take_notes()
    _, md = environments()
    folder = md.bytecode_cache.folder  # a private temporary cache (odelab.cachedir), mode 0700
    assert not str(folder).startswith(str(blocked)) and (folder.parent.parent.stat().st_mode & 0o777) == 0o700
    assert md.get_template("report.md.j2").filename.endswith("report.md.j2")
    assert blocked.read_text() == "not a folder"
    assert any("is a file, not a folder" in n and "private temporary cache" in n for n in take_notes())


def pytest_fail():
    import pytest

    pytest.fail("compiled again")
