"""The Simulink reader's parts: MATLAB parameter text, the workspace (callbacks, scripts beside the model, driver
scripts, --workspace, --set), Simulink's defaults, names made identifiers, and the document's shape."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from odelab import formats
from odelab.formats.base import GAP, ImportOptions
from odelab.formats.simulink.mexpr import MExprError, V, evaluate
from odelab.formats.toml import parse_toml

HERE = Path(__file__).resolve().parents[2] / "assets" / "simulink"
sys.path.insert(0, str(HERE))
from make_corpus import B, L, Sub, classic_mdl, slx  # noqa: E402


def _value(text, **names):
    lookup = {k: V(np.atleast_2d(np.asarray(v, dtype=float)), np.array([[k]], dtype=object)) for k, v in
              names.items()}
    return evaluate(text, lookup.get)


@pytest.mark.parametrize("text, numbers", [
    ("[1 -2]", [[1, -2]]), ("[1 - 2]", [[-1]]), ("[1 -2 + 3]", [[1, 1]]), ("[a' b']", [[1, 2]]),
    ("[1 2; 3 4]'", [[1, 3], [2, 4]]), ("-2^2", [[-4]]), ("2^-1", [[0.5]]), ("[0:0.5:1]", [[0, 0.5, 1]]),
    ("tanh([-1:1])", [np.tanh([-1, 0, 1])]), ("eye(2)*3", [[3, 0], [0, 3]]), ("1e-3", [[0.001]]),
    ("[1 2\n3 4]", [[1, 2], [3, 4]]), ("eps", [[np.finfo(float).eps]]), ("zeros(1,2)", [[0, 0]]),
])
def test_matlab_parameter_text(text, numbers):
    names = {"a": 1.0, "b": 2.0}
    value = evaluate(text, lambda n: V(np.array([[names[n]]])) if n in names else None)
    assert np.array_equal(value.num, np.asarray(numbers, dtype=float))


def test_parameters_stay_parameters_in_the_written_text():
    value = _value("[1 2*zeta*wn wn^2]", zeta=0.5, wn=2.0)
    assert value.num.tolist() == [[1.0, 2.0, 4.0]]
    assert [value.item((0, i)) for i in range(3)] == [1.0, "((2.0 * zeta) * wn)", "(wn ^ 2.0)"]


@pytest.mark.parametrize("text, why", [("(" * 40 + "1" + ")" * 40, "nest more than 32 deep"),
                                       ("zeros(1e7, 1e7)", "at most 1,000,000"), ("[1 2", "unclosed"),
                                       ("'text'", "a string")])
def test_matlab_text_that_is_refused(text, why):
    with pytest.raises(MExprError, match=why):
        evaluate(text, lambda n: None)


GAIN = Sub([B("Step", "Step"), B("Gain", "Gain", {"Gain": "K"}), B("Outport", "y", {"Port": "1"})],
           [L("Step:1", "Gain:1"), L("Gain:1", "y:1")])


def test_a_driver_script_is_the_workspace_and_its_sim_span_the_time(tmp_path):
    (tmp_path / "model.mdl").write_text(classic_mdl("model", GAIN, {"StopTime": "10"}))
    (tmp_path / "other.m").write_text("K = 99;\n")  # beside the model, but not its driver
    (tmp_path / "run_it.m").write_text("K = 3;\nout = sim('Model', [0 4]);\nK = 7;\n")
    doc = formats.read(tmp_path / "model.mdl")
    assert doc.data["parameters"]["K"] == 3.0 and doc.data["time"]["stop"] == 4.0
    assert not doc.gaps


def test_scripts_that_disagree_are_a_gap_until_workspace_chooses(tmp_path):
    (tmp_path / "model.slx").write_bytes(slx("model", GAIN, {"StopTime": "1"}))
    (tmp_path / "a.m").write_text("K = 1;\n")
    (tmp_path / "b.m").write_text("K = 2;\n")
    doc = formats.read(tmp_path / "model.slx")
    (gap,) = doc.gaps
    assert gap.construct == "K" and "a.m" in gap.detail and "b.m" in gap.detail and "--workspace" in gap.detail
    chosen = formats.read(tmp_path / "model.slx", ImportOptions(workspace=(tmp_path / "b.m",)))
    assert chosen.data["parameters"]["K"] == 2.0 and not chosen.gaps
    pinned = formats.read(tmp_path / "model.slx", ImportOptions(sets=(("K", "2.5*2"),)))
    assert pinned.data["parameters"]["K"] == 5.0 and not pinned.gaps


def test_a_variable_nobody_sets_is_a_gap_with_the_blocks_that_use_it(tmp_path):
    (tmp_path / "model.mdl").write_text(classic_mdl("model", GAIN, {"StopTime": "1"}))
    doc = formats.read(tmp_path / "model.mdl")
    (gap,) = doc.gaps
    assert (gap.where, gap.construct, gap.outcome) == ("workspace", "K", GAP)
    assert gap.detail.startswith("nobody sets `K` (used by model/Gain)")


def test_defaults_names_and_the_document(tmp_path):
    model = Sub([B("Step", "Step 1"), B("Gain", "Gain\nfor K"), B("Sum", "Sum", ports=(2, 1)),
                 B("Scope", "Scope")],
                [L("Step 1:1", ["Gain\nfor K:1", "Sum:2"]), L("Gain\nfor K:1", "Sum:1"), L("Sum:1", "Scope:1")])
    (tmp_path / "m.mdl").write_text(classic_mdl("m", model, {}))
    doc = formats.read(tmp_path / "m.mdl")
    assert doc.data == parse_toml(doc.text.encode(), "m.mdl") and doc.raw == (tmp_path / "m.mdl").read_bytes()
    blocks = doc.data["blocks"]
    assert blocks["Step_1"] == {"type": "step", "time": 1.0, "initial": 0.0, "final": 1.0}  # Simulink's Step
    assert blocks["Gain_for_K"]["gain"] == 1.0 and blocks["Sum"]["signs"] == "++"  # Gain 1, Sum "|++"
    note = next(n for n in doc.notes if n.where == "block m/Gain for K")
    assert "its name made an identifier: Gain_for_K" in note.detail
    solver = doc.data["solver"]
    assert (solver["method"], solver["rtol"], solver["atol"], solver["max_step"], solver["refine"]) == (
        "ode45", 1e-3, 1e-6, 0.2, 1)  # VariableStepAuto, RelTol 1e-3, AbsTol auto, MaxStep auto = 10/50, Refine 1
    assert doc.data["time"] == {"start": 0.0, "stop": 10.0}


def test_real_world_constructs_second_order_integrator_and_an_initial_condition_port(tmp_path):
    model = Sub([B("Constant", "One"), B("Constant", "x0", {"Value": "2"}),
                 B("Integrator", "I", {"InitialConditionSource": "external"}, ports=(2, 1)),
                 B("SecondOrderIntegrator", "I2", {"ICX": "1", "ICDXDT": "-1"}, ports=(1, 2)),
                 B("Scope", "Scope", ports=(3, 0))],
                [L("One:1", ["I:1", "I2:1"]), L("x0:1", "I:2"), L("I:1", "Scope:1", name="a"),
                 L("I2:1", "Scope:2", name="x"), L("I2:2", "Scope:3", name="v")])
    (tmp_path / "m.slx").write_bytes(slx("m", model, {"StopTime": "2", "RelTol": "1e-8", "AbsTol": "1e-10"}))
    from odelab.run.runner import run_experiment

    (r,) = run_experiment(tmp_path / "m.slx")
    t = r.t
    names = list(r.case.problem.outputs)
    assert np.max(np.abs(r.y[:, names.index("a")] - (2 + t))) < 1e-9
    assert np.max(np.abs(r.y[:, names.index("x")] - (1 - t + t * t / 2))) < 1e-9
    assert np.max(np.abs(r.y[:, names.index("v")] - (-1 + t))) < 1e-9


FUNCTION = "function [r, theta] = fcn(x, y)\n% polar form\nr2 = x^2 + y^2;\nr = sqrt(r2);\ntheta = atan2(y, x);\n"
POLAR = Sub([B("Constant", "x", {"Value": "3"}), B("Constant", "y", {"Value": "4"}),
             B("SubSystem", "MATLAB Function", {"SFBlockType": "MATLAB Function"},
               sub=Sub([B("Inport", "x", {"Port": "1"}), B("Inport", "y", {"Port": "2"}),
                        B("Outport", "r", {"Port": "1"}), B("Outport", "theta", {"Port": "2"})], []), ports=(2, 2)),
             B("Outport", "r", {"Port": "1"}), B("Outport", "theta", {"Port": "2"})],
            [L("x:1", "MATLAB Function:1"), L("y:1", "MATLAB Function:2"), L("MATLAB Function:1", "r:1"),
             L("MATLAB Function:2", "theta:1")])


def _escaped(text):
    return text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")


def test_matlab_function_blocks_of_straight_line_code_become_fcn_blocks(tmp_path):
    import io
    import zipfile

    from make_corpus import xml_parts

    chart = ('<?xml version="1.0" encoding="utf-8"?><chart id="7"><P Name="name">MATLAB Function</P><Children>'
             '<state SSID="1"><eml><P Name="isEML">1</P><P Name="script">' + FUNCTION + '</P></eml></state>'
             '</Children></chart>')
    parts = {**xml_parts("polar", POLAR, {"StopTime": "1"}), "simulink/stateflow/chart_7.xml": chart}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, text in parts.items():
            zf.writestr(name, text)
    (tmp_path / "polar.slx").write_bytes(buf.getvalue())
    mdl = classic_mdl("polar", POLAR, {"StopTime": "1"}) + (
        'Stateflow {\n  machine {\n    id 1\n  }\n  chart {\n    id 7\n    name "MATLAB Function"\n  }\n'
        f'  state {{\n    id 8\n    chart 7\n    eml {{\n      isEML 1\n      script "{_escaped(FUNCTION)}"\n    }}\n'
        '  }\n}\n')
    (tmp_path / "polar.mdl").write_text(mdl)
    from odelab.run.runner import run_experiment

    for name in ("polar.slx", "polar.mdl"):
        doc = formats.read(tmp_path / name)
        assert not doc.gaps, doc.gaps
        (r,) = run_experiment(tmp_path / name)
        names = list(r.case.problem.outputs)
        assert np.all(r.y[:, names.index("r")] == 5.0)
        assert np.all(r.y[:, names.index("theta")] == np.arctan2(4.0, 3.0))
    (tmp_path / "loop.mdl").write_text(mdl.replace("r = sqrt(r2);", "for i = 1:3\\n r2 = r2 + 1;\\nend\\nr = r2;"))
    (gap,) = formats.read(tmp_path / "loop.mdl").gaps
    assert gap.construct == "MATLAB Function" and "is not an assignment" in gap.detail
