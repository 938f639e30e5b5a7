"""The report's "Why stiff solvers" part, from the shipped experiments/stiff.toml run by `odelab run`."""

import re


def test_stiff_section_shows_what_each_method_paid(lab_runs, lab_report):
    md = lab_report.md
    part = md.split("### Why stiff solvers", 1)[1].split("\n### ", 1)[0]
    rows = {cells[1]: cells for cells in (
        [c.strip() for c in line.strip("|").split("|")] for line in part.splitlines() if line.startswith("| ode"))}
    assert set(rows) >= {"ode45", "ode15s", "ode23s", "ode23t", "ode23tb"}
    # ode45 stopped by its step limit far from the end; the stiff solvers crossed [0, 3000]
    assert rows["ode45"][3] == "failed" and float(rows["ode45"][4]) < 100 and rows["ode45"][5] == "20000"
    for name in ("ode15s", "ode23s", "ode23t", "ode23tb"):
        assert rows[name][2].startswith("stiff") and rows[name][3] == "success" and rows[name][4] == "3000"
        assert int(rows[name][5]) < 800 and int(rows[name][8]) >= 1  # steps; Jacobians counted
    # the exact Jacobian came from the equations: no finite-difference evaluations in ode15s's count
    assert int(rows["ode15s"][7]) == 2 + int(rows["ode15s"][10])
    summary = re.search(r"Over the whole span ode15s took (\d+) steps .* ode45 stopped at t = ([\d.]+) of 3000 "
                        r"after 20,000 steps \(at that pace the whole span would take about ([\d,]+) steps\)", part)
    assert summary and int(summary.group(3).replace(",", "")) > 1_000_000
    assert (lab_report.out / "figures" / "stiff-step-size.png").stat().st_size > 10_000
    assert 'id="fig-stiff-step-size"' in lab_report.html and "<h3>Why stiff solvers</h3>" in lab_report.html


def test_no_stiff_section_without_a_stiff_method(lab_report):
    sections = lab_report.md.split("\n## ")
    for section in sections:
        if "ode15s" not in section and "Radau" not in section and "ode23s" not in section:
            assert "### Why stiff solvers" not in section
