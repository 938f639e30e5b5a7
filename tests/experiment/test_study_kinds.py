"""Study kinds are registered classes (odelab.experiment.studykinds): a toy kind registered in the test is
read from TOML with its own key, computed, shown in the terminal and drawn in the report."""

import math

import numpy as np
import pytest
from rich.console import Console

from odelab.exceptions import ExperimentError
from odelab.cli.display import print_sweep
from odelab.experiment.keyref import explain
from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_experiment
from odelab.store.sweeps import sweep_record
from odelab.experiment.studykinds import STUDY_KINDS, StudyKind, fmt_number, register_study_kind
from odelab.report.studies import study_sections
from odelab.report.study_sections import SECTIONS, register_section
from odelab.cli.study_views import TERMINAL_VIEWS, register_terminal_view

DECAY = """
[system]
states = ["x"]
[system.equations]
x = "-x"
[time]
stop = 5
[initial]
x = 1
[exact]
x = "exp(-t)"
[solver]
method = "ode45"
atol = 1e-14     # the relative tolerance alone sets the error
max_step = 5     # and the steps
[sweep]
"solver.rtol" = [1e-5, 1e-6, 1e-7, 1e-8, 1e-9]
[study]
{study}
"""


@pytest.fixture
def steps_kind():
    """A toy kind: the error against the number of steps, whose log-log slope is minus the order."""

    @register_study_kind
    class Steps(StudyKind):
        NAME = "steps"
        DOC = "error against the number of steps"
        KEYS = {"min_steps": 1}
        DOCS = {"min_steps": "cases with fewer steps are left out of the fit."}
        ERROR = "end"

        def curve(self, spec, label, x, err, members):
            n = np.array([m["nsteps"] for m in members], dtype=float)
            e = np.array(err, dtype=float)
            ok = (n >= spec.options["min_steps"]) & np.isfinite(e) & (e > 0)
            slope = float(np.polyfit(np.log10(n[ok]), np.log10(e[ok]), 1)[0]) if ok.sum() >= 2 else math.nan
            return {"label": label, "method": members[0]["method"], "steps": n.tolist(), "error": e.tolist(),
                    "slope": slope}, []

    yield STUDY_KINDS["steps"]
    del STUDY_KINDS["steps"]


@pytest.fixture
def steps_views(steps_kind):
    """The toy kind's own terminal table and report section (the views live with the CLI and the report)."""

    @register_terminal_view("steps")
    def terminal(study, over):
        return ("error against steps:", ["method", "slope"],
                [[c["label"], f"{c['slope']:.2f}"] for c in study["curves"]])

    @register_section("steps")
    def draw(record, study, section):
        section.summary = "Error against the number of steps."
        section.header = ["method", "slope"]
        section.rows = [[c["label"], fmt_number(c["slope"], 3)] for c in study["curves"]]

    yield steps_kind
    del TERMINAL_VIEWS["steps"], SECTIONS["steps"]


def _file(tmp_path, study):
    path = tmp_path / "steps.toml"
    path.write_text(DECAY.format(study=study))
    return path


def test_a_registered_kind_runs_from_toml_and_reaches_terminal_and_report(steps_views, tmp_path):
    exp = load_experiment(_file(tmp_path, 'kind = "steps"\nmin_steps = 10'))
    assert exp.study.kind == "steps" and exp.study.over == "solver.rtol" and exp.study.error == "end"
    assert exp.study.options == {"min_steps": 10}
    record = sweep_record(exp, run_experiment(exp))
    (curve,) = record["study"]["curves"]
    assert record["study"]["min_steps"] == 10 and curve["method"] == "ode45"
    # ode45 is of order 5: the error at the end falls as (number of steps)^-5 (whole step counts: within 1)
    assert abs(curve["slope"] + 5) < 1, curve["slope"]
    console = Console(record=True, width=80)
    print_sweep(console, exp, run_experiment(exp))
    assert "error against steps:" in console.export_text()
    (section,), warnings = study_sections([record], set())
    assert not warnings and section.kind == "steps" and section.rows == [["ode45", fmt_number(curve["slope"], 3)]]


def test_a_kind_without_views_of_its_own_shows_its_numbers(steps_kind, tmp_path):
    exp = load_experiment(_file(tmp_path, 'kind = "steps"\nmin_steps = 10'))
    results = run_experiment(exp)
    record = sweep_record(exp, results)
    (curve,) = record["study"]["curves"]
    console = Console(record=True, width=100)
    print_sweep(console, exp, results)
    text = console.export_text()
    assert "steps of the x error over rtol:" in text and "slope" in text and fmt_number(curve["slope"]) in text
    (section,), warnings = study_sections([record], set())
    assert not warnings and section.header == ["curve", "method", "slope"]
    assert section.rows == [["ode45", "ode45", fmt_number(curve["slope"])]]


def test_its_name_and_keys_join_the_messages_and_explain(steps_kind, tmp_path):
    with pytest.raises(ExperimentError) as info:
        load_experiment(_file(tmp_path, 'kind = "order"'))
    assert info.value.message.startswith('`study.kind` is \'order\'; it must be "convergence" (error against step '
                                         'size or tolerance) or "work-precision" (error against cost) or "steps" '
                                         '(error against the number of steps).')
    with pytest.raises(ExperimentError) as info:
        load_experiment(_file(tmp_path, 'kind = "convergence"\nmin_steps = 10'))
    assert info.value.key == "study.min_steps" and "not a key of a convergence study" in info.value.message
    assert "steps" in explain("study.kind") and "cases with fewer steps" in explain("study.min_steps")


def test_without_it_the_key_is_unknown(tmp_path):
    with pytest.raises(ExperimentError) as info:
        load_experiment(_file(tmp_path, 'kind = "work-precision"\nmin_steps = 10'))
    assert info.value.message.startswith("unknown key `study.min_steps`.")


def test_a_kind_declares_its_name_and_keeps_off_the_common_keys():
    with pytest.raises(TypeError, match="declares NAME and DOC"):
        register_study_kind(type("Nameless", (StudyKind,), {}))
    with pytest.raises(ValueError, match="common keys"):
        register_study_kind(type("Clash", (StudyKind,), {"NAME": "clash", "DOC": "x", "KEYS": {"over": 1}}))
