"""The documentation site: it builds with no warning, its key reference covers the schema, and
every TOML and Python snippet in it is checked (TOML parsed and its keys known; complete
experiment files loaded; Python run)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
import typing
from pathlib import Path

import pytest

from odelab.experiment import keyref, schema
from odelab.experiment.build import SIGNAL_KEYS
from odelab.systems.diagram.blocks import BLOCKS

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```(toml|python)[ \t]*\n(.*?)^```", re.M | re.S)
PAGES = sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts) + [ROOT / "README.md"]


def snippets(lang: str) -> list[tuple[Path, int, str]]:
    out = []
    for page in PAGES:
        text = page.read_text()
        for m in FENCE.finditer(text):
            if m.group(1) == lang:
                out.append((page, text[:m.start()].count("\n") + 1, m.group(2)))
    return out


def test_the_site_builds_with_warnings_as_errors(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-E", "-W", "--keep-going", "-q", "-b", "html",
                           str(DOCS), str(tmp_path / "html")], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-4000:]
    keys = (tmp_path / "html" / "reference" / "keys.html").read_text()
    cli = (tmp_path / "html" / "reference" / "cli.html").read_text()
    assert "solver.rtol" in keys and "RelTol" in keys and "inputs.pulse.width" in keys
    assert "odelab run" in cli and "--max-steps" in cli and "odelab explain" in cli
    gallery = (tmp_path / "html" / "gallery.html").read_text()
    shipped = sorted((ROOT / "experiments").rglob("*.toml"))  # every shipped file, networks/ too
    for toml in shipped:
        assert str(toml.relative_to(ROOT)) in gallery, toml.name
    assert gallery.count("<img") >= len(shipped)


def _schema_paths(model, prefix=""):
    from pydantic import BaseModel

    for name, info in model.model_fields.items():
        path = f"{prefix}.{info.alias or name}" if prefix else (info.alias or name)
        yield path
        for arg in (info.annotation, *typing.get_args(info.annotation)):
            if isinstance(arg, type) and issubclass(arg, BaseModel):
                yield from _schema_paths(arg, path)
            elif typing.get_origin(arg) is dict:
                value = typing.get_args(arg)[1]
                value = typing.get_args(value)[0] if typing.get_origin(value) is typing.Annotated else value
                if isinstance(value, type) and issubclass(value, BaseModel) and path != "inputs":
                    yield from _schema_paths(value, f"{path}.<name>")


def test_the_key_reference_lists_every_key_the_schema_accepts():
    listed = {e.path for e in keyref.entries()}
    missing = [p for p in _schema_paths(schema.Experiment) if p not in listed]
    assert not missing, f"keys the schema accepts but the reference omits: {missing}"
    for kind, keys in SIGNAL_KEYS.items():
        assert {f"inputs.{kind}.{k}" for k in keys} <= listed, kind
    for kind, cls in BLOCKS.items():
        assert {f"blocks.{kind}.{k}" for k in cls.KEYS} <= listed, kind
    for table in ("case", "problem", "sweep", "study", "events"):
        assert table in listed
    page = keyref.markdown()
    assert all(f"`{p}`" in page for p in listed)


def test_the_key_reference_describes_the_keys_a_student_meets_first():
    for path in ("system.states", "solver.method", "solver.rtol", "time.stop", "inputs.pulse.width",
                 "reference.solver", "events.<name>.when", "sweep.mode"):
        assert keyref.find(path).text, path


@pytest.mark.parametrize(("page", "line", "body"), snippets("toml"),
                         ids=lambda v: f"{v.relative_to(ROOT)}" if isinstance(v, Path) else str(v))
def test_every_toml_snippet_parses_and_names_only_known_keys(page, line, body):
    data = tomllib.loads(body)
    if "check" in data or "reference" in data and isinstance(data["reference"], str):
        return  # a grading rubric (docs/grading.md), not an experiment file: odelab grade checks it
    assert keyref.unknown_keys(data) == [], f"{page.name}:{line}"


def test_complete_experiment_snippets_load(tmp_path):
    from odelab.experiment.loader import load_experiments

    loaded = 0
    for page, line, body in snippets("toml"):
        data = tomllib.loads(body)
        if "system" in data and "time" in data and "function" not in data["system"]:
            path = tmp_path / f"{page.stem}-{line}.toml"
            path.write_text(body)
            assert load_experiments(path), f"{page.name}:{line}"
            loaded += 1
    assert loaded >= 3


@pytest.mark.parametrize("page", sorted({p for p, _, _ in snippets("python")}),
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_every_python_snippet_runs(page, tmp_path):
    code = "\n\n".join(body for p, _, body in snippets("python") if p == page)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]


def test_explain_prints_the_reference_entry_and_lists_the_choices():
    from typer.testing import CliRunner

    from odelab.cli import app

    runner = CliRunner()
    result = runner.invoke(app, ["explain", "inputs.pulse"])
    assert result.exit_code == 0
    assert "amplitude, period, width, delay" in result.output
    result = runner.invoke(app, ["explain", "solver.RelTol"])
    assert result.exit_code == 0 and result.output.startswith("solver.rtol")
    result = runner.invoke(app, ["explain", "inputs.vin.duty"])
    assert result.exit_code == 2
    assert "The keys of `inputs.<name>` are: type, amplitude" in result.output
    result = runner.invoke(app, ["explain", "solver.rtl"])
    assert result.exit_code == 2 and "Did you mean `solver.rtol`" in result.output
