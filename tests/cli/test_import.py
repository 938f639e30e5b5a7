"""`odelab import` and `odelab run` on MATLAB files: the written file, the table, the exit codes."""

import json
import shutil
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from odelab.cli import app

ROOT = Path(__file__).resolve().parents[2]
LAB = ROOT / "tests" / "assets" / "matlab" / "lab"
runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_import_writes_the_experiment_file_prints_the_table_and_exits_0(tmp_path):
    result = invoke("import", LAB / "run_rigid.m", "-o", tmp_path)
    assert result.exit_code == 0, result.output
    written = tmp_path / "run_rigid.toml"
    text = written.read_text()
    assert text.startswith("# Imported from run_rigid.m by `odelab import`")
    assert 'y3 = "-0.51*y1*y2"' in text and "atol = [0.0001, 0.0001, 1e-05]" in text
    assert "# line 3: [T,Y] = ode45(@rigid,[0 12],[0 1 1],options);" in text
    out = result.output
    assert f"run_rigid.toml: 2 translated, 1 ignored, everything translated" in out.replace("\n", " ").replace(
        str(tmp_path) + "/", "")
    assert "rigid.m:1" in out and "plotting: the report draws" in out
    stored = tmp_path / "runs"
    ran = invoke("run", "--json", "--runs", stored, written)
    ran_m = invoke("run", "--json", "--runs", tmp_path / "runs_m", LAB / "run_rigid.m")
    assert ran.exit_code == 0 and ran_m.exit_code == 0
    a = json.loads(ran.stdout)["experiments"][0]["cases"][0]
    b = json.loads(ran_m.stdout)["experiments"][0]["cases"][0]
    assert (a["stats"], a["points"]) == (b["stats"], b["points"]) == ({"nsteps": 21, "nfailed": 0, "nfevals": 127},
                                                                     85)


def test_a_function_file_alone_is_written_with_gaps_and_exit_1_then_call_completes_it(tmp_path):
    result = invoke("import", LAB / "eq1.m", "-o", tmp_path)
    assert result.exit_code == 1
    assert "1 gap: fill it in before it runs" in result.output
    assert "# GAP: eq1.m has no solver call" in (tmp_path / "eq1.toml").read_text()
    result = invoke("import", LAB / "eq1.m", "-o", tmp_path, "--call", "[t,y] = ode23(@eq1, [0 pi], 2)")
    assert result.exit_code == 0, result.output
    text = (tmp_path / "eq1.toml").read_text()
    assert 'method = "ode23"' in text and 'stop = "pi"' in text and "y = 2" in text
    ran = invoke("run", "--no-store", "--json", LAB / "eq1.m", "--call", "[t,y] = ode23(@eq1, [0 pi], 2)")
    assert ran.exit_code == 0
    assert json.loads(ran.stdout)["experiments"][0]["cases"][0]["stats"]["nsteps"] == 11


def test_run_of_a_function_file_alone_names_its_gaps_and_exits_2(tmp_path):
    result = invoke("run", "--no-store", LAB / "eq1.m")
    assert result.exit_code == 2
    assert "could not be translated completely (1 gap): line 1: function eq1: no solver call" in result.output
    assert "`odelab import eq1.m`" in result.output


def test_import_refuses_unusable_files_with_exit_2_and_writes_nothing(tmp_path):
    junk = tmp_path / "junk.m"
    junk.write_bytes(bytes(range(256)) * 8)
    hostile = tmp_path / "hostile.m"
    hostile.write_text("k = 2;\nsystem('touch pwned')\n[t,y] = ode45(@(t,y) -k*y, [0 1], 1);\n")
    result = invoke("import", junk, hostile, "-o", tmp_path / "out")
    assert result.exit_code == 2
    assert "junk.m: is a binary file, not MATLAB source text" in result.output
    assert "hostile.m: line 2: `system` runs a shell command" in result.output
    assert not (tmp_path / "out").exists() and not (tmp_path / "pwned").exists()


def test_import_will_not_replace_a_file_it_did_not_write(tmp_path):
    shutil.copy(LAB / "rigid.m", tmp_path)
    shutil.copy(LAB / "run_rigid.m", tmp_path)
    (tmp_path / "run_rigid.toml").write_text("# my own experiment\n")
    result = invoke("import", tmp_path / "run_rigid.m")
    assert result.exit_code == 2 and "exists and was not written by `odelab import`" in result.output
    assert (tmp_path / "run_rigid.toml").read_text() == "# my own experiment\n"
    assert invoke("import", tmp_path / "run_rigid.m", "--force").exit_code == 0
    assert invoke("import", tmp_path / "run_rigid.m").exit_code == 0  # its own file: replaced


def test_set_and_workspace_reach_the_reader(tmp_path):
    (tmp_path / "params.m").write_text("k = 2;\n")
    (tmp_path / "decay.m").write_text("[t, y] = ode45(@(t, y) -k*y, [0 1], 1);\n")
    result = invoke("import", tmp_path / "decay.m", "--workspace", tmp_path / "params.m", "-o", tmp_path)
    assert result.exit_code == 0, result.output
    assert "k = 2\n" in (tmp_path / "decay.toml").read_text()
    result = invoke("import", tmp_path / "decay.m", "--workspace", tmp_path / "params.m", "--set", "k=5",
                    "-o", tmp_path)
    assert "k = 5\n" in (tmp_path / "decay.toml").read_text()
    bad = invoke("run", "--no-store", tmp_path / "decay.m", "--set", "k")
    assert bad.exit_code == 2 and "`--set k`: write NAME=VALUE" in bad.output
    ran = invoke("run", "--no-store", "--json", "--trajectories", tmp_path / "decay.m", "--workspace",
                 tmp_path / "params.m")
    traj = json.loads(ran.stdout)["experiments"][0]["cases"][0]["trajectory"]
    assert abs(traj["y"][-1] - np.exp(-2.0)) < 1e-3 * np.exp(-2.0) * 10
