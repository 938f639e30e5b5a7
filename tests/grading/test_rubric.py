"""The rubric file: the prescribed syntax, and one message per mistake naming the key path and the fix."""

from __future__ import annotations

import pytest
from grading_support import EXERCISE1, EXERCISE1_RUBRIC
from typer.testing import CliRunner

from odelab.grading import RubricError, grade_class, load_rubric

HEAD = 'title = "Lab 5"\nreference = "reference/"\n'


def rubric_error(tmp_path, text: str) -> RubricError:
    path = tmp_path / "rubric.toml"
    path.write_text(text)
    with pytest.raises(RubricError) as info:
        load_rubric(path)
    assert info.value.source == str(path)
    return info.value


def test_the_issues_rubric_loads(tmp_path):
    path = tmp_path / "rubric.toml"
    path.write_text(EXERCISE1_RUBRIC)
    rubric = load_rubric(path)
    assert rubric.title == "Lab 5" and rubric.max_score == 3
    assert rubric.reference == (tmp_path / "reference/",) and rubric.submissions == tmp_path / "submissions/"
    headline, solver = rubric.checks
    assert (headline.kind, headline.quantity, headline.rel, headline.abs, headline.points) == (
        "headline", "y", 0.01, None, 2.0)
    assert solver.solver == {"method": ("method", "ode23"), "rtol": ("RelTol", 1e-3)}  # MATLAB's name accepted


@pytest.mark.parametrize("body, key, words", [
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "headline"\nquantity = "y"\ntolerance = { rel = 0.01 }\n'
     'pionts = 2\n', "check[0].pionts", "Did you mean `points`?"),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "headlines"\n', "check[0].kind",
     "Did you mean 'headline'?"),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "final"\ntolerance = { rel = 0.01 }\n', "check[0].quantity",
     'add quantity = "y"'),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "stepinfo"\nquantity = "y"\nmetric = "SettleTime"\n'
     'tolerance = { rel = 0.01 }\n', "check[0].metric", "Did you mean 'SettlingTime'?"),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "solver"\nRelTl = 1e-3\n', "check[0].RelTl",
     "Did you mean `RelTol`?"),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "solver"\n', "check[0]", "no [solver] key to compare"),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "headline"\nquantity = "y"\ntolerance = { rel = -1 }\n',
     "check[0].tolerance.rel", "must be a finite number >= 0"),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "solver"\nmethod = "ode23"\nquantity = "y"\n',
     "check[0].quantity", "is for kind ="),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "matrix"\nmatrix = "E"\ntolerance = { abs = 0 }\n',
     "check[0].matrix", 'one of "A", "B", "C", "D"'),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "solver"\nmethod = "ode23"\n[[check]]\nname = "a"\n'
     'experiment = "e"\nkind = "solver"\nmethod = "ode45"\n', "check[1].name", "give each check its own name"),
    ('[[check]]\nname = "a"\nexperiment = "e"\nkind = "solver"\nmethod = "ode23"\npoints = "two"\n',
     "check[0].points", "must be a number"),
])
def test_mistakes_are_named_by_key_path(tmp_path, body, key, words):
    err = rubric_error(tmp_path, HEAD + body)
    assert err.key == key and words in err.message, err.message


def test_missing_reference_and_checks(tmp_path):
    assert rubric_error(tmp_path, 'title = "x"\n[[check]]\nname = "a"\nexperiment = "e"\nkind = "solver"\n'
                        'method = "ode23"\n').key == "reference"
    err = rubric_error(tmp_path, HEAD)
    assert err.key == "check" and "add at least one [[check]]" in err.message
    assert "Did you mean `reference`" in rubric_error(tmp_path, HEAD + 'referense = "x"\n').message


def test_checks_are_checked_against_the_reference(make_class):
    bad_experiment = EXERCISE1_RUBRIC.replace('experiment = "exercise1"\ncase = "ode23"\nkind = "headline"',
                                              'experiment = "exercise_1"\ncase = "ode23"\nkind = "headline"')
    with pytest.raises(RubricError) as info:
        grade_class(make_class({}, rubric=bad_experiment))
    assert info.value.key == "check[0].experiment" and "Did you mean 'exercise1'?" in info.value.message


@pytest.mark.parametrize("old, new, key, words", [
    ('case = "ode23"\nkind = "headline"', 'case = "ode32"\nkind = "headline"', "check[0].case",
     "Did you mean 'ode23'?"),
    ('quantity = "y"', 'quantity = "x"', "check[0].quantity", "not a state, input or output"),
    ('case = "ode23"\nkind = "headline"', 'kind = "headline"', "check[0].case", "name the one to grade"),
])
def test_cases_and_quantities_are_checked(tmp_path, old, new, key, words):
    from grading_support import write_class

    rubric = write_class(tmp_path, {"exercise1.toml": EXERCISE1}, {}, EXERCISE1_RUBRIC.replace(old, new, 1))
    with pytest.raises(RubricError) as info:
        grade_class(rubric)
    assert info.value.key == key and words in info.value.message, info.value.message


def test_a_headline_needs_a_reference_error(tmp_path):
    from grading_support import write_class

    no_exact = EXERCISE1.replace('[exact]                  # analytical solution: enables the error tables\n'
                                 'y = "sin(t) + 2"', "")
    assert no_exact != EXERCISE1
    rubric = write_class(tmp_path, {"exercise1.toml": no_exact}, {}, EXERCISE1_RUBRIC)
    with pytest.raises(RubricError) as info:
        grade_class(rubric)
    assert info.value.key == "check[0]" and "has no error for it" in info.value.message


def test_cli_bad_rubric_is_exit_2_with_one_message(tmp_path):
    from odelab.cli import app

    path = tmp_path / "rubric.toml"
    path.write_text(HEAD + '[[check]]\nname = "a"\nexperiment = "e"\nkind = "headlines"\n')
    result = CliRunner().invoke(app, ["grade", str(path)])
    assert result.exit_code == 2
    assert "error:" in result.stderr and "rubric.toml" in result.stderr and "check[0].kind" in result.stderr
    assert "Traceback" not in result.output


def test_cli_missing_submissions_folder_is_exit_2(make_class, tmp_path):
    from odelab.cli import app

    rubric = make_class({"alice": {"exercise1.toml": EXERCISE1}})
    result = CliRunner().invoke(app, ["grade", str(rubric), str(tmp_path / "nowhere"), "--out", str(tmp_path / "g")])
    assert result.exit_code == 2 and "the submissions folder does not exist" in result.stderr
    assert not (tmp_path / "g").exists()  # nothing written
