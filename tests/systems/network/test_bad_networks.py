"""Bad networks: one clear message naming the elements and the fix, exit code 2, nothing runs
and nothing is stored. Each file in tests/assets/bad_networks/ says its message on its first
line (``# expect: ...``)."""

from pathlib import Path

import pytest
from typer.testing import CliRunner

pytest.importorskip("sympy")

from odelab.cli import app  # noqa: E402
from odelab.network import CurrentSource, Inductor, Mass, Network, NetworkError, Resistor, VelocitySource  # noqa: E402

BAD = Path(__file__).resolve().parents[2] / "assets" / "bad_networks"
FILES = sorted(BAD.glob("*.toml"))


def expected(path: Path) -> str:
    first = path.read_text().splitlines()[0]
    assert first.startswith("# expect: ")
    return first[len("# expect: "):]


def test_every_bad_network_of_the_issue_has_a_file():
    names = {p.stem for p in FILES}
    assert {"floating_node", "two_domains", "parallel_voltage_sources", "two_velocity_sources",
            "current_source_inductor", "unknown_type", "unknown_parameter", "law_wrong_variable"} <= names


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
@pytest.mark.parametrize("command", ["run", "network"])
def test_bad_network_gives_one_message_and_exit_2_and_stores_nothing(path, command, tmp_path):
    runs = tmp_path / "runs"
    args = [command, str(path)] + (["--runs", str(runs)] if command == "run" else [])
    result = CliRunner().invoke(app, args)
    text = " ".join(result.output.split())
    assert result.exit_code == 2, result.output
    assert expected(path) in text
    assert text.count("error:") == 1 and "Traceback" not in text
    assert not runs.exists() or not any(runs.rglob("*"))


def test_the_python_api_raises_the_same_errors():
    with pytest.raises(NetworkError, match="the current of 'L1' \\(inductor\\) is fixed by the source 'I1'"):
        Network({"I1": CurrentSource(node="a", value="u"), "L1": Inductor(node="a", L=1)}).derive()
    with pytest.raises(NetworkError, match="'v1' and 'v2' fix the same variable"):
        Network({"m": Mass(node="p"), "v1": VelocitySource(node="p", value="u"),
                 "v2": VelocitySource(node="p", value="w")}).derive()
    with pytest.raises(NetworkError, match="nodes 'b', 'c' float"):
        Network({"I1": CurrentSource(node="a", value="u"), "R1": Resistor(nodes=["a", "ground"]),
                 "R2": Resistor(nodes=["b", "c"]), "R3": Resistor(nodes=["c", "b"])}).derive()


def test_a_mass_moved_by_a_velocity_source_is_reduced_not_refused():
    net = Network({"mass": Mass(node="p", m=2), "drive": VelocitySource(node="p", value="u"),
                   "R": Resistor(nodes=["a", "ground"]), "I": CurrentSource(node="a", value="i")},
                  outputs={"v": "mass.v"})
    d = net.derive()
    assert d.states == ()
    assert d.state_notes == ["mass's velocity is fixed by the source drive: mass adds no state (it follows drive's "
                             "value)"]
    assert d.output_texts() == {"v": "u"}
    with pytest.raises(NetworkError, match="needs d\\(u\\)/dt, the derivative of an input"):
        Network(net.elements, outputs={"f": "mass.f"}).derive()
