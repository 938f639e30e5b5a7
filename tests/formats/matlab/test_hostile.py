"""Hostile MATLAB files: each is one message and exit 2; nothing is run, nothing written."""

from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.exceptions import ExperimentError
from odelab.formats import read

runner = CliRunner()
DECAY = "[t, y] = ode45(@(t, y) -y, [0 1], 1);\n"


def _refused(tmp_path: Path, name: str, content, expected: str, named: Path | None = None):
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    out = tmp_path / "out"
    result = runner.invoke(app, ["import", str(path), "-o", str(out)])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"error: {named or path}: ") and expected in lines[0], result.output
    assert "Traceback" not in result.output and not out.exists()
    ran = runner.invoke(app, ["run", "--runs", str(tmp_path / "runs"), str(path)])
    assert ran.exit_code == 2 and expected in ran.output and not (tmp_path / "runs").exists()
    return lines[0]


@pytest.mark.parametrize("call, word", [
    ("system('touch pwned')", "`system` runs a shell command"),
    ("eval('k = 3;')", "`eval` runs text as MATLAB code"),
    ("evalin('base', 'k = 3;')", "`evalin` runs text as MATLAB code"),
    ("unix('touch pwned')", "`unix` runs a shell command"),
    ("dos('del pwned')", "`dos` runs a shell command"),
    ("!touch pwned", "`!` runs a shell command"),
    ("[s, out] = system('ls');", "`system` runs a shell command"),
])
def test_files_that_would_run_commands_are_refused_with_their_line(tmp_path, call, word):
    line = _refused(tmp_path, "hostile.m", f"k = 2;\n{call}\n{DECAY}", word)
    assert ": line 2: " in line and not (tmp_path / "pwned").exists()


def test_a_command_inside_a_function_the_driver_calls_is_refused_too(tmp_path):
    (tmp_path / "rhs.m").write_text("function d = rhs(t, y)\nsystem('touch pwned');\nd = -y;\n")
    line = _refused(tmp_path, "driver.m", "[t, y] = ode45(@rhs, [0 1], 1);\n", "`system` runs a shell command",
                    named=tmp_path / "rhs.m")
    assert line.startswith(f"error: {tmp_path / 'rhs.m'}: line 2: ")


def test_binary_junk_and_utf16_are_refused(tmp_path):
    _refused(tmp_path, "junk.m", bytes(range(256)) * 16, "is a binary file, not MATLAB source text")
    _refused(tmp_path, "wide.m", "\ufeffx = 1;\n".encode("utf-16"), "is UTF-16 text")


def test_a_50_mb_file_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "huge.m"
    with open(path, "wb") as fh:
        fh.truncate(50 * 1024 * 1024)
    result = runner.invoke(app, ["import", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert "is 52,428,800 bytes; odelab reads MATLAB files of up to 1,000,000 bytes" in result.output
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("text, expected", [
    ("x = " + "(" * 10_000 + "1" + ")" * 10_000 + ";\n" + DECAY, "brackets nest more than 48 deep"),
    ("x = " + "[" * 10_000 + "1" + "]" * 10_000 + ";\n" + DECAY, "brackets nest more than 48 deep"),
    ("x = " + "-" * 10_000 + "1;\n" + DECAY, "nests more than 64 levels deep"),
    ("x = 0" + " + 1" * 20_000 + ";\n" + DECAY, "more than 120 operations deep"),
    ("if 1\n" * 2000 + "x = 1;\n" + "end\n" * 2000 + DECAY, "blocks nest more than 32 deep"),
])
def test_deep_nesting_is_refused_before_anything_recursive(tmp_path, text, expected):
    _refused(tmp_path, "deep.m", text, expected)


def test_huge_loop_bounds_are_refused_before_the_loop_is_unrolled(tmp_path):
    line = _refused(tmp_path, "loop.m", "s = 0;\nfor k = 1:1e9\n  s = s + k;\nend\n" + DECAY,
                    "the loop runs 1,000,000,000 times; odelab unrolls at most 100,000")
    assert ": line 2: " in line


def test_loops_within_the_budget_that_grow_an_expression_are_a_gap_not_a_hang(tmp_path):
    path = tmp_path / "grow.m"
    path.write_text("[t, y] = ode45(@rhs, [0 1], 1);\nfunction d = rhs(t, y)\nd = y;\nfor k = 1:2000\n"
                    "  d = d + sin(d);\nend\nend\n")
    doc = read(path)
    assert doc.gaps and "grows past 1200 operations" in doc.gaps[0].detail


def test_recursive_functions_are_refused(tmp_path):
    text = "[t, y] = ode45(@f, [0 1], 1);\nfunction d = f(t, y)\nd = g(y);\nend\nfunction r = g(y)\nr = f(0, y);\nend\n"
    _refused(tmp_path, "recursive.m", text, "function `f` calls itself (recursion)")


def test_a_script_that_calls_itself_is_refused(tmp_path):
    _refused(tmp_path, "again.m", "x = 1;\nagain\n" + DECAY, "the script again.m runs itself")


def test_too_many_solver_calls_are_refused(tmp_path):
    text = "for k = 1:500\n  [t, y] = ode45(@(t, y) -k*y, [0 1], 1);\nend\n"
    _refused(tmp_path, "many.m", text, "calls a solver more than 200 times")


def test_a_data_file_outside_the_folder_is_not_read(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("1 2\n3 4\n")
    folder = tmp_path / "student"
    folder.mkdir()
    path = folder / "peek.m"
    path.write_text("d = load('../secret.txt');\n[t, y] = ode45(@(t, y) -d(1)*y, [0 1], 1);\n")
    doc = read(path)
    assert doc.gaps and "`../secret.txt` is outside the MATLAB file's folder" in doc.gaps[0].detail
    assert "1 2" not in doc.text and "3 4" not in doc.text


def test_other_languages_named_m_are_refused(tmp_path):
    _refused(tmp_path, "objc.m", "#import <Foundation/Foundation.h>\n@interface Foo : NSObject\n@end\n",
             "is Objective-C source, not MATLAB")


def test_a_script_with_nothing_to_translate_is_refused(tmp_path):
    _refused(tmp_path, "plots.m", "x = linspace(0, 1);\nplot(x, x.^2)\n", "holds no call to an ODE solver")


def test_errors_are_exceptions_not_crashes_for_each_refusal(tmp_path):
    path = tmp_path / "e.m"
    path.write_text("eval('x')\n")
    with pytest.raises(ExperimentError):
        read(path)
