"""The report's fit section says how the Jacobian was taken, also for fits stored before it was said."""

from __future__ import annotations

import json

from conftest import EXPERIMENTS, odelab_run
from report_support import build

EXACT = "with the exact Jacobian from forward sensitivities"
DIFFERENCED = "with the Jacobian by central differences of the FMU's runs"


def test_a_fit_stored_without_the_jacobian_key_is_reported_as_before(tmp_path):
    runs = tmp_path / "runs"
    assert odelab_run([EXPERIMENTS / "cooling_fit.toml"], runs).exit_code == 0
    stored = sorted(runs.rglob("result.json"))
    assert stored
    for path in stored:
        data = json.loads(path.read_text())
        assert data["extra"]["fit"]["jacobian"] == "sensitivities" and data["extra"]["fit"]["fmu_runs"] is None
        for key in ("jacobian", "fmu_runs"):  # as odelab wrote fits before these keys
            del data["extra"]["fit"][key]
        path.write_text(json.dumps(data))
    report = build(runs, tmp_path / "report")
    assert EXACT in report.html and EXACT in report.md
    assert DIFFERENCED not in report.html


def test_a_differenced_fit_says_so_and_counts_the_runs(tmp_path):
    runs = tmp_path / "runs"
    assert odelab_run([EXPERIMENTS / "cooling_fit.toml"], runs).exit_code == 0
    for path in runs.rglob("result.json"):
        data = json.loads(path.read_text())
        data["extra"]["fit"].update(jacobian="differences", fmu_runs=21)
        path.write_text(json.dumps(data))
    report = build(runs, tmp_path / "report")
    assert DIFFERENCED in report.html and "21 runs of the FMU" in report.md
    assert EXACT not in report.html
