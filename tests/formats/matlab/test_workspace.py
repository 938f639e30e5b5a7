"""formats.matlab.workspace: the constant assignments of workspace scripts, evaluated without running them."""

import numpy as np
import pytest

from odelab.exceptions import ExperimentError
from odelab.formats.matlab import workspace

SCRIPT = """% a mass-spring-damper's workspace
m = 2; k = 3;   b = 0.5;
A = [0 1; -k/m -b/m];
B = [0; 1/m];
p.wn = sqrt(k/m);
p.name = 'msd';
x0 = [1 0]';
t = linspace(0, 1, 5);
figure; plot(t, t)
r = rand(3);
if k > 2
    zeta = b/(2*sqrt(k*m));
else
    zeta = 0;
end
for i = 1:3
    s(i) = i^2;
end
"""


def test_constants_matrices_structs_and_loops_are_evaluated(tmp_path):
    path = tmp_path / "params.m"
    path.write_text(SCRIPT)
    values, notes = workspace([path])
    assert values["m"] == 2.0 and values["k"] == 3.0 and values["b"] == 0.5
    np.testing.assert_array_equal(values["A"], [[0.0, 1.0], [-1.5, -0.25]])
    np.testing.assert_array_equal(values["B"], [[0.0], [0.5]])
    assert values["p"] == {"wn": np.sqrt(1.5), "name": "msd"}
    np.testing.assert_array_equal(values["x0"], [[1.0], [0.0]])
    np.testing.assert_array_equal(values["t"], [[0.0, 0.25, 0.5, 0.75, 1.0]])
    assert values["zeta"] == 0.5 / (2 * np.sqrt(6.0))
    np.testing.assert_array_equal(values["s"], [[1.0, 4.0, 9.0]])
    assert "r" not in values
    rows = {(n.where, n.construct, n.outcome) for n in notes}
    assert ("line 9", "plot(...)", "ignored") in rows and ("line 10", "r", "ignored") in rows
    why = next(n.detail for n in notes if n.construct == "r")
    assert "`rand` draws random numbers" in why


def test_set_overrides_a_name_wherever_a_script_assigns_it(tmp_path):
    path = tmp_path / "params.m"
    path.write_text(SCRIPT)
    values, notes = workspace([path], [("k", "8"), ("extra", "[1 2; 3 4]")])
    assert values["k"] == 8.0
    np.testing.assert_array_equal(values["A"], [[0.0, 1.0], [-4.0, -0.25]])  # derived from the set k
    np.testing.assert_array_equal(values["extra"], [[1.0, 2.0], [3.0, 4.0]])
    assert any(n.construct == "k = ..." and "set by --set" in n.detail for n in notes)


def test_a_later_script_wins_and_scripts_call_scripts_beside_them(tmp_path):
    (tmp_path / "base.m").write_text("g = 9.81;\nL = 1;\n")
    (tmp_path / "more.m").write_text("base\nL = 2*L;\n")
    values, _ = workspace([tmp_path / "base.m", tmp_path / "more.m"])
    assert values == {"g": 9.81, "L": 2.0}


@pytest.mark.parametrize("line, word", [("system('rm -rf /')", "system"), ("eval('k = 3')", "eval"),
                                        ("!ls", "!"), ("unix('ls')", "unix")])
def test_scripts_that_would_run_commands_are_refused(tmp_path, line, word):
    path = tmp_path / "bad.m"
    path.write_text(f"k = 1;\n{line}\n")
    with pytest.raises(ExperimentError) as info:
        workspace([path])
    text = str(info.value)
    assert text.startswith(f"{path}: line 2: ") and f"`{word}`" in text
