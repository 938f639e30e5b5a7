"""The next labs' frictions (issue 37): the file a student writes, run as they run it, and what they read."""

import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab.cli import app


def run(tmp_path: Path, text: str, *args: str, files: dict[str, str] | None = None):
    (tmp_path / "lab.toml").write_text(text)
    for name, content in (files or {}).items():
        (tmp_path / name).write_text(content)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "lab.toml"), "--no-store", *args])
    return result.exit_code, " ".join(result.output.split())


def test_a_delayed_state_written_as_matlab_writes_it_is_answered_with_lag(tmp_path):
    code, out = run(tmp_path, '[parameters]\ntau = 1\n[system]\nstates = ["y"]\n[system.equations]\n'
                              'y = "-y(t - tau)"\n[initial]\ny = 1\n[time]\nstop = 2\n')
    assert code == 2
    assert "`y(t - tau)` reads as y delayed by tau: write `lag(y, tau)`" in out and "[history]" in out
    assert "is not an allowed function" not in out


BALL = """
[system]
states = ["h", "v"]
[system.equations]
h = "v"
v = "-9.81"
[initial]
h = 1
v = 0
[time]
stop = 2
[events.floor]
when = "h"
direction = -1
terminal = {terminal}
"""


@pytest.mark.parametrize("given, stops", [("1", True), ("0", False)])
def test_matlab_isterminal_values_are_taken(tmp_path, given, stops):
    import json

    code, out = run(tmp_path, BALL.format(terminal=given), "--json", "--trajectories")
    assert code == 0, out
    (case,) = json.loads(out[out.index("{"):])["experiments"][0]["cases"]
    floor = math.sqrt(2 / 9.81)
    assert case["status"] == "success" and abs(case["events"][0]["t"] - floor) < 1e-6
    t_end = case["trajectory"]["t"][-1]
    assert (abs(t_end - floor) < 1e-9) if stops else (t_end == 2.0)


def test_a_terminal_of_another_kind_is_refused_with_the_matlab_values(tmp_path):
    code, out = run(tmp_path, BALL.format(terminal="2"))
    assert code == 2 and "`events.floor.terminal` must be true or false (MATLAB's isterminal 1 or 0); got 2" in out


PID = """
[blocks]
ref = {{ type = "step" }}
err = {{ type = "sum", inputs = ["ref", "plant"], signs = "+-" }}
pid = {{ type = "pid", input = "err", {gains} }}
plant = {{ type = "transfer-fcn", input = "pid", num = [1], den = [1, 1] }}
[system]
kind = "diagram"
[time]
stop = 5
"""


def test_a_pid_takes_matlab_s_kp_ki_kd(tmp_path):
    code, out = run(tmp_path, PID.format(gains="Kp = 2, Ki = 1, Kd = 0.1"))
    assert code == 0, out
    code, same = run(tmp_path, PID.format(gains="P = 2, I = 1, D = 0.1"))
    assert code == 0 and same.split("lab (")[1] == out.split("lab (")[1]


def test_every_wrong_key_of_a_block_is_in_one_message(tmp_path):
    code, out = run(tmp_path, PID.format(gains="Kp = 2, Kx = 1, gian = 3"))
    assert code == 2
    assert "`blocks.pid.Kx` and `blocks.pid.gian` do not apply to a pid block; a pid takes input, P, I, D, N (Kp " \
           "for P, Ki for I, Kd for D, as MATLAB writes them)." in out
    code, out = run(tmp_path, PID.format(gains="P = 2, Kp = 2"))
    assert code == 2 and "gives `P` twice (as `P` and as MATLAB's `Kp`); keep one" in out


def test_a_resistance_is_a_resistor_first(tmp_path):
    code, out = run(tmp_path, '[system]\nkind = "network"\n[elements]\n'
                              'R = { type = "resistance", nodes = ["a", "ground"], R = 1 }\n[time]\nstop = 1\n')
    assert code == 2 and "'resistance' is not an element type" in out and "Did you mean 'resistor'?" in out


DECIMAL_COMMA = "t;u\n0,0;1,5\n0,5;2,25\n1,0;3\n"


def test_a_decimal_comma_table_is_named_as_such(tmp_path):
    code, out = run(tmp_path, '[system]\nstates = ["x"]\ninputs = ["u"]\n[system.equations]\nx = "-x + u"\n'
                              '[initial]\nx = 0\n[time]\nstop = 1\n[inputs.u]\ntype = "table"\nfile = "u.csv"\n',
                    files={"u.csv": DECIMAL_COMMA})
    assert code == 2 and "line 2 writes its numbers with decimal commas ('0,0;1,5')" in out
    assert "Save the file with '.' as the decimal separator" in out
    code, out = run(tmp_path, '[system]\nstates = ["x"]\n[system.equations]\nx = "-x"\n[initial]\nx = 1\n'
                              '[time]\nstop = 1\n[data]\nfile = "x.csv"\n', files={"x.csv": "t;x\n0,0;1\n0,5;0,6\n"})
    assert code == 2 and "line 2 writes its numbers with decimal commas ('0,0;1')" in out


def test_stepinfo_of_an_undamped_response_says_it_does_not_settle(tmp_path):
    code, out = run(tmp_path, '[system]\nkind = "state-space"\nA = "[0 1; -4 0]"\nB = "[0; 1]"\nC = "[1 0]"\n'
                              'D = "[0]"\n[initial]\nx1 = 0\nx2 = 0\n[time]\nstop = 5\n[inputs.u1]\ntype = "step"\n'
                              '[analysis]\nstep_info = true\n')
    assert code == 0, out
    assert "u1 -> y1 does not settle (an undamped or growing mode): SettlingTime is NaN" in out
    from odelab import StateSpace
    from odelab.analysis.control import stepinfo

    ((_, info),) = stepinfo(StateSpace([[0, 1], [-4, 0]], [[0], [1]], [[1, 0]], [[0]])).items()
    assert math.isnan(info.settling_time) and abs(info.peak - 0.5) < 1e-9
    assert abs(info.peak_time - math.pi / 2) < 1e-6  # the first peak, not the window's last
    assert abs(info.rise_time - (math.acos(0.1) - math.acos(0.9)) / 2) < 1e-6


PENDULUM = """
[parameters]
g = 9.81
L = 1
[system]
states = ["theta", "omega"]
[system.equations]
theta = "omega"
omega = "-g/L*sin(theta)"
[initial]
theta = 0.5
omega = 0
[time]
stop = 10
"""


def test_without_a_reference_the_table_shows_final_min_and_max(tmp_path):
    import json

    code, out = run(tmp_path, PENDULUM)
    assert code == 0, out
    assert "quantity final min max" in out and "max abs error" not in out
    code, doc = run(tmp_path, PENDULUM, "--json", "--trajectories")
    (case,) = json.loads(doc[doc.index("{"):])["experiments"][0]["cases"]
    theta = case["trajectory"]["theta"]
    assert f"theta {theta[-1]:.6g} {min(theta):.6g} {max(theta):.6g}" in out


def _lines(tmp_path, text, *args, env=None):
    import os
    import subprocess
    import sys

    (tmp_path / "lab.toml").write_text(text)
    base = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}  # readline's, under pytest
    out = subprocess.run([sys.executable, "-m", "odelab", "run", "lab.toml", "--no-store", *args], cwd=tmp_path,
                         capture_output=True, text=True, env={**base, **(env or {})})
    assert out.returncode == 0, out.stderr
    return out.stdout.splitlines()


BOUNCE = BALL.format(terminal="true").replace("v = 0\n", "v = 0\n[events.floor.reset]\nv = \"-0.8*v\"\n") \
    .replace("stop = 2", "stop = 3").replace('terminal = true', 'terminal = true\n[events]\nmax_events = 9')


@pytest.mark.parametrize("how", [{"env": {"COLUMNS": "80"}}, {"args": ("--width", "80")}])
def test_columns_and_width_are_honoured_when_piped_and_no_number_is_cut(tmp_path, how):
    lines = _lines(tmp_path, BOUNCE, *how.get("args", ()), env=how.get("env"))
    assert max(len(line) for line in lines) <= 80, max(lines, key=len)
    wide = _lines(tmp_path, BOUNCE)  # piped with neither: 200 columns, every event time in full
    assert max(len(line) for line in wide) > 80
    times = [line.split()[2] for line in wide if line.split()[:2] and line.split()[0].isdigit()
             and line.split()[1] == "floor"]
    assert len(times) >= 3
    narrow = "\n".join(lines)
    for t in times:
        assert t in narrow and len(t) >= 9, t  # 10 significant digits, whole, at 80 columns


DAMPING = """
[parameters]
m = 1
k = 3
b = 4
q = 10
[system]
kind = "state-space"
states = ["x", "v"]
inputs = ["f"]
outputs = ["y"]
A = [[0, 1], ["-k/m", "-b/m"]]
B = [[0], ["1/m"]]
C = [["q", 0]]
D = [[0]]
[initial]
x = 0
v = 0
[time]
stop = 40
[inputs.f]
type = "step"
[reference]
method = "none"
[analysis]
step_info = true
[sweep]
"parameters.b" = [0.5, 2, 4]
"""


def test_a_damping_sweep_with_step_info_has_its_overshoot_table_everywhere(tmp_path):
    import csv
    import subprocess
    import sys

    from odelab import StateSpace
    from odelab.analysis.control import stepinfo

    (tmp_path / "damping.toml").write_text(DAMPING)
    out = subprocess.run([sys.executable, "-m", "odelab", "run", "damping.toml"], cwd=tmp_path, capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stderr
    expected = {b: stepinfo(StateSpace([[0, 1], [-3, -b]], [[0], [1]], [[10, 0]], [[0]]))
                [("y1", "u1")].overshoot for b in (0.5, 2, 4)}
    assert "step response of each case" in out.stdout
    for b, overshoot in expected.items():
        row = next(line for line in out.stdout.splitlines() if line.startswith(f"b={b:g} ") and "f -> y" in line)
        assert f"{overshoot:.4g}" in row.split(), row
    with open(tmp_path / "runs" / "damping" / "sweep.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        b = float(r["parameters.b"])
        assert abs(float(r["y/f_Overshoot"]) - expected[b]) <= 1e-9 * max(1.0, expected[b])
        assert float(r["y_final"]) == pytest.approx(10 / 3, rel=1e-3)
    report = subprocess.run([sys.executable, "-m", "odelab", "report", "--format", "md"], cwd=tmp_path,
                            capture_output=True, text=True)
    assert report.returncode == 0, report.stderr
    md = (tmp_path / "report" / "report.md").read_text()
    assert "| rise time | settling time | overshoot (%) | peak | peak time |" in md
    assert f"| {expected[0.5]:.4g} |" in md


PENDULUM_LINEARIZED = """
[parameters]
g = 9.81
L = 1
[system]
states = ["theta", "omega"]
inputs = ["tau"]
[system.equations]
theta = "omega"
omega = "-g/L*sin(theta) + tau"
[system.outputs]
y = "theta"
[initial]
theta = 0.1
omega = 0
[time]
stop = 5
[inputs.tau]
type = "constant"
value = 0
[linearize]
input = {{ tau = 0 }}
{start}
[analysis]
step_info = true
"""


def test_linearize_runs_from_the_files_initial_state_and_analyses_the_linear_model(tmp_path):
    import json

    code, out = run(tmp_path, PENDULUM_LINEARIZED.format(start=""), "--json", "--trajectories")
    assert code == 0, out
    (case,) = json.loads(out[out.index("{"):])["experiments"][0]["cases"]
    assert case["trajectory"]["theta"][0] == 0.1 and case["extra"]["linearization"]["start"] == "initial"
    (s,) = case["extra"]["analysis"]["step_info"]  # the linear model's: 1/(s^2 + 9.81), undamped
    assert s["SettlingTime"] is None and abs(s["PeakTime"] - math.pi / math.sqrt(9.81)) < 1e-6
    assert not case["warnings"]


def test_an_initial_state_linearize_does_not_use_is_said(tmp_path):
    import json

    code, out = run(tmp_path, PENDULUM_LINEARIZED.format(start='start = "operating-point"'), "--json",
                    "--trajectories")
    assert code == 0, out
    (case,) = json.loads(out[out.index("{"):])["experiments"][0]["cases"]
    assert case["trajectory"]["theta"][0] == 0.0
    assert any('[initial] (theta = 0.1) is not used: linearize.start = "operating-point"' in w
               for w in case["warnings"]), case["warnings"]


SPRING_UNITS = """
[parameters]
m = "250 g"
k = "3 N/m"
L = "100 cm"
[system]
states = ["x", "v"]
[system.equations]
x = "v"
v = "-k/m*x"
[system.outputs]
stretch = "x/L"
[initial]
x = "{x0}"
v = 0
[time]
stop = "{stop}"
[units]
{units}
"""


def test_parameters_with_units_are_converted_to_si_and_said(tmp_path):
    import json

    text = SPRING_UNITS.format(x0="5 cm", stop="0.5 min", units="")
    code, out = run(tmp_path, text, "--json", "--trajectories")
    assert code == 0, out
    (case,) = json.loads(out[out.index("{"):])["experiments"][0]["cases"]
    plain = SPRING_UNITS.replace('"250 g"', "0.25").replace('"3 N/m"', "3").replace('"100 cm"', "1").format(
        x0="0.05", stop="30", units="")
    code, same = run(tmp_path, plain, "--json", "--trajectories")
    (expected,) = json.loads(same[same.index("{"):])["experiments"][0]["cases"]
    assert case["trajectory"]["x"] == expected["trajectory"]["x"]  # the same run, bit for bit
    notes = case["warnings"]
    for note in ("parameters.m = 250 g is 0.25 kg (converted by pint)", "parameters.k = 3 N/m is 3 N/m (converted by pint)",
                 "parameters.L = 100 cm is 1 m (converted by pint)", "initial.x = 5 cm is 0.05 m (converted by pint)",
                 "time.stop = 0.5 min is 30 s (converted by pint)"):
        assert note in notes, notes
    stored = tmp_path / "runs"
    from typer.testing import CliRunner

    (tmp_path / "lab.toml").write_text(text)
    assert CliRunner().invoke(app, ["run", str(tmp_path / "lab.toml"), "--runs", str(stored)]).exit_code == 0
    resolved = next(stored.rglob("resolved.toml")).read_text()
    assert "# parameters.L = 100 cm is 1 m (converted by pint): the number below." in resolved
    import tomllib

    assert tomllib.loads(resolved)["parameters"]["L"] == 1.0


def test_a_unit_converts_to_the_one_units_declares_and_a_misfit_names_both(tmp_path):
    import json

    code, out = run(tmp_path, SPRING_UNITS.format(x0="5 cm", stop="30", units='x = "cm"'), "--json", "--trajectories")
    assert code == 0, out
    (case,) = json.loads(out[out.index("{"):])["experiments"][0]["cases"]
    assert case["trajectory"]["x"][0] == 5.0 and "initial.x = 5 cm is 5 cm (converted by pint)" in case["warnings"]
    code, out = run(tmp_path, SPRING_UNITS.format(x0="5 cm", stop="30", units='L = "s"'))
    assert code == 2
    assert ("`parameters.L` is '100 cm', a quantity of [length], but [units] gives L in 's', a quantity of [time]: "
            "the two do not fit.") in out


@pytest.mark.parametrize("value, message", [
    ("1e400 km", "'1e400 km': inf is not a finite number"),
    ("1e308 km", "which is inf in m: not a finite number"),
    ("2 m + 3 s", "is not a unit odelab reads"),
    ("5 kg*(((((m)))))", "is not a unit odelab reads"),
    ("3 " + "(" * 10000 + "m" + ")" * 10000, "is not a unit odelab reads"),
    ("7 furlong_per_fortnite", "it is not a unit pint knows"),
])
def test_hostile_values_with_units_get_one_message(tmp_path, value, message):
    code, out = run(tmp_path, SPRING_UNITS.replace('"100 cm"', f'"{value}"').format(x0="5 cm", stop="30", units=""))
    assert code == 2 and message in out and "Traceback" not in out, out


def test_a_unit_dunder_name_is_no_unit_and_runs_no_code(tmp_path):
    code, out = run(tmp_path, SPRING_UNITS.replace('"100 cm"', '"5 __class__"').format(x0="5 cm", stop="30",
                                                                                        units=""))
    assert code == 2 and "Traceback" not in out and "parameters.L" in out
