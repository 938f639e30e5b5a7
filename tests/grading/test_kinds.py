"""Each check kind on small classes whose right answers are known in closed form, and the matching
of a student's experiment by its system."""

from __future__ import annotations

import math

import pytest
from grading_support import EXERCISE1, EXERCISE1_RUBRIC, EXERCISE2, ROOT, by_name

from odelab.grading import grade_class

EX2_RUBRIC = """\
title = "Lab 5, Exercise 2"
reference = "reference/"
submissions = "submissions/"

[[check]]
name = "step response"
experiment = "exercise2"
case = "step-ode45"
kind = "trajectory"
quantity = "y"
tolerance = { abs = 1e-3 }
points = 3

[[check]]
name = "settling time"
experiment = "exercise2"
case = "step-ode45"
kind = "stepinfo"
metric = "SettlingTime"
quantity = "y"
tolerance = { rel = 0.01 }

[[check]]
name = "steady state"
experiment = "exercise2"
case = "step-ode23"
kind = "final"
quantity = "y"
tolerance = { rel = 0.01 }

[[check]]
name = "A"
experiment = "exercise2"
case = "step-ode45"
kind = "matrix"
matrix = "A"
tolerance = { abs = 1e-12 }
"""


@pytest.fixture(scope="module")
def exercise2_class(tmp_path_factory):
    from grading_support import write_class

    root = tmp_path_factory.mktemp("ex2")
    students = {
        "correct": {"exercise2.toml": EXERCISE2},
        "stiffer-spring": {"exercise2.toml": EXERCISE2.replace("k = 3\n", "k = 2\n")},
        # the first case's step only (step-ode45); step-ode23 keeps its unit step
        "bigger-step": {"exercise2.toml": EXERCISE2.replace('inputs.f = { type = "step", time = 0, final = 1 }',
                                                            'inputs.f = { type = "step", time = 0, final = 2 }', 1)},
    }
    return by_name(grade_class(write_class(root, {"exercise2.toml": EXERCISE2}, students, EX2_RUBRIC)))


def test_exercise2_correct_student_passes_every_kind(exercise2_class):
    s = exercise2_class["correct"]
    assert [o.passed for o in s.outcomes] == [True] * 4 and s.score == 6
    # y = q x of the unit step: the steady state is q / k = 10 / 3
    assert float(s.outcomes[2].reference) == pytest.approx(10 / 3, rel=1e-3)
    # y = 10/3 (1 - 1.5 e^-t + 0.5 e^-3t) settles within 2 % when 1.5 e^-t = 0.02: t = ln 75 = 4.317 s
    assert float(s.outcomes[1].reference) == pytest.approx(math.log(75), rel=0.01)


def test_a_wrong_parameter_is_named(exercise2_class):
    s = exercise2_class["stiffer-spring"]
    trajectory, settling, final, A = s.outcomes
    assert not trajectory.passed and not final.passed and not A.passed
    assert "parameters.k is 2 where the reference has 3" in trajectory.differences
    assert "system.A[1][0] is -2 where the reference has -3" in trajectory.differences
    # y(10) = q x(10) of 1 / (s^2 + 4 s + 2) from rest: poles p1,2 = -2 +- sqrt(2) (ode23 at RelTol 1e-3)
    p1, p2 = -2 + math.sqrt(2), -2 - math.sqrt(2)
    exact = 10 * (1 / (p1 * p2) + math.exp(10 * p1) / (p1 * (p1 - p2)) + math.exp(10 * p2) / (p2 * (p2 - p1)))
    assert float(final.student) == pytest.approx(exact, rel=1e-3)
    assert A.summary.startswith("A[1][0] is -2 where the reference's is -3")


def test_a_wrong_input_is_named(exercise2_class):
    s = exercise2_class["bigger-step"]
    trajectory, settling, final, A = s.outcomes
    assert A.passed and settling.passed  # the model is right; a step twice as big settles as fast
    assert not trajectory.passed and final.passed
    assert trajectory.differences == ["inputs.f.final is 2 where the reference has 1"]


def test_matched_by_system_up_to_renaming(make_class):
    renamed = (EXERCISE1.replace('title = "Exercise 1: dy/dt = cos(t), y(0) = 2"', 'title = "my first ODE"')
               .replace('states = ["y"]', 'states = ["z"]').replace('y = "cos(t)"', 'z = "cos(t)"')
               .replace("y = 2\n", "z = 2\n").replace('y = "sin(t) + 2"', 'z = "sin(t) + 2"'))
    assert renamed.count("z") >= 4
    other = EXERCISE1.replace('title = "Exercise 1: dy/dt = cos(t), y(0) = 2"', 'title = "another ODE"').replace(
        'y = "cos(t)"', 'y = "sin(t)"')
    grades = by_name(grade_class(make_class({"alice": {"mine.toml": renamed},
                                             "bob": {"lab.toml": other}})))
    alice = grades["alice"]
    assert alice.score == 3, [o.summary for o in alice.outcomes]
    assert alice.matched["exercise1"].startswith("found by its system")
    assert "headline relative error of z" in alice.outcomes[0].summary
    assert grades["bob"].outcomes[0].summary == "not found: expected exercise1"


def test_matched_by_system_with_states_in_another_order(tmp_path):
    """Exercise 2 written as equations, velocity first: the same system up to renaming and order."""
    from grading_support import write_class

    equations = EXERCISE2.split("[system]")[0] + """\
[system]
states = ["w", "p"]
inputs = ["u"]
[system.equations]
w = "(u - b*w - k*p)/m"
p = "w"
[system.outputs]
y = "q*p"
[initial]
p = 0
w = 0
[time]
stop = 10
[[case]]
name = "step-ode45"
inputs.u = { type = "step", time = 0, final = 1 }
"""
    equations = equations.replace('title = "Exercise 2: mass-spring-damper as a state-space model"',
                                  'title = "my mass-spring-damper"')
    rubric = EX2_RUBRIC.split('[[check]]\nname = "steady state"')[0] + (
        '[[check]]\nname = "A"\nexperiment = "exercise2"\ncase = "step-ode45"\nkind = "matrix"\nmatrix = "A"\n'
        'tolerance = { abs = 1e-9 }\n')
    grades = by_name(grade_class(write_class(tmp_path, {"exercise2.toml": EXERCISE2},
                                             {"eq": {"msd.toml": equations}}, rubric)))
    s = grades["eq"]
    assert s.matched["exercise2"].startswith("found by its system")
    assert [o.passed for o in s.outcomes] == [True, True, True], [o.summary for o in s.outcomes]


BALL = (ROOT / "experiments" / "bouncing_ball.toml").read_text()
BALL_RUBRIC = """\
reference = "reference/"
submissions = "submissions/"
[[check]]
name = "bounces"
experiment = "ball"
kind = "events"
event = "floor"
tolerance = { abs = 1e-3 }
"""


def test_events(tmp_path):
    from grading_support import write_class

    students = {"right": {"ball.toml": BALL}, "bouncier": {"ball.toml": BALL.replace("e = 0.8 ", "e = 0.85")},
                "higher": {"ball.toml": BALL.replace("h0 = 10", "h0 = 10.2")}}
    grades = by_name(grade_class(write_class(tmp_path, {"ball.toml": BALL}, students, BALL_RUBRIC)))
    right = grades["right"].outcomes[0]
    assert right.passed and right.reference == "7"  # seven bounces before t = 10 (the file's closed form)
    # bounce k at t1 (1 + 2 e (1 - e^k) / (1 - e)), t1 = sqrt(2 h0 / g): with e = 0.85, five before t = 10
    bouncier = grades["bouncier"].outcomes[0]
    assert not bouncier.passed and bouncier.summary == "events 'floor': yours 5, the reference's 7"
    assert bouncier.differences == ["parameters.e is 0.85 where the reference has 0.8"]
    # dropped from 10.2 m: still seven bounces, the first at sqrt(2 * 10.2 / 9.81) = 1.442 s, not 1.428 s
    higher = grades["higher"].outcomes[0]
    assert not higher.passed
    assert higher.summary.startswith("events 'floor': event 1 at t = 1.442 where the reference's is at t = 1.428")
    assert "parameters.h0 is 10.2 where the reference has 10" in higher.differences


def test_matrix_of_a_linearisation(tmp_path):
    """An equations system's A is its Jacobian at the equilibrium for zero input (x = 0: k1, not k1 + 3 k3 x^2)."""
    from grading_support import write_class

    spring = """\
title = "hardening spring"
[parameters]
m = 1
b = 4
k1 = 3
k3 = 2
[system]
states = ["x", "v"]
inputs = ["f"]
[system.equations]
x = "v"
v = "(f - b*v - k1*x - k3*x^3)/m"
[initial]
x = 0
v = 0
[time]
stop = 1
[inputs]
f = { type = "constant", value = 0 }
"""
    rubric = ('reference = "reference/"\nsubmissions = "submissions/"\n[[check]]\nname = "A"\nexperiment = '
              '"spring"\nkind = "matrix"\nmatrix = "A"\ntolerance = { abs = 1e-9 }\n[[check]]\nname = "B"\n'
              'experiment = "spring"\nkind = "matrix"\nmatrix = "B"\ntolerance = { abs = 1e-9 }\n')
    students = {"right": {"spring.toml": spring.replace("k3 = 2", "k3 = 5")},  # k3 does not enter A at x = 0
                "wrong": {"spring.toml": spring.replace("k1 = 3", "k1 = 4")}}
    grades = by_name(grade_class(write_class(tmp_path, {"spring.toml": spring}, students, rubric)))
    assert grades["right"].score == 2
    A, B = grades["wrong"].outcomes
    assert not A.passed and B.passed
    assert A.summary.startswith("A[1][0] is -4 where the reference's is -3")


def test_a_headline_of_the_headline_rubric_on_exercise1_2pi(make_class):
    """The lab sheet's number: ode23 on [0, 2 pi] has a maximum relative error of 6.907e-4."""
    from grading_support import write_class  # noqa: F401

    two_pi = (ROOT / "experiments" / "exercise1_2pi.toml").read_text()
    rubric = EXERCISE1_RUBRIC.replace('"exercise1"', '"exercise1_2pi"')
    grades = by_name(grade_class(make_class({"alice": {"exercise1_2pi.toml": two_pi}},
                                            reference={"exercise1_2pi.toml": two_pi}, rubric=rubric)))
    headline = grades["alice"].outcomes[0]
    assert headline.passed and float(headline.reference) == pytest.approx(6.907e-4, rel=1e-3)


def test_a_trajectory_with_fewer_output_points_still_passes(make_class):
    """Refine = 1 (ode45's steps only): the spline through them is within 1e-3 of the reference's Refine = 4."""
    from grading_support import write_class  # noqa: F401

    sparse = EXERCISE2.replace('name = "step-ode45"\n', 'name = "step-ode45"\nsolver.Refine = 1\n')
    assert sparse != EXERCISE2
    rubric = EX2_RUBRIC.split('[[check]]\nname = "settling time"')[0]
    grades = by_name(grade_class(make_class({"sparse": {"exercise2.toml": sparse}, "same": {"exercise2.toml": EXERCISE2}},
                                            reference={"exercise2.toml": EXERCISE2}, rubric=rubric)))
    assert grades["same"].outcomes[0].student == "0"  # the same points: the spline passes through them
    sparse_outcome = grades["sparse"].outcomes[0]
    assert sparse_outcome.passed, sparse_outcome.summary
    assert 0 < float(sparse_outcome.student) < 1e-3


def test_a_case_renamed_is_graded_by_position_and_said_so(make_class):
    renamed = EXERCISE1.replace('name = "ode23"', 'name = "first"').replace('name = "ode45"', 'name = "second"')
    grades = by_name(grade_class(make_class({"alice": {"exercise1.toml": renamed},
                                             "bob": {"exercise1.toml": renamed.replace('[[case]]\nname = "second"\n'
                                                                                       'solver.method = "ode45"', "")}})))
    alice = grades["alice"]
    assert alice.score == 3
    assert alice.notes == ["exercise1 has no case named 'ode23': your case 1, named 'first', was graded in its place."]
    bob = grades["bob"]  # one case where the reference has two: no guessing
    assert bob.score == 0
    assert bob.outcomes[0].summary == "not found: expected case 'ode23' in exercise1 (your cases: first)"
