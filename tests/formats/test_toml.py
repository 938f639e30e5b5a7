"""Reading experiment files: size before reading, encodings, nesting depth (issue 15, classes 5 and 7)."""

import codecs
import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.exceptions import ExperimentError
from odelab.experiment.loader import load_experiment, merge
from odelab.formats.toml import MAX_NESTING, nesting_depth, read_toml

ROOT = Path(__file__).resolve().parents[2]
EXERCISE1 = (ROOT / "experiments" / "exercise1.toml").read_text(encoding="utf-8")


def run(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def test_a_utf8_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "notepad.toml"
    path.write_bytes(codecs.BOM_UTF8 + EXERCISE1.replace("\n", "\r\n").encode("utf-8"))
    exp = load_experiment(path)
    assert [c.name for c in exp.cases] == ["ode23", "ode45"]
    assert exp.file_hash == __import__("hashlib").sha256(path.read_bytes()).hexdigest()  # the file as it is


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-16-be", "utf-32"])
def test_utf16_and_utf32_files_are_told_to_be_saved_as_utf8(tmp_path, encoding):
    path = tmp_path / "wide.toml"
    path.write_bytes(EXERCISE1.encode(encoding))
    with pytest.raises(ExperimentError) as info:
        load_experiment(path)
    kind = "UTF-32" if "32" in encoding else "UTF-16"
    assert str(info.value).startswith(f"{path}: is {kind} text")
    assert "save it as UTF-8" in str(info.value)


def test_dev_zero_is_refused_without_reading_it():
    result = run("run", "/dev/zero", "--no-store")
    assert result.exit_code == 2
    assert "/dev/zero: is not a regular file (a device, a pipe or a socket)" in result.output
    assert "Traceback" not in result.output


def test_a_named_pipe_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    with pytest.raises(ExperimentError, match="is not a regular file"):
        read_toml(fifo)


def test_a_large_file_is_refused_by_its_size(tmp_path):
    path = tmp_path / "big.toml"
    with open(path, "wb") as fh:
        fh.truncate(50_000_000)  # sparse: refused from its size, never read
    with pytest.raises(ExperimentError, match=r"is 50,000,000 bytes; experiment files are limited to 1,000,000 bytes"):
        read_toml(path)


@pytest.mark.parametrize("text", [
    "x = " + "[" * 100_000 + "]" * 100_000,          # the TOML parser's own recursion
    "x = " + "{a = " * 5_000 + "1" + "}" * 5_000,
    "x = " + "[" * 40 + "1" + "]" * 40,                # parses, but deeper than the limit
    "[" + ".".join(["a"] * 40) + "]\nb = 1\n",       # a table header 40 levels deep
    ".".join(["a"] * 3000) + " = 1\n",               # dotted keys: the case merge used to recurse on it
])
def test_deep_nesting_is_one_message(tmp_path, text):
    path = tmp_path / "deep.toml"
    path.write_text(text)
    result = run("run", path, "--no-store")
    assert result.exit_code == 2, result.output
    assert f"levels deep; experiment files are limited to {MAX_NESTING} levels" in result.output
    assert "Traceback" not in result.output and "RecursionError" not in result.output


def test_nesting_depth_is_iterative():
    data: dict = {}
    node = data
    for _ in range(100_000):
        node["a"] = {}
        node = node["a"]
    assert nesting_depth(data) == MAX_NESTING + 1  # stops counting past the limit
    assert nesting_depth({"a": [[1, 2], [3]], "b": 1}) == 3


def test_a_nul_byte_in_the_path_is_a_message(tmp_path):
    with pytest.raises(ExperimentError, match="cannot be read: embedded null byte"):
        read_toml(Path(str(tmp_path / "a") + "\x00.toml"))


def test_merge_shares_what_the_case_does_not_change():
    base = {"system": {"A": [[1, 2], [3, 4]]}, "solver": {"method": "ode23", "atol": [1, 2]}}
    out = merge(base, {"solver": {"rtol": 1e-4}})
    assert out["system"] is base["system"]  # not copied: linear in the cases, not cases x base
    assert out["solver"] == {"method": "ode23", "atol": [1, 2], "rtol": 1e-4}
    assert base["solver"] == {"method": "ode23", "atol": [1, 2]}
