"""An FMU someone handed you: each way it can be hostile or broken is one message (exit 2 at the
command line), checked before anything is unpacked or any of its code is loaded."""

from __future__ import annotations

import zipfile

import pytest

pytest.importorskip("fmpy")


def load(tmp_path, fmu_name: str):
    from odelab.exceptions import ExperimentError
    from odelab.experiment.loader import load_experiment
    from odelab.fmi import allow_native

    path = tmp_path / "case.toml"
    path.write_text(f'[system]\nkind = "fmu"\nfile = "{fmu_name}"\n[time]\nstop = 1\n')
    with allow_native(), pytest.raises(ExperimentError) as info:
        load_experiment(path)
    assert info.value.key == "system.file"
    return info.value.message


def write_zip(path, members: dict, compression=zipfile.ZIP_DEFLATED):
    with zipfile.ZipFile(path, "w", compression) as z:
        for name, data in members.items():
            z.writestr(name, data)


DESCRIPTION = (b'<?xml version="1.0"?>\n<fmiModelDescription fmiVersion="2.0" modelName="M" guid="{0}" '
               b'numberOfEventIndicators="0"><ModelExchange modelIdentifier="M"/><ModelVariables/>'
               b'<ModelStructure/></fmiModelDescription>')


def test_not_a_zip(tmp_path):
    (tmp_path / "m.fmu").write_bytes(b"MZ\x90\x00 not a zip")
    assert load(tmp_path, "m.fmu").startswith("m.fmu: not an FMU: an FMU is a zip archive, and this one cannot be "
                                              "read as one")


def test_a_zip_bomb(tmp_path):
    write_zip(tmp_path / "m.fmu", {"modelDescription.xml": DESCRIPTION, "resources/zeros": b"\0" * (64 * 2 ** 20)})
    message = load(tmp_path, "m.fmu")
    assert message.startswith("m.fmu: the member 'resources/zeros' inflates ")
    assert message.endswith("(to 67,108,864 bytes): a zip bomb; refusing to unpack it.")
    assert not any((tmp_path / "resources").exists() for _ in [0])


@pytest.mark.parametrize("member", ["../evil.txt", "/etc/evil", "sources/../../evil"])
def test_a_member_outside_the_archive(tmp_path, member):
    write_zip(tmp_path / "m.fmu", {"modelDescription.xml": DESCRIPTION, member: b"x"})
    assert load(tmp_path, "m.fmu") == (f"m.fmu: the member {member!r} points outside the archive; refusing to "
                                       "unpack it.")
    assert not (tmp_path.parent / "evil.txt").exists()


def test_a_symbolic_link(tmp_path):
    with zipfile.ZipFile(tmp_path / "m.fmu", "w") as z:
        z.writestr("modelDescription.xml", DESCRIPTION)
        link = zipfile.ZipInfo("resources/passwd")
        link.external_attr = (0o120777 << 16)
        z.writestr(link, "/etc/passwd")
    assert load(tmp_path, "m.fmu") == "m.fmu: the member 'resources/passwd' is a symbolic link; refusing to unpack it."


def test_entities_in_the_model_description(tmp_path):
    laughs = (b'<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;">]>'
              b'<fmiModelDescription fmiVersion="2.0" modelName="&lol2;" guid="x"/>')
    write_zip(tmp_path / "m.fmu", {"modelDescription.xml": laughs})
    assert load(tmp_path, "m.fmu") == ("m.fmu: its modelDescription.xml declares a DOCTYPE or entities, which an "
                                       "FMU's model description never needs (and which can expand without bound); "
                                       "refusing to read it.")


def test_absurd_sizes(tmp_path):
    many = DESCRIPTION.replace(b"<ModelVariables/>", b"<ModelVariables>" + b'<ScalarVariable name="a" '
                               b'valueReference="0"><Real/></ScalarVariable>' * 100_001 + b"</ModelVariables>")
    write_zip(tmp_path / "m.fmu", {"modelDescription.xml": many}, zipfile.ZIP_STORED)
    assert load(tmp_path, "m.fmu") == "m.fmu: its model description declares 100,001 variables; odelab loads at most 100,000."
    write_zip(tmp_path / "n.fmu", {"modelDescription.xml": DESCRIPTION.replace(b'numberOfEventIndicators="0"',
                                                                              b'numberOfEventIndicators="99999999"')})
    assert load(tmp_path, "n.fmu") == "n.fmu: it declares 99,999,999 event indicators; odelab takes between 0 and 10,000."


def test_no_model_description(tmp_path):
    write_zip(tmp_path / "m.fmu", {"model.xml": DESCRIPTION})
    assert load(tmp_path, "m.fmu") == "m.fmu: not an FMU: it has no modelDescription.xml at its top level."


def test_a_missing_or_wrong_platform_binary(tmp_path, test_fmus):
    with zipfile.ZipFile(test_fmus["Dahlquist"]) as z:
        description = z.read("modelDescription.xml")
        library = z.read("binaries/linux64/Dahlquist.so")
    write_zip(tmp_path / "w.fmu", {"modelDescription.xml": description, "binaries/win64/Dahlquist.dll": library})
    assert load(tmp_path, "w.fmu") == (
        "w.fmu: it has no binary for this machine (binaries/linux64/Dahlquist.so); its binaries: win64. Build it "
        "for this platform from its sources, or ask its supplier for one.")
    write_zip(tmp_path / "s.fmu", {"modelDescription.xml": description})
    assert "its binaries: none (a source-only FMU)" in load(tmp_path, "s.fmu")


def test_a_model_identifier_that_is_a_path(tmp_path, test_fmus):
    with zipfile.ZipFile(test_fmus["Dahlquist"]) as z:
        description = z.read("modelDescription.xml").replace(b'modelIdentifier="Dahlquist"',
                                                              b'modelIdentifier="../../../../tmp/evil"')
    write_zip(tmp_path / "p.system.fmu", {"modelDescription.xml": description})
    assert load(tmp_path, "p.system.fmu") == ("p.system.fmu: its modelIdentifier '../../../../tmp/evil' is not a C identifier, as "
                                       "the standard asks (it names the binary to load); refusing to load it.")


def test_a_binary_that_is_not_one(tmp_path, test_fmus):
    with zipfile.ZipFile(test_fmus["Dahlquist"]) as z:
        description = z.read("modelDescription.xml")
    write_zip(tmp_path / "b.fmu", {"modelDescription.xml": description, "binaries/linux64/Dahlquist.so": b"\x7fELF?"})
    assert load(tmp_path, "b.fmu").startswith("b.fmu: its binary for this machine cannot be loaded (")


def test_the_cli_says_it_in_one_line(tmp_path):
    from typer.testing import CliRunner

    from odelab.cli.app import app

    write_zip(tmp_path / "m.fmu", {"modelDescription.xml": DESCRIPTION, "../evil": b"x"})
    (tmp_path / "c.toml").write_text('[system]\nkind = "fmu"\nfile = "m.fmu"\n[time]\nstop = 1\n')
    done = CliRunner().invoke(app, ["run", "--no-store", "--allow-native", str(tmp_path / "c.toml")])
    assert done.exit_code == 2
    assert "`system.file`: m.fmu: the member '../evil' points outside the archive; refusing to unpack it." in \
        done.output
    assert "Traceback" not in done.output
