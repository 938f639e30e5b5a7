"""`odelab network`, `odelab run` and the report show the derivation; networks run with events,
the compiled backend and unquoted dotted keys."""

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

pytest.importorskip("sympy")

from odelab.cli import app  # noqa: E402
from odelab.experiment.loader import load_experiment  # noqa: E402
from odelab.run.runner import run_case  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
EXPERIMENTS = ROOT / "experiments"
NETWORKS = EXPERIMENTS / "networks"


def test_odelab_network_prints_the_derivation_at_80_columns():
    result = CliRunner().invoke(app, ["network", str(NETWORKS / "network_msd.toml")])
    assert result.exit_code == 0, result.output
    out = result.output
    for heading in ("Element laws", "Interconnection laws", "States", "State equations", "Outputs",
                    "Linear: state-space matrices", "Transfer functions"):
        assert f"\n{heading}\n" in out
    assert "node p: mass.f + spring.f + damper.f = push.f" in out
    assert "d(mass.v)/dt = (f - b*mass.v - k*mass.x)/m" in out
    assert "A = [0, 1; -k/m, -b/m] = [0, 1; -3, -4]" in out
    assert "G_y/f(s) = (q) / (m*s^2 + b*s + k) = (10) / (s^2 + 4 s + 3)" in out
    assert max(len(line) for line in out.splitlines()[2:]) <= 80  # after the title and the file's path


def test_odelab_network_shows_reductions_and_nonlinear_laws():
    dc = CliRunner().invoke(app, ["network", str(NETWORKS / "network_dc_motor.toml")]).output
    assert "load and rotor are joined by gear: load.w = rotor.w/n, so load adds no state" in " ".join(dc.split())
    tanks = " ".join(CliRunner().invoke(app, ["network", str(NETWORKS / "network_tanks.toml")]).output.split())
    assert "orifice.q = cd*sqrt(abs(orifice.p))*sign(orifice.p)" in tanks
    assert "tank1.q = (A1/(g*rho))*d(tank1.p)/dt" in tanks
    assert "Nonlinear" in tanks and "A =" not in tanks


def test_odelab_network_refuses_a_file_that_is_not_a_network():
    result = CliRunner().invoke(app, ["network", str(EXPERIMENTS / "exercise2.toml")])
    assert result.exit_code == 2 and "the system is not a network" in result.output


def test_odelab_run_shows_the_states_and_equations(tmp_path):
    result = CliRunner().invoke(app, ["run", str(NETWORKS / "network_rlc.toml"), "--no-store"])
    assert result.exit_code == 0, result.output
    assert "network: 4 elements -> 2 states (C1.v, L1.i) (linear)" in result.output
    assert "d(L1.i)/dt = (u - C1.v - R*L1.i)/L" in result.output


NETWORK = """
title = "a nonlinear oscillator"
[parameters]
k1 = 3
k3 = 2
[system]
kind = "network"
[elements]
mass   = { type = "mass", node = "p", m = 1 }
spring = { type = "spring", nodes = ["p", "ground"], force = "k1*x + k3*x^3" }
damper = { type = "damper", nodes = ["p", "ground"], b = 0.5 }
[initial]
mass.x = 1          # TOML's dotted key: the state mass.x
[time]
stop = 10
[events.cross]
when = "mass.x"
direction = "falling"
"""


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_a_network_runs_with_events_on_its_dotted_states(tmp_path, backend):
    path = tmp_path / "osc.toml"
    path.write_text(NETWORK)
    case = load_experiment(path).cases[0]
    assert case.problem.states == ("mass.x", "mass.v") and case.problem.x0.tolist() == [1.0, 0.0]
    r = run_case(case, backend=backend)
    assert r.status == "success" and r.backend == backend and len(r.events) == 3
    # each event is a zero of mass.x, located on the step's interpolant
    assert max(abs(e["state"]["mass.x"]) for e in r.events) < 1e-12


def test_the_report_draws_the_network_and_shows_the_derivation(tmp_path):
    runs, out = tmp_path / "runs", tmp_path / "report"
    assert CliRunner().invoke(app, ["run", str(NETWORKS / "network_msd.toml"), "--runs", str(runs)]).exit_code == 0
    result = CliRunner().invoke(app, ["report", "--runs", str(runs), "--out", str(out), "--format", "both", "-j", "1"])
    assert result.exit_code == 0, result.output
    html = (out / "index.html").read_text()
    assert "<h3>The network and its equations</h3>" in html and '<pre class="derivation">' in html
    assert "d(mass.v)/dt = (f - b*mass.v - k*mass.x)/m" in html
    md = (out / "report.md").read_text()
    assert "### The network and its equations" in md
    assert "d(mass.v)/dt = (f - b*mass.v - k*mass.x)/m" in md
    assert "node p: mass.f + spring.f + damper.f = push.f" in md
    assert (out / "figures" / "network_msd-network.svg").is_file()  # the system's Graphviz or the WebAssembly one


def test_analysis_of_a_network_with_an_integrator_and_several_outputs(tmp_path):
    # the quarter-car from a road velocity: a pole at 0, three outputs (python-control's MIMO
    # dcgain of a singular A needs a square system; odelab's goes channel by channel)
    text = (NETWORKS / "network_quarter_car.toml").read_text().replace("[solver]", "[analysis]\npoles = true\n\n[solver]")
    path = tmp_path / "qc.toml"
    path.write_text(text)
    r = run_case(load_experiment(path).cases[0])
    assert r.status == "success"
    info = r.extra["analysis"]
    assert len(info["poles"]) == 5 and min(abs(complex(p["re"], p["im"])) for p in info["poles"]) < 1e-9
    assert len(info["transfer_functions"]) == 3  # body, wheel and travel from the road


def test_odelab_network_derives_a_file_whose_inputs_are_not_written_yet(tmp_path):
    path = tmp_path / "first.toml"
    path.write_text('title = "elements first"\n[system]\nkind = "network"\n[elements]\n'
                    'mass = { type = "mass", node = "p", m = 2 }\n'
                    'push = { type = "force-source", node = "p", value = "F" }\n'
                    'damper = { type = "damper", nodes = ["p", "ground"], b = 4 }\n[time]\nstop = 1\n')
    shown = CliRunner().invoke(app, ["network", str(path)])
    assert shown.exit_code == 0 and "d(mass.v)/dt = F/2 - 2*mass.v" in shown.output
    ran = CliRunner().invoke(app, ["run", str(path), "--no-store"])
    assert ran.exit_code == 2 and "input 'F' has no signal: add [inputs.F]" in ran.output
