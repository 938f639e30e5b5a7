"""The experiment file's JSON Schema (editor support, issue 37): generated from the key reference, shipped,
and right about every file the project ships."""

import json
import re
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.experiment.jsonschema import experiment_schema, schema_text, shipped_path
from odelab.experiment.keyref import find

jsonschema = pytest.importorskip("jsonschema")
ROOT = Path(__file__).resolve().parents[2]


def test_the_shipped_schema_is_the_generated_one():
    assert shipped_path().read_text(encoding="utf-8") == schema_text(), (
        "src/odelab/schemas/experiment.schema.json is out of date: run "
        "`odelab schema -o src/odelab/schemas/experiment.schema.json`")


def _documents():
    files = [*ROOT.glob("experiments/**/*.toml"), *ROOT.glob("src/odelab/templates/*.toml"),
             *ROOT.glob("examples/grading/reference/*.toml"), *ROOT.glob("examples/grading/submissions/*/*.toml")]
    for path in files:
        yield path.relative_to(ROOT).as_posix(), path.read_text(encoding="utf-8")
    for page in [*ROOT.glob("docs/**/*.md"), ROOT / "README.md"]:
        for i, text in enumerate(re.findall(r"^```toml[ \t]*\n(.*?)^```", page.read_text(encoding="utf-8"), re.M | re.S)):
            yield f"{page.relative_to(ROOT).as_posix()}#{i}", text


def test_every_file_and_snippet_the_project_ships_is_valid():
    validator = jsonschema.Draft7Validator(experiment_schema())
    checked = 0
    for name, text in _documents():
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError:
            continue  # a snippet showing a mistake
        if "check" in data or "submissions" in data or "broken" in name:
            continue  # a grading rubric, a broken submission
        errors = [f"{e.json_path}: {e.message}" for e in validator.iter_errors(data)]
        assert not errors, f"{name}: {errors[:3]}"
        checked += 1
    assert checked >= 60


def test_a_typo_is_flagged_and_each_key_carries_its_reference_entry():
    schema = experiment_schema()
    validator = jsonschema.Draft7Validator(schema)
    typo = tomllib.loads('[system]\nstates = ["y"]\n[system.equations]\ny = "-y"\n[initial]\ny = 1\n[time]\nstop = 1\nstp = 2\n')
    (error,) = validator.iter_errors(typo)
    assert error.json_path == "$.time" and "'stp' was unexpected" in error.message
    rtol = schema["properties"]["solver"]["properties"]["rtol"]
    assert rtol["type"] == "number" and find("solver.rtol").text in rtol["description"] and "RelTol" in rtol["description"]
    assert schema["properties"]["solver"]["properties"]["RelTol"]["description"].startswith("MATLAB's name for `rtol`.")
    kind = schema["properties"]["system"]["properties"]["kind"]
    assert kind["enum"][:3] == ["ode", "state-space", "diagram"]
    ode45 = tomllib.loads('[system]\nstates = ["y"]\n[system.equations]\ny = "-y"\n[initial]\ny = 1\n[time]\nstop = 1\n'
                          '[solver]\nmethod = "ODE45"\nRelTol = 1e-4\n[events.e]\nwhen = "y - 0.5"\ndirection = -1\n')
    assert not list(validator.iter_errors(ode45))  # what the loader takes, the schema takes


def test_odelab_schema_prints_it_and_new_files_point_at_it(tmp_path):
    result = CliRunner().invoke(app, ["schema"])
    assert result.exit_code == 0 and json.loads(result.output) == experiment_schema()
    assert CliRunner().invoke(app, ["new", str(tmp_path / "lab.toml")]).exit_code == 0
    first = (tmp_path / "lab.toml").read_text().splitlines()[0]
    assert first.startswith("#:schema file://") and first.endswith("/odelab/schemas/experiment.schema.json")
    assert Path(first.removeprefix("#:schema file://")).is_file()
    out = tmp_path / "schema.json"
    assert CliRunner().invoke(app, ["schema", "-o", str(out)]).exit_code == 0 and out.read_text() == schema_text()
