"""Hostile Simulink files: each is one message naming the file, exit 2 from the CLI, no traceback, nothing stored,
nothing fetched or extracted (zip bombs, `../` members, billion laughs, external entities, 1,000-deep subsystems,
binary junk, a file over the size budget, a physical-network model)."""

from __future__ import annotations

import io
import sys
import zipfile
from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab import formats
from odelab.cli import app
from odelab.exceptions import ExperimentError

HERE = Path(__file__).resolve().parents[2] / "assets" / "simulink"
sys.path.insert(0, str(HERE))
from make_corpus import B, L, Sub, xml_parts  # noqa: E402

SOLVER = {"Solver": "ode45", "StopTime": "1"}
TINY = Sub([B("Constant", "c"), B("Outport", "y", {"Port": "1"})], [L("c:1", "y:1")])


def _zip(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return buf.getvalue()


def _good_parts():
    return {k: v.encode() for k, v in xml_parts("m", TINY, SOLVER).items()}


def _deep_mdl(depth: int) -> bytes:
    """Subsystems nested ``depth`` deep, written without recursion (the writer must not be the limit)."""
    opening = 'Block {\n BlockType SubSystem\n Name "S"\n System {\n Name "S"\n'
    return (b'Model {\n Name "deep"\n System {\n Name "deep"\n' + opening.encode() * depth
            + b"}\n}\n" * depth + b"}\n}\n")


def _deep_slx(depth: int, inline: bool) -> bytes:
    if inline:
        body = '<Block BlockType="SubSystem" Name="S" SID="1"><System>' * depth + "</System></Block>" * depth
        model = f'<ModelInformation><Model Name="deep"><System>{body}</System></Model></ModelInformation>'
        return _zip({"simulink/blockdiagram.xml": model.encode()})
    parts = {"simulink/blockdiagram.xml": b'<ModelInformation><Model Name="deep"><System Ref="system_root"/>'
                                          b"</Model></ModelInformation>"}
    names = ["system_root"] + [f"system_{i}" for i in range(1, depth + 1)]
    for i, name in enumerate(names[:-1]):
        parts[f"simulink/systems/{name}.xml"] = (f'<System><Block BlockType="SubSystem" Name="S" SID="{i + 1}">'
                                                 f'<System Ref="{names[i + 1]}"/></Block></System>').encode()
    parts[f"simulink/systems/{names[-1]}.xml"] = b"<System/>"
    return _zip(parts)


LAUGHS = ('<?xml version="1.0"?>\n<!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;'
          '&lol;&lol;&lol;&lol;"><!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">'
          ']>\n<ModelInformation><Model Name="m"><P Name="Description">&lol3;</P><System/></Model></ModelInformation>')
EXTERNAL = ('<?xml version="1.0"?>\n<!DOCTYPE x [<!ENTITY secret SYSTEM "file:///etc/passwd">]>\n'
            '<ModelInformation><Model Name="m"><P Name="Description">&secret;</P><System/></Model></ModelInformation>')


def _package(blockdiagram: str) -> str:
    return ("Model {\n  Version 10.4\n}\n__MWOPC_PACKAGE_BEGIN__ R2021b\n__MWOPC_PART_BEGIN__ /simulink/blockdiagram.xml\n"
            + blockdiagram + "\n__MWOPC_PACKAGE_END__\n")


def _hostile(tmp_path) -> dict[str, tuple[bytes, str]]:
    """name -> (bytes, what the one message says)."""
    bomb = _good_parts()
    bomb["simulink/blockdiagram.xml"] = b"<a>" + b" " * 30_000_000 + b"</a>"
    escape = _good_parts()
    escape["../../outside.xml"] = b"<x/>"
    laughs_parts = _good_parts()
    laughs_parts["simulink/blockdiagram.xml"] = LAUGHS.encode()
    return {
        "bomb.slx": (_zip(bomb), "inflates"),
        "escape.slx": (_zip(escape), "'../../outside.xml' has a name no model has"),
        "laughs.mdl": (_package(LAUGHS).encode(), "declares a DTD or entities"),
        "laughs.slx": (_zip(laughs_parts), "declares a DTD or entities"),
        "external.mdl": (_package(EXTERNAL).encode(), "declares a DTD or entities"),
        "deep.mdl": (_deep_mdl(1000), "subsystems nest more than 100 deep"),
        "deep.slx": (_deep_slx(1000, inline=False), "subsystems nest more than 100 deep"),
        "deep_inline.slx": (_deep_slx(1000, inline=True), "subsystems nest more than 100 deep"),
        "junk.slx": (bytes(range(256)) * 40, "it is a binary file, neither an .slx (a zip) nor an .mdl"),
        "broken.slx": (b"PK\x03\x04" + bytes(range(256)) * 4, "not a readable zip"),
        "junk.mdl": (b"\x00\x01\x02binary" * 100, "binary file"),
        "text.mdl": (b"just some text\nnot a model\n", "is outside any section"),
        "library.mdl": (b"Library {\n  Name \"lib\"\n  System {\n    Name \"lib\"\n  }\n}\n", "a Simulink library"),
        "empty.mdl": (b"Model {\n  Name \"empty\"\n  System {\n    Name \"empty\"\n    Block {\n      BlockType Scope\n"
                      b"      Name \"Scope\"\n    }\n  }\n}\n", "has nothing to simulate"),
    }


def test_each_hostile_file_is_one_message_naming_the_file(tmp_path):
    for name, (data, said) in _hostile(tmp_path).items():
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(ExperimentError) as info:
            formats.read(path)
        text = str(info.value)
        assert text.startswith(str(path) + ": ") and said in text, (name, text)
        assert "\n" not in text and "Traceback" not in text


def test_nothing_is_fetched_or_expanded(tmp_path, monkeypatch):
    import urllib.request

    def refuse(*a, **k):  # an external entity would be fetched through here
        raise AssertionError("fetched")

    monkeypatch.setattr(urllib.request, "urlopen", refuse)
    path = tmp_path / "external.slx"
    parts = _good_parts()
    parts["simulink/blockdiagram.xml"] = EXTERNAL.encode()
    path.write_bytes(_zip(parts))
    with pytest.raises(ExperimentError, match="refused before anything was expanded or fetched"):
        formats.read(path)


def test_a_file_over_the_size_budget_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "huge.slx"
    with open(path, "wb") as fh:  # sparse: 60 MB declared, nothing written
        fh.truncate(60_000_000)
    with pytest.raises(ExperimentError, match=r"is 60,000,000 bytes; Simulink models are read up to 50,000,000"):
        formats.read(path)


def test_the_cli_exits_2_with_one_line_and_stores_nothing(tmp_path):
    runner = CliRunner()
    for name, (data, said) in _hostile(tmp_path).items():
        path = tmp_path / name
        path.write_bytes(data)
        result = runner.invoke(app, ["run", str(path), "--runs", str(tmp_path / "runs")])
        assert result.exit_code == 2, (name, result.output)
        assert said in result.output and "Traceback" not in result.output
        assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").iterdir())
    assert not (tmp_path.parent / "outside.xml").exists()


def test_physical_network_models_are_refused_with_the_list_and_the_advice():
    with pytest.raises(ExperimentError) as info:
        formats.read(HERE / "physical.slx")
    text = str(info.value)
    assert "its blocks physical/Resistor, physical/Solver Configuration are physical components" in text
    assert "odelab network (`kind = \"network\"`" in text


def test_a_missing_variable_is_a_gap_naming_the_blocks_that_use_it():
    doc = formats.read(HERE / "with_gaps.slx")
    gap = next(g for g in doc.gaps if g.construct == "K_missing")
    assert gap.where == "workspace" and "used by with_gaps/Unknown gain" in gap.detail
    assert "--set K_missing=VALUE" in gap.detail
    assert "# GAP: `K_missing` is used by with_gaps/Unknown gain but nobody sets it" in doc.text
