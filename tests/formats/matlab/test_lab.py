"""The lab's own MATLAB files: imported, they run bit for bit as the experiment files written for them."""

from pathlib import Path

import numpy as np
import pytest

from odelab.exceptions import ExperimentError
from odelab.experiment.loader import load_experiments
from odelab.formats import read
from odelab.formats.base import ImportOptions
from odelab.run.runner import run_experiment

ROOT = Path(__file__).resolve().parents[3]
LAB = ROOT / "tests" / "assets" / "matlab" / "lab"


def _run(path, call=None):
    (exp,) = load_experiments(path, options=ImportOptions(call=call))
    return run_experiment(exp)


def _case(path, name):
    return next(r for r in run_experiment(path) if r.case.name == name)


def test_rigid_gives_matlabs_output_points_and_statistics_as_rigid_body_toml():
    (imported,) = _run(LAB / "run_rigid.m")
    written = _case(ROOT / "experiments" / "rigid_body.toml", "ode45")
    assert np.array_equal(imported.t, written.t) and np.array_equal(imported.x, written.x)
    assert imported.stats == written.stats
    assert (imported.stats.nsteps, imported.stats.nfailed, imported.stats.nfevals, imported.t.size) == (21, 0, 127, 85)


@pytest.mark.parametrize("span, toml", [("[0 pi]", "exercise1.toml"), ("[0 2*pi]", "exercise1_2pi.toml")])
def test_eq1_with_the_call_runs_as_exercise1(span, toml):
    (imported,) = _run(LAB / "eq1.m", f"[t,y] = ode23(@eq1, {span}, 2)")
    written = _case(ROOT / "experiments" / toml, "ode23")
    assert np.array_equal(imported.t, written.t) and np.array_equal(imported.x, written.x)
    exact = np.sin(imported.t) + 2
    error = np.max(np.abs(imported.x[:, 0] - exact) / np.abs(exact))
    assert f"{error:.3e}" == ("1.068e-04" if span == "[0 pi]" else "6.907e-04")  # the lab sheet's 6.907e-4


def test_eq1_alone_is_the_system_with_its_span_and_initial_value_as_gaps():
    doc = read(LAB / "eq1.m")
    assert doc.format == "matlab" and doc.data["system"] == {"states": ["y"], "equations": {"y": "cos(t)"}}
    assert [(g.where, g.construct) for g in doc.gaps] == [("line 1", "function eq1")]
    assert '# GAP: eq1.m has no solver call: the initial values come with it' in doc.text
    assert "# y = ...\n" in doc.text and "# stop = ...\n" in doc.text
    with pytest.raises(ExperimentError) as info:
        load_experiments(LAB / "eq1.m")
    assert "could not be translated completely (1 gap): line 1: function eq1: no solver call" in str(info.value)
