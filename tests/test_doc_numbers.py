"""The numbers the README and the tutorials quote are the build's: each quoted sentence is found
in its page (a test fails when the wording changes, so that the check moves with it) and its
numbers are computed again here, from the shipped experiment files, as a reader would get them.
A number that drifts (a solver change that takes 776 steps where a page says 658) fails here."""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ROOT / "experiments"


def quoted(page: str, pattern: str) -> tuple[str, ...]:
    """The groups of ``pattern`` in ``page`` (whitespace in the pattern matches any run of it)."""
    text = (ROOT / page).read_text(encoding="utf-8")
    m = re.search(pattern.replace(" ", r"\s+"), text)
    assert m is not None, f"{page} no longer says {pattern!r}: update this test with the page"
    return m.groups()


@lru_cache(maxsize=None)
def runs(name: str) -> dict:
    """Each case of a shipped experiment, run as `odelab run` runs it (name -> CaseResult)."""
    from odelab.experiment.loader import load_experiment
    from odelab.run.runner import run_case

    return {c.name: run_case(c) for c in load_experiment(EXPERIMENTS / f"{name}.toml").cases}


def sci(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}e}"


def test_experiment_files_quotes_the_stiff_step_counts():
    ode45_steps, ode45_t, *steps = quoted(
        "docs/tutorials/experiment-files.md",
        r"ode45 stopped by its step limit after ([\d,]+) steps at t = (\d+), ode15s, ode23s, ode23t, ode23tb and "
        r"Radau across the span in (\d+), (\d+), (\d+), (\d+) and (\d+) steps")
    r = runs("stiff")
    assert r["ode45"].status == "failed" and f"{r['ode45'].stats.nsteps:,}" == ode45_steps
    assert int(float(r["ode45"].t[-1])) == int(ode45_t)
    got = [r[m].stats.nsteps for m in ("ode15s", "ode23s", "ode23t", "ode23tb", "Radau")]
    assert [str(n) for n in got] == steps
    assert all(float(r[m].t[-1]) == 3000.0 for m in ("ode15s", "ode23s", "ode23t", "ode23tb", "Radau"))


def test_matlab_parity_quotes_the_same_ode23t_run():
    steps, failed, fevals, jacobians, lus = quoted(
        "docs/MATLAB-PARITY.md", r"van der Pol mu = 1000 on \[0, 3000\] (\d+) steps, (\d+) failed, (\d+) "
        r"evaluations, (\d+) Jacobians, (\d+) LU")
    s = runs("stiff")["ode23t"].stats
    assert (s.nsteps, s.nfailed, s.npds, s.ndecomps) == (int(steps), int(failed), int(jacobians), int(lus))
    # the page's 2121 evaluations count numjac's (MATLAB's defaults); odelab's exact Jacobian needs none
    assert s.nfevals <= int(fevals)


def test_readme_terminal_table_is_what_odelab_run_prints():
    rows = quoted("README.md", r"\$ odelab run experiments/exercise1.toml\n[^\n]*\n(ode23 [^\n]*)\n(ode45 [^\n]*)\n")
    r = runs("exercise1")
    for line in rows:
        case, method, points, steps, failed, fevals, quantity, max_abs, rel, status = line.split()
        got = r[case]
        e = got.errors[quantity]
        assert (got.case.solver.method if hasattr(got.case, "solver") else method) == method
        assert (got.t.size, got.stats.nsteps, got.stats.nfailed, got.stats.nfevals) == (
            int(points), int(steps), int(failed), int(fevals)), case
        assert (sci(e.max_abs), sci(e.headline)) == (max_abs, rel), case
        assert got.status == "success" and status == "ok"


def test_exercise1_headline_numbers():
    points, on_pi, on_2pi = quoted("README.md", r"\| (\d+) points, max relative error \*\*([\d.e-]+)\*\*; "
                                               r"\*\*([\d.e-]+)\*\* on \[0, 2 pi\]")
    ode23 = runs("exercise1")["ode23"]
    assert ode23.t.size == int(points)
    assert sci(ode23.errors["y"].headline) == on_pi
    assert sci(runs("exercise1_2pi")["ode23"].errors["y"].headline) == on_2pi
    pi, two_pi = quoted("docs/tutorials/coming-from-matlab.md", r"sin\(t\) \+ 2 is ([\d.e-]+) on \[0, pi\] and "
                                                                r"([\d.e-]+) \(the lab sheet's number\)")
    assert float(pi) == float(on_pi) and float(two_pi) == float(on_2pi)


def test_the_rigid_body_step_statistics():
    steps, failed, fevals = quoted("README.md", r"\*\*(\d+) steps, (\d+) failed, (\d+) evaluations\*\*, as MATLAB")
    s = runs("rigid_body")["ode45"].stats
    assert (s.nsteps, s.nfailed, s.nfevals) == (int(steps), int(failed), int(fevals))
    steps2, fevals2, points = quoted("docs/tutorials/coming-from-matlab.md",
                                     r"MATLAB's: (\d+) steps, (\d+) evaluations,\s+(\d+) points with Refine 4")
    assert (s.nsteps, s.nfevals, runs("rigid_body")["ode45"].t.size) == (int(steps2), int(fevals2), int(points))


def test_control_tutorial_quotes_the_analysis():
    dc, rise, settle, pm, wc = quoted(
        "docs/tutorials/control.md", r"DC gain ([\d.]+), RiseTime\s+([\d.]+) s, SettlingTime ([\d.]+) s, no overshoot, "
        r"phase margin ([\d.]+) deg at ([\d.]+) rad/s")
    a = next(r.extra["analysis"] for r in runs("exercise2").values() if "analysis" in r.extra)
    info = a["step_info"][0]
    assert f"{a['transfer_functions'][0]['dc_gain']:.4g}" == dc
    assert (f"{info['RiseTime']:.4g}", f"{info['SettlingTime']:.4g}", info["Overshoot"]) == (rise, settle, 0)
    margin = a["margins"][0]
    assert f"{margin['phase_margin']:.3g}" == pm and f"{margin['gain_crossover']:.2f}" == wc
    overshoot, settling = quoted("docs/tutorials/control.md", r"s\^3 \+ 4 s\^2 \+ 23 s \+ 15\) \(overshoot ([\d.]+) %, "
                                                              r"settling ([\d.]+) s\)")
    pi = next(r.extra["analysis"] for r in runs("feedback_pi").values() if "analysis" in r.extra)
    closed = next(i for i in pi["step_info"] if i.get("input") == "reference")
    assert (f"{closed['Overshoot']:.3g}", f"{closed['SettlingTime']:.3g}") == (overshoot, settling)


def test_events_tutorial_quotes_the_bounces():
    count, within = quoted("docs/tutorials/events.md", r"bouncing ball's (\d+) bounces in \[0, 10\] land within "
                                                       r"([\d.e-]+) s of the exact")
    ball = next(iter(runs("bouncing_ball").values()))
    assert len(ball.events) == int(count)
    worst = max(abs(e["t"] - e["exact_t"]) for e in ball.events)
    assert worst <= float(within) and worst > float(within) / 10  # "within 3e-13": of that size, not far below


@pytest.mark.parametrize("method, index", [("ode89", 0), ("ode45", 2)])
def test_high_order_tutorial_quotes_the_kepler_steps_and_errors(method, index):
    import numpy as np

    import odelab

    numbers = quoted("docs/tutorials/high-order.md", r"# (\d+) steps, error ([\d.e-]+); ode45: (\d+) steps, "
                                                     r"error ([\d.e-]+)")
    kepler = lambda t, y: [y[2], y[3], -y[0] / np.hypot(y[0], y[1]) ** 3, -y[1] / np.hypot(y[0], y[1]) ** 3]
    y0 = [0.4, 0, 0, 2]
    sol = getattr(odelab, method)(kepler, [0, 4 * np.pi], y0, RelTol=1e-12, AbsTol=1e-15)
    assert sol.stats.nsteps == int(numbers[index])
    # the orbit's period is 2 pi: after two, the exact solution is back at y0
    assert f"{np.max(np.abs(sol.y[-1] - y0)):.0e}" == numbers[index + 1]


def test_control_tutorial_quotes_the_loop_margins():
    pm, wc = quoted("docs/tutorials/control.md", r"with its margins: phase margin\s+([\d.]+) deg at ([\d.]+) rad/s, "
                                                 r"infinite gain margin")
    pi = next(r.extra["analysis"] for r in runs("feedback_pi").values() if "analysis" in r.extra)
    loop = pi["loop"]
    assert f"{loop['phase_margin']:.3g}" == pm and f"{loop['gain_crossover']:.3g}" == wc
    assert loop["gain_margin"] is None or loop["gain_margin"] == float("inf")


@lru_cache(maxsize=None)
def study_records(tmp: str) -> dict:
    """The sweep records of the shipped work-precision study and damping sweep, stored by `odelab run`."""
    import json

    from typer.testing import CliRunner

    from odelab.cli import app

    out = CliRunner().invoke(app, ["run", str(EXPERIMENTS / "work-precision.toml"), str(EXPERIMENTS / "damping.toml"),
                                   "--runs", tmp])
    assert out.exit_code == 0, out.output
    return {p.parent.name: json.loads(p.read_text(encoding="utf-8")) for p in Path(tmp).glob("*/sweep.json")}


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    return study_records(str(tmp_path_factory.mktemp("studies")))


def test_studies_tutorial_quotes_the_work_precision_of_the_rigid_body(studies):
    """The numbers of the report's work-precision table (tightest error, its evaluations, the
    evaluations' factor per digit, as the report prints it: ×{10**slope:.2f})."""
    (ode23, ode45, dop853, ode78_err, ode78, f23, f45, fdop, f78, ode113_err, ode113, f113) = quoted(
        "docs/tutorials/studies.md",
        r"costs ode23 (\d+) function evaluations, ode45 (\d+) and DOP853 under (\d+) \(ode78 reaches ([\d.e-]+) "
        r"with (\d+)\); each further digit multiplies ode23's work by ([\d.]+), ode45's by ([\d.]+), DOP853's by "
        r"([\d.]+) and ode78's by ([\d.]+) \(about 10\^\(1/p\) for order p\)\. ode113 \(variable order up to 13, two "
        r"evaluations a step\) reaches ([\d.e-]+) with (\d+) evaluations, x([\d.]+) per digit")
    curves = {c["label"]: c for c in studies["work-precision_rigid_body"]["study"]["curves"]}

    def tightest(label):
        return int(curves[label]["nfevals"][-1])

    def per_digit(label):
        return f"{10 ** curves[label]['slope']:.2f}"

    assert (tightest("ode23"), tightest("ode45"), tightest("DOP853"), tightest("ode78"), tightest("ode113")) == (
        int(ode23), int(ode45), int(dop853), int(ode78), int(ode113))
    assert [per_digit(m) for m in ("ode23", "ode45", "DOP853", "ode78", "ode113")] == [f23, f45, fdop, f78, f113]
    assert f"{curves['ode78']['error'][-1]:.0e}" == ode78_err
    assert f"{curves['ode113']['error'][-1]:.2g}" == f"{float(ode113_err):.2g}"
    # "an error of about 5e-8": ode23's and ode45's tightest, within a factor 3 of it
    for m in ("ode23", "ode45"):
        assert 5e-8 / 3 <= curves[m]["error"][-1] <= 5e-8 * 3, m


def test_studies_tutorial_quotes_the_damping_sweep(studies):
    overshoot, b0, critical, within = quoted(
        "docs/tutorials/studies.md", r"overshoot \((\d+) % at b = ([\d.]+), none above critical damping "
                                     r"b = ([\d.]+): at most ([\d.e-]+) %")
    rows = {row["swept"]["parameters.b"]: row["metrics"]["y"]["overshoot_percent"] for row in studies["damping"]["rows"]}
    assert round(rows[float(b0)]) == int(overshoot)
    import math

    assert f"{2 * math.sqrt(3.0 * 1.0):.2f}" == critical  # b = 2 sqrt(k m), Exercise 2's k = 3, m = 1
    above = [v for b, v in rows.items() if b > float(critical)]
    assert above and max(above) <= float(within) and max(above) > float(within) / 10
    assert min(v for b, v in rows.items() if b < float(critical)) > 0.1  # below it, a real overshoot


def test_python_guide_quotes_the_ode15s_steps_on_van_der_pol():
    import odelab

    (steps,) = quoted("docs/guide/python.md", r"odelab.ode15s\(vdp, \[0, 3000\], \[2, 0\]\) # (\d+) steps;")
    vdp = lambda t, y: [y[1], 1000 * (1 - y[0] ** 2) * y[1] - y[0]]
    assert odelab.ode15s(vdp, [0, 3000], [2, 0]).stats.nsteps == int(steps)
