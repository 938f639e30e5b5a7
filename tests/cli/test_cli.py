"""The CLI through typer's CliRunner: exit codes, messages, JSON shape, the bad-file corpus."""

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab.cli import app

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENTS = ROOT / "experiments"
BAD = sorted((ROOT / "tests" / "assets" / "bad").glob("*.toml"))

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def expected_message(path: Path) -> str:
    first = path.read_text().splitlines()[0]
    assert first.startswith("# expect: "), f"{path.name} must start with '# expect: <message>'"
    return first[len("# expect: "):]


def corpus_header(path: Path) -> tuple[str, int, list[str], str | None]:
    """A corpus file's expected message fragment, exit code, extra `odelab run` arguments and
    text that must not appear: ``# expect: <fragment>``, then optionally ``# exit: 1`` (an
    honest failure: a stored failed case), ``# args: --limit states=50`` (tight budgets keep
    the corpus fast) and ``# absent: root:`` (content of a file that must not be quoted)."""
    code, args, absent = 2, [], None
    for line in path.read_text().splitlines()[1:5]:
        if line.startswith("# exit: "):
            code = int(line[len("# exit: "):])
        elif line.startswith("# args: "):
            args = line[len("# args: "):].split()
        elif line.startswith("# absent: "):
            absent = line[len("# absent: "):]
    return expected_message(path), code, args, absent


def test_version_and_help():
    result = invoke("--version")
    assert result.exit_code == 0 and result.output.startswith("odelab 0.")
    result = invoke("--help")
    assert result.exit_code == 0
    for command in ("run", "validate", "new", "solvers"):
        assert command in result.output


def test_help_shows_readable_metavars_not_python_types():
    result = runner.invoke(app, ["run", "--help"], terminal_width=100)
    assert result.exit_code == 0
    usage, *rest = [line.strip() for line in result.output.splitlines() if line.strip()]
    assert usage.endswith("run [OPTIONS] FILES...")
    assert "FILES...  Experiment files or folders of them.  [required]" in rest
    for option in ("--runs FOLDER", "--max-steps N", "--limit NAME=N", "--jobs N", "--executor NAME",
                   "--scheduler ADDRESS", "--backend NAME"):
        assert any(line.startswith(option) or f", {option}" in line for line in rest), option
    report = runner.invoke(app, ["report", "--help"], terminal_width=100).output
    assert "report [OPTIONS] [EXPERIMENTS...]" in report and "--out FOLDER" in report
    for text in (result.output, report, runner.invoke(app, ["validate", "--help"]).output,
                 runner.invoke(app, ["new", "--help"]).output):
        assert "<" not in text and "list[" not in text, text
    missing = runner.invoke(app, ["run"])
    assert missing.exit_code == 2 and "Missing argument 'FILES...'" in missing.output


def test_run_exercise1_prints_the_lab_numbers(tmp_path):
    result = invoke("run", EXPERIMENTS / "exercise1.toml", "--runs", tmp_path / "runs")
    assert result.exit_code == 0, result.output
    lines = {line.split()[0]: line.split() for line in result.output.splitlines() if line.startswith("ode")}
    # case method points steps failed fevals quantity max-abs max-rel status
    assert lines["ode23"][1:6] == ["ode23", "12", "11", "0", "34"] and lines["ode23"][8] == "1.068e-04"
    assert lines["ode45"][1:6] == ["ode45", "41", "10", "0", "61"] and lines["ode45"][8] == "1.187e-07"
    for case in ("ode23", "ode45"):
        folder = tmp_path / "runs" / "exercise1" / case
        assert sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")) == [
            "resolved.toml", "result.json", "trajectory.csv"]


def test_run_folder_json_shape(tmp_path):
    result = invoke("run", EXPERIMENTS, "--runs", tmp_path / "runs", "--json")
    doc = json.loads(result.output)
    names = [e["name"] for e in doc["experiments"]]
    # stiff.toml's ode45 case is stopped by its step limit on purpose (it shows why stiff solvers
    # exist) and says so (expect = "max-steps"): stored as failed, expected, and the run exits 0;
    # every other shipped case succeeds
    failed = [(e["name"], c["name"], c.get("expected")) for e in doc["experiments"] for c in e["cases"]
              if c["status"] != "success"]
    assert result.exit_code == 0 and failed == [("stiff", "ode45", True)], result.output
    assert {"exercise1", "exercise1_2pi", "rigid_body"} <= set(names)
    exp = doc["experiments"][names.index("exercise1_2pi")]
    assert exp["title"].startswith("Exercise 1 over [0, 2 pi]")
    case = exp["cases"][0]
    for key in ("name", "method", "status", "message", "points", "stats", "max_abs_error", "max_rel_error"):
        assert key in case
    assert [c["name"] for c in exp["cases"]] == ["ode23", "ode45"]
    assert case["points"] == 17 and f"{case['max_rel_error']['y']:.3e}" == "6.907e-04"
    assert case["stats"] == {"nsteps": 16, "nfailed": 2, "nfevals": 55}
    rigid = doc["experiments"][names.index("rigid_body")]["cases"][0]
    assert rigid["stats"] == {"nsteps": 21, "nfailed": 0, "nfevals": 127} and rigid["points"] == 85
    assert set(rigid["max_rel_error"]) == {"y1", "y2", "y3"}


def test_headline_rule_is_the_same_in_the_terminal_json_and_result_json(tmp_path):
    """Exercise 2's sine input: y ~ 4e-4 at t = 0.027 makes the pointwise maximum 2.8e-2; the
    headline is the error relative to y's peak (3.3), 3.682e-05, marked "of peak"."""
    result = invoke("run", EXPERIMENTS / "exercise2.toml", "--runs", tmp_path / "runs")
    assert result.exit_code == 0, result.output
    row = next(line for line in result.output.splitlines() if line.startswith("sine-ode45"))
    assert "9.093e-06" not in row and "3.682e-05 of peak" in row
    assert "2.8e-02 at t = 0.0271 (|f| = 6.4e-07)" in row  # x's pointwise maximum, where and how small |f| was
    assert "where the reference nears zero it is max |f - y| / max |f|, marked 'of peak'" in " ".join(
        result.output.split())
    record = json.loads((tmp_path / "runs" / "exercise2" / "sine-ode45" / "result.json").read_text())
    assert f"{record['rel_error']['y']:.3e}" == "3.682e-05" and record["rel_basis"]["y"] == "peak"
    assert f"{record['max_rel_error']['y']:.3e}" == "2.801e-02"  # the lab's pointwise maximum, kept
    e = record["errors"]["y"]
    assert e["rel_error"] == record["rel_error"]["y"] == e["max_abs"] / e["scale"]
    assert f"{e['t_max_rel']:.4f}" == "0.0271" and e["ref_at_max_rel"] < 1e-4
    doc = json.loads(invoke("run", EXPERIMENTS / "exercise2.toml", "--no-store", "--json").output)
    case = next(c for c in doc["experiments"][0]["cases"] if c["name"] == "sine-ode45")
    assert case["rel_error"] == record["rel_error"] and case["rel_error_rule"] == record["rel_error_rule"]


def test_exercise1_headline_is_the_labs_number(tmp_path):
    doc = json.loads(invoke("run", EXPERIMENTS / "exercise1.toml", EXPERIMENTS / "exercise1_2pi.toml",
                            "--no-store", "--json").output)
    ode23 = [next(c for c in e["cases"] if c["name"] == "ode23") for e in doc["experiments"]]
    assert [f"{c['rel_error']['y']:.3e}" for c in ode23] == ["1.068e-04", "6.907e-04"]
    assert [c["rel_basis"]["y"] for c in ode23] == ["pointwise", "pointwise"]


def test_table_prints_every_point(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = invoke("run", EXPERIMENTS / "exercise1.toml", "--no-store", "--table")
    assert result.exit_code == 0
    assert "ode23: y at each output point" in result.output
    assert result.output.count("1.068e-04") >= 2  # in the summary and at its point in the table
    assert not (tmp_path / "runs").exists()  # --no-store writes nothing


def test_resolved_toml_reproduces_the_case(tmp_path):
    invoke("run", EXPERIMENTS / "rigid_body.toml", "--runs", tmp_path / "a")
    resolved = tmp_path / "a" / "rigid_body" / "ode45" / "resolved.toml"
    again = invoke("run", resolved, "--runs", tmp_path / "b", "--json")
    assert again.exit_code == 0, again.output
    first = json.loads((tmp_path / "a" / "rigid_body" / "ode45" / "result.json").read_text())
    second = json.loads(again.output)["experiments"][0]["cases"][0]
    assert second["stats"] == first["stats"] and second["max_abs_error"] == first["max_abs_error"]


def test_failed_integration_exits_1_and_keeps_partial_results(tmp_path):
    exp = tmp_path / "blowup.toml"
    exp.write_text('[system]\nstates = ["y"]\n[system.equations]\ny = "y^2"\n[initial]\ny = 1\n'
                   '[time]\nstop = 2\n[exact]\ny = "1/(1 - t)"\n')
    result = invoke("run", exp, "--runs", tmp_path / "runs")
    assert result.exit_code == 1
    assert "FAILED" in result.output and "step size fell below" in result.output
    record = json.loads((tmp_path / "runs" / "blowup" / "ode45" / "result.json").read_text())
    assert record["status"] == "failed" and record["points"] > 10


@pytest.mark.parametrize("path", BAD, ids=lambda p: p.stem)
def test_bad_file_gives_one_clear_message_and_exit_2(path, tmp_path):
    """Exit 2 with one clear message and nothing stored; or (``# exit: 1``) an honest failure:
    the message, and a stored failed case with its partial result. Never a traceback, never a
    raw control character."""
    import re

    runs = tmp_path / "runs"
    message, code, args, absent = corpus_header(path)
    result = invoke("run", path, "--runs", runs, *args)
    assert result.exit_code == code, result.output
    assert message in result.output or " ".join(message.split()) in " ".join(result.output.split())  # wrapped
    assert absent is None or absent not in result.output
    assert "Traceback" not in result.output and result.exception is None or isinstance(result.exception, SystemExit)
    assert not re.search("[\x00-\x08\x0b-\x1f\x7f]", result.output), result.output
    if code == 2:
        assert path.name in result.output
        assert not runs.exists() or not any(runs.rglob("*.json"))
    else:
        records = [json.loads(p.read_text()) for p in runs.rglob("result.json")]
        assert records and all(r["status"] == "failed" and r["points"] >= 1 for r in records), records
    assert len(result.output) < 2000, len(result.output)  # a message, not a listing


def test_special_bad_inputs(tmp_path):
    (tmp_path / "empty.toml").write_text("")
    (tmp_path / "binary.toml").write_bytes(b"\x00\x01\x02title")
    (tmp_path / "latin1.toml").write_bytes("title = 'caf\xe9'".encode("latin-1"))
    (tmp_path / "folder").mkdir()
    cases = {
        "empty.toml": "is empty; an experiment needs at least [system], [initial] and [time]",
        "binary.toml": "is a binary file, not a TOML text file",
        "latin1.toml": "is not UTF-8 text",
        "folder": "is a folder with no *.toml experiment files in it",
        "missing.toml": "no such file or folder",
    }
    for name, message in cases.items():
        result = invoke("run", tmp_path / name, "--runs", tmp_path / "runs")
        assert result.exit_code == 2, name
        assert message in result.output, (name, result.output)
        assert "Traceback" not in result.output


def test_a_bad_file_does_not_stop_the_others(tmp_path):
    shutil.copy(EXPERIMENTS / "exercise1.toml", tmp_path / "good.toml")
    shutil.copy(ROOT / "tests" / "assets" / "bad" / "rtol_negative.toml", tmp_path / "bad.toml")
    result = invoke("run", tmp_path, "--runs", tmp_path / "runs")
    assert result.exit_code == 2
    assert "1.068e-04" in result.output
    assert (tmp_path / "runs" / "good" / "ode23" / "result.json").exists()


def test_validate(tmp_path):
    result = invoke("validate", EXPERIMENTS)
    assert result.exit_code == 0
    assert "ok: " in result.output and "(2 cases: ode23, ode45)" in result.output
    result = invoke("validate", ROOT / "tests" / "assets" / "bad" / "unknown_method.toml")
    assert result.exit_code == 2 and "Did you mean 'ode45'?" in result.output


@pytest.mark.parametrize("kind", ["ode", "state-space", "python", "diagram", "network", "sweep", "study"])
def test_new_writes_a_starter_that_runs(kind, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = invoke("new", "exp.toml", "--kind", kind)
    assert result.exit_code == 0, result.output
    assert "wrote exp.toml" in result.output
    ran = invoke("run", "exp.toml", "--runs", "runs")
    assert ran.exit_code == 0, ran.output
    again = invoke("new", "exp.toml", "--kind", kind)
    assert again.exit_code == 2 and "exists; choose another name or pass --force" in again.output


def test_new_rejects_unknown_kind(tmp_path):
    result = invoke("new", tmp_path / "x.toml", "--kind", "pde")
    assert result.exit_code == 2 and "choose one of ode, state-space, diagram, network, python, sweep, study" in result.output


def test_solvers_lists_every_method():
    result = invoke("solvers")
    assert result.exit_code == 0
    for name in ("ode23", "ode45", "ode15s", "ode23s", "ode23t", "ode23tb", "ode113", "ode78", "ode89", "euler",
                 "heun", "midpoint", "ralston", "rk3", "rk4", "RK45", "LSODA"):
        assert name in result.output
    rows = {line.split("│")[1].strip(): [c.strip() for c in line.split("│")[2:]]
            for line in result.output.splitlines() if line.startswith("│") and line.split("│")[1].strip()}
    assert rows["ode15s"][:2] == ["stiff, DAE", "1-5"] and rows["ode45"][:2] == ["non-stiff", "5(4)"]
    assert rows["LSODA"][1].startswith("Adams 1-12") and rows["ode23s"][:2] == ["stiff", "2(3)"]
    assert rows["ode78"][:2] == ["non-stiff", "8(7)"] and rows["ode89"][:2] == ["non-stiff", "9(8)"]
    assert rows["ode113"][:2] == ["non-stiff", "1-13"] and rows["ode113"][2].startswith("rtol 1e-3, atol 1e-6, refine 1")
    assert rows["ode78"][2].startswith("rtol 1e-3, atol 1e-6, refine 1")
    assert rows["ode23t"][:2] == ["stiff, DAE", "2"] and rows["ode23tb"][:2] == ["stiff", "2(3)"]


def test_function_system_runs_the_users_file(tmp_path):
    (tmp_path / "eq1.py").write_text("import math\n\ndef eq1(t, y):\n    return math.cos(t)\n")
    (tmp_path / "exp.toml").write_text('[system]\nstates = ["y"]\nfunction = "eq1.py:eq1"\n[initial]\ny = 2\n'
                                       '[time]\nstop = "pi"\n[exact]\ny = "sin(t) + 2"\n[solver]\nmethod = "ode23"\n')
    result = invoke("run", tmp_path / "exp.toml", "--runs", tmp_path / "runs", "--json")
    assert result.exit_code == 0, result.output
    case = json.loads(result.output)["experiments"][0]["cases"][0]
    assert case["points"] == 12 and f"{case['max_rel_error']['y']:.3e}" == "1.068e-04"


def _modules_after(*args) -> set[str]:
    import subprocess
    import sys

    code = ("import sys\nfrom odelab.cli import app\ntry:\n    app(%r)\nexcept SystemExit:\n    pass\n"
            "print(' '.join(m for m in ('numpy', 'scipy', 'matplotlib', 'pydantic', 'rich.progress', 'rich.table') "
            "if m in sys.modules))" % (list(args),))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    return set(out.split("\n")[-2].split())


def test_help_imports_neither_numpy_scipy_nor_matplotlib():
    assert _modules_after("--help") == set()


def test_exercise1_run_imports_neither_scipy_nor_matplotlib(tmp_path):
    loaded = _modules_after("run", str(EXPERIMENTS / "exercise1.toml"), "--runs", str(tmp_path))
    assert "numpy" in loaded and "scipy" not in loaded and "matplotlib" not in loaded
    assert "rich.progress" not in loaded  # no progress bar when the output is not a terminal


def test_mat_export_loads_in_scipy(tmp_path):
    from scipy.io import loadmat

    result = invoke("run", EXPERIMENTS / "rigid_body.toml", "--runs", tmp_path, "--mat")
    assert result.exit_code == 0
    data = loadmat(tmp_path / "rigid_body" / "ode45" / "result.mat")
    assert data["t"].shape == (85, 1) and data["x"].shape == (85, 3)
    assert data["ref_y3"].shape == (85, 1)


def test_names_cannot_escape_the_results_folder(tmp_path):
    text = (EXPERIMENTS / "exercise1.toml").read_text()
    text = 'name = "../../escaped"\n' + text.replace('name = "ode23"', 'name = "/etc/passwd"').replace(
        'name = "ode45"', 'name = "a\\u0000b/../../c"')
    (tmp_path / "work").mkdir()
    (tmp_path / "work" / "exp.toml").write_text(text)
    result = invoke("run", tmp_path / "work" / "exp.toml", "--runs", tmp_path / "work" / "runs")
    assert result.exit_code == 0, result.output
    runs = (tmp_path / "work" / "runs").resolve()
    written = [p for p in tmp_path.rglob("*") if p.is_file() and p.name != "exp.toml"]
    assert written and all(runs in p.resolve().parents for p in written)
    assert sorted(p.parent.relative_to(runs).as_posix() for p in runs.rglob("result.json")) == [
        "escaped/ab-..-..-c", "escaped/etc-passwd"]


@pytest.mark.parametrize("first, second", [("run A", "run/A"), (".", ".."), ("x" * 80 + "1", "x" * 80 + "2"),
                                           ("Lab", "lab")])
def test_experiments_sharing_a_results_folder_are_refused(tmp_path, first, second):
    """Issue 15, class 2: the second file would overwrite the first's cases and exit 0."""
    text = (EXPERIMENTS / "exercise1.toml").read_text()
    (tmp_path / "a.toml").write_text(f"name = {json.dumps(first)}\n" + text)
    (tmp_path / "b.toml").write_text(f"name = {json.dumps(second)}\n" + text)
    result = invoke("run", tmp_path, "--runs", tmp_path / "runs")
    assert result.exit_code == 2, result.output
    b = tmp_path / "b.toml"
    assert f"{b}: experiment is named {second!r}, which would be stored in the same results folder" in result.output
    assert f"as {first!r} from {tmp_path / 'a.toml'}, overwriting its cases: give this file its own `name`" in result.output
    assert "1.068e-04" in result.output  # the first file ran
    records = [json.loads(p.read_text()) for p in (tmp_path / "runs").rglob("result.json")]
    assert {r["experiment"] for r in records} == {first}
    validate = invoke("validate", tmp_path)
    assert validate.exit_code == 2 and "would be stored in the same results folder" in validate.output


def test_two_files_with_the_same_name_are_refused(tmp_path):
    text = 'name = "lab"\n' + (EXPERIMENTS / "exercise1.toml").read_text()
    (tmp_path / "a.toml").write_text(text)
    (tmp_path / "b.toml").write_text(text)
    result = invoke("run", tmp_path, "--no-store")
    assert result.exit_code == 2
    assert (f"{tmp_path / 'b.toml'}: experiment is also named 'lab' and would be stored in the same results folder 'lab' "
            f"as 'lab' from {tmp_path / 'a.toml'}") in result.output


def test_backend_option_says_which_engine_ran(tmp_path):
    result = invoke("run", EXPERIMENTS / "rigid_body.toml", "--runs", tmp_path, "--backend", "compiled")
    assert result.exit_code == 0, result.output
    assert "ode45 (compiled)" in result.output
    record = json.loads((tmp_path / "rigid_body" / "ode45" / "result.json").read_text())
    assert record["backend"] == "compiled" and record["stats"] == {"nsteps": 21, "nfailed": 0, "nfevals": 127}
    assert json.loads(invoke("run", EXPERIMENTS / "rigid_body.toml", "--no-store", "--json").output)[
        "experiments"][0]["cases"][0]["backend"] == "python"  # auto: a lab-sized run stays on Python
    bad = invoke("run", EXPERIMENTS / "rigid_body.toml", "--no-store", "--backend", "numba")
    assert bad.exit_code == 2 and "`--backend` is 'numba'; use auto, python or compiled." in bad.output


def test_json_trajectories_are_there_when_asked_and_never_dropped_silently():
    plain = json.loads(invoke("run", EXPERIMENTS / "exercise1.toml", "--no-store", "--json").output)
    assert "trajectory" not in plain["experiments"][0]["cases"][0]
    for flag in ("--trajectories", "--table"):
        doc = json.loads(invoke("run", EXPERIMENTS / "exercise1.toml", "--no-store", "--json", flag).output)
        case = doc["experiments"][0]["cases"][0]
        traj = case["trajectory"]
        assert case["name"] == "ode23" and len(traj["t"]) == 12 == case["points"]
        assert set(traj) == {"t", "y", "y_ref", "y_abs_err", "y_rel_err"}
        assert f"{max(traj['y_rel_err']):.3e}" == "1.068e-04"


def test_a_linearised_system_without_inputs_prints_its_empty_b_as_matlab_builds_it(tmp_path):
    path = tmp_path / "pendulum.toml"
    path.write_text('[system]\nstates = ["th", "w"]\n[system.equations]\nth = "w"\nw = "-9.81*sin(th) - 0.1*w"\n'
                    '[time]\nstop = 2\n[initial]\nth = 0.01\nw = 0\n[linearize]\nstart = "initial"\n')
    result = runner.invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs")], env={"COLUMNS": "160"})
    assert result.exit_code == 0, result.output
    assert "A = [0 1; -9.81 -0.1], B = zeros(2, 0), C = [1 0; 0 1], D = zeros(2, 0)" in result.output
    # with an output whose slope is -0.0 at the rest point (d(-cos th)/dth = sin 0), C shows 0 as MATLAB does
    path.write_text(path.read_text().replace('[system.equations]', 'outputs = { y = "-cos(th)" }\n[system.equations]'))
    result = runner.invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs2")], env={"COLUMNS": "160"})
    assert result.exit_code == 0, result.output
    assert "C = [0 0], D = zeros(1, 0)" in result.output
