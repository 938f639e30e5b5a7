"""Any folder of FMUs run as kind = "fmu" and by FMPy's own simulation, compared: set
ODELAB_FMUS to the folder (the Modelica Association's Reference FMUs built with cmake, a
supplier's FMUs). Each FMU runs on each interface it offers (Model Exchange: ode45 at 1e-10;
Co-Simulation: at its DefaultExperiment's step) over its DefaultExperiment (ode15s where ode45 runs out of steps: a stiff model),
and its states and outputs must equal FMPy's (CVode at 1e-10, or FMPy's co-simulation at the same
step) within 1e-6 of their largest value. Without
ODELAB_FMUS the tests skip; odelab's own test FMUs run this way in test_import.py."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")

FOLDER = os.environ.get("ODELAB_FMUS")
FMUS = sorted(Path(FOLDER).glob("*.fmu")) if FOLDER else []


def compare(fmu: Path, tmp_path: Path, interface: str) -> dict[str, float]:
    """The largest difference over the largest value of each state and output, odelab against FMPy."""
    from odelab.fmi import allow_native
    from odelab.fmi.fmu import open_fmu
    from odelab.run.runner import run_experiment

    model = open_fmu(fmu)
    start = model.default.get("startTime", 0.0)
    stop = model.default.get("stopTime", start + 1.0)
    if interface not in model.interfaces:
        pytest.skip(f"{fmu.name} offers no {interface}")
    me = interface == "model-exchange"
    step = model.default.get("stepSize") or (stop - start) / 500
    points = int(round((stop - start) / step)) + 1
    for method in ("ode45", "ode15s"):  # a stiff model (Roberts) stops ode45 at its step budget
        toml = (f'[system]\nkind = "fmu"\nfile = "{fmu}"\ninterface = "{"model-exchange" if me else "co-simulation"}"\n'
                f"[time]\nstart = {start!r}\nstop = {stop!r}\npoints = {points}\n"
                f"[solver]\nmethod = \"{method}\"\nrtol = 1e-10\natol = 1e-12\nmax_steps = 100000\n")
        path = tmp_path / f"{fmu.stem}.toml"
        path.write_text(toml)
        with allow_native():
            (r,) = run_experiment(path)
        if r.status == "success":
            break
    assert r.status == "success", r.message
    names = [*r.case.problem.states, *r.case.problem.outputs]
    mine = np.column_stack([r.x, r.y]) if r.y is not None else r.x
    kwargs = {"solver": "CVode"} if me else {}
    try:
        theirs = fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange" if me else "CoSimulation", start_time=start,
                                   stop_time=stop, output_interval=step, relative_tolerance=1e-10, output=names,
                                   **kwargs)
    except Exception as exc:  # FMPy's own run failed (its CVode's step limit on Roberts at 1e-10): nothing to compare
        pytest.skip(f"FMPy's own simulation failed: {str(exc)[:200]}")
    # at an event both record the value before and after: compare the last row of each time
    last_mine = {round(t, 9): i for i, t in enumerate(r.t)}
    last_theirs = {round(t, 9): i for i, t in enumerate(theirs["time"])}
    common = sorted(set(last_mine) & set(last_theirs))
    assert len(common) >= points // 2
    rows_mine = [last_mine[t] for t in common]
    rows_theirs = [last_theirs[t] for t in common]
    out = {}
    for j, name in enumerate(names):
        a, b = mine[rows_mine, j], np.asarray(theirs[name], dtype=float)[rows_theirs]
        out[name] = float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))
    return out


@pytest.mark.skipif(not FMUS, reason="set ODELAB_FMUS to a folder of FMUs")
@pytest.mark.parametrize("interface", ["model-exchange", "co-simulation"])
@pytest.mark.parametrize("fmu", FMUS, ids=lambda p: p.stem)
def test_a_folders_fmu_equals_fmpys_simulation(fmu, interface, tmp_path):
    from odelab.exceptions import InputError

    try:
        differences = compare(fmu, tmp_path, interface)
    except InputError as exc:  # what odelab says it does not load (Scheduled Execution, arrays): said, skipped
        pytest.skip(exc.message)
    assert max(differences.values(), default=0.0) < 1e-6, differences
