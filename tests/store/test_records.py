"""result.json read back (store/records.py): every field a reader depends on is checked, never a KeyError later."""

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.report.collect import collect_runs

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """The PI loop of feedback_pi.toml: a diagram with [analysis] and its loop gain opened at the actuator."""
    runs = tmp_path_factory.mktemp("stored") / "runs"
    result = CliRunner().invoke(app, ["run", str(ROOT / "experiments" / "feedback_pi.toml"), "--runs", str(runs)])
    assert result.exit_code == 0, result.output
    return runs


@pytest.mark.parametrize("field", ["at", "num", "den", "text", "bode"])
def test_a_loop_entry_without_a_field_the_report_reads_is_skipped_with_its_name(stored, tmp_path, field):
    runs = tmp_path / "runs"
    shutil.copytree(stored, runs)
    folders = [f for f in (runs / "feedback_pi").iterdir() if (f / "result.json").is_file()]
    edited = None
    for folder in folders:
        record = json.loads((folder / "result.json").read_text())
        loop = record.get("extra", {}).get("analysis", {}).get("loop")
        if loop is not None:
            del loop[field]
            (folder / "result.json").write_text(json.dumps(record))
            edited = folder
            break
    assert edited is not None, "feedback_pi stores a loop gain"
    groups, warnings = collect_runs(runs)
    assert [w for w in warnings if f"`extra.analysis.loop` has no `{field}`, which odelab always writes" in w
            and str(edited) in w], warnings
    assert all(r.folder != edited for g in groups for r in g.runs)
    result = CliRunner().invoke(app, ["report", "--runs", str(runs), "--out", str(tmp_path / "report"), "--format",
                                      "md", "--jobs", "1"])
    assert result.exit_code == 0, result.output
    assert "Traceback" not in result.output and "has no `" in result.output


def test_what_odelab_writes_passes(stored):
    groups, warnings = collect_runs(stored)
    assert not warnings and groups and all(g.runs for g in groups)
