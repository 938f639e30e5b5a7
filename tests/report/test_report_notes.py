"""[report]: an experiment file sets its section's place and note; the report never reads an experiment's name."""

from __future__ import annotations

from report_support import build, parse_html

from odelab.experiment.loader import load_experiment

BASE = """
title = "{title}"
[system]
states = ["y"]
[system.equations]
y = "-y"
[initial]
y = 1
[time]
stop = {stop}
[exact]
y = "exp(-t)"
[solver]
method = "ode23"
[[case]]
name = "fast"
solver.method = "ode45"
[[case]]
name = "slow"
"""


def _run(tmp_path, files: dict[str, str]):
    from typer.testing import CliRunner

    from odelab.cli import app

    paths = []
    for name, text in files.items():
        path = tmp_path / f"{name}.toml"
        path.write_text(text)
        paths.append(str(path))
    result = CliRunner().invoke(app, ["run", *paths, "--runs", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    return build(tmp_path / "runs", tmp_path / "out", jobs=1)


def test_sections_follow_report_order_and_the_note_quotes_the_named_runs(tmp_path):
    report = _run(tmp_path, {
        # alphabetically first, but ordered last of the two
        "alpha": BASE.format(title="Alpha", stop=1) + "[report]\norder = 2\n",
        "zulu": BASE.format(title="Zulu", stop=2) + (
            '[report]\norder = 1\nnote = "**Decay** is quoted from the runs."\n'
            'quote = ["zulu/slow", "alpha/slow", "missing/slow"]\n'),
    })
    tree, _, _ = parse_html(report.html)
    order = [s.attrs["id"] for s in tree.find_all("section", cls="experiment")]
    assert order == ["zulu", "alpha"]
    note = tree.find("section", id="zulu").find("div", cls="lab-note")
    assert note.find("strong").text() == "Decay"
    text = " ".join(note.text().split())
    assert "Decay is quoted from the runs. From the stored runs, the maximum relative error of ode23 is" in text
    assert " on [0, 2] with " in text and " on [0, 1] with " in text
    assert "No successful slow run of missing is stored" in text
    assert tree.find("section", id="alpha").find("div", cls="lab-note") is None
    assert "> **Decay** is quoted from the runs. From the stored runs" in report.md


def test_a_quote_that_names_no_case_is_a_load_error(tmp_path):
    import pytest

    from odelab.exceptions import ExperimentError

    path = tmp_path / "bad.toml"
    path.write_text(BASE.format(title="Bad", stop=1) + '[report]\nnote = "n"\nquote = ["exercise1"]\n')
    with pytest.raises(ExperimentError) as info:
        load_experiment(path)
    assert info.value.key == "report.quote[0]"
    assert "name a stored case as \"experiment/case\"" in str(info.value)
