"""Evaluating one check: the student's value, the reference's, and whether they agree.

Every kind reduces to numbers compared within the check's tolerance: a scalar passes when
``|student - reference| <= abs`` or ``<= rel * |reference|`` (either one given suffices). The
kinds:

- ``headline``: the headline relative error (analysis.errors.HEADLINE_RULE) of the student's
  run of ``quantity``, measured against the *reference's* exact solution (its [exact], or the
  exact LTI response of the reference's model) at the student's output times, so that a student
  who edits [exact] cannot change their own error;
- ``trajectory``: the student's ``quantity`` interpolated (a cubic spline through their output
  points) at the reference run's output times, against the reference run's values: the maximum deviation is compared with
  ``abs``, or the maximum deviation divided by max |reference| with ``rel``;
- ``final``: the value at the end of the span;
- ``stepinfo``: a MATLAB stepinfo metric of the run's ``quantity``, measured as MATLAB's
  ``stepinfo(y, t)`` does on data (final value y(end), initial value 0);
- ``events``: the number of located events (of ``event``, or all) must be the reference's, and
  each time must agree within the tolerance;
- ``matrix``: A, B, C or D of the state-space model (or of the linearisation about the
  equilibrium for zero input), each entry within ``abs`` or ``rel`` times max |entry|;
- ``solver``: each given [solver] key must be what the student's case used (defaults filled in
  as ``odelab run`` fills them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from odelab.exceptions import InputError
from odelab.grading.compare import NameMap, fmt
from odelab.grading.rubric import STEPINFO_METRICS, CheckSpec

__all__ = ["Outcome", "evaluate", "evaluate_solver", "evaluate_matrix", "failed", "within"]


@dataclass
class Outcome:
    """A graded check of one student."""

    check: CheckSpec
    score: float
    passed: bool
    summary: str  # one line: the student's value against the reference's, or why there is none
    student: str | None = None
    reference: str | None = None
    differences: list[str] = field(default_factory=list)  # what differs in the file (when failed)
    failure: str = ""  # a short reason, the same for students failing the same way (the class summary counts it)


def failed(check: CheckSpec, summary: str, reason: str, differences: list[str] | None = None) -> Outcome:
    return Outcome(check, 0.0, False, summary, differences=list(differences or []), failure=reason)


def within(check: CheckSpec, student: float, reference: float) -> bool:
    if not (math.isfinite(student) and math.isfinite(reference)):
        return student == reference  # both inf the same way; NaN never passes
    d = abs(student - reference)
    return (check.abs is not None and d <= check.abs) or (check.rel is not None and d <= check.rel * abs(reference))


def _scalar(check: CheckSpec, what: str, student: float, reference: float, differences) -> Outcome:
    ok = within(check, student, reference)
    text = f"{what}: yours {fmt(student)}, the reference's {fmt(reference)} (tolerance {check.tolerance_text()})"
    if ok:
        return Outcome(check, check.points, True, text, fmt(student), fmt(reference))
    return Outcome(check, 0.0, False, text, fmt(student), fmt(reference), list(differences),
                   failure=_reason(differences, f"{what} out of tolerance"))


def _reason(differences, default: str) -> str:
    return differences[0] if differences else default


def _series(result, name: str):
    return result.series().get(name)


def _truth(ref_result, t: np.ndarray, quantity: str):
    """The reference's exact values of ``quantity`` at times ``t``: its [exact] or its model's LTI response."""
    p = ref_result.case.problem
    kind = ref_result.reference_kind
    if kind == "exact" and p.system.exact_fn is not None:
        values = p.system.exact_fn(t)
        return None if quantity not in values else np.asarray(values[quantity], dtype=float)
    if kind == "lti" and t.size >= 2 and np.all(np.diff(t) > 0):
        from odelab.analysis.lti import lti_response

        x, y = lti_response(p.system.model, t, p.x0, u=list(p.system.signals) if p.system.signals else None)
        if quantity in p.states:
            return x[:, p.states.index(quantity)]
        if quantity in p.outputs:
            return y[:, p.outputs.index(quantity)]
    return None


def evaluate(check: CheckSpec, ref_result, stu_result, names: NameMap, differences: list[str]) -> Outcome:
    """Grade a check on a run (the kinds that need one: headline, trajectory, final, stepinfo, events)."""
    if stu_result.status != "success":
        return failed(check, f"your run did not finish: {stu_result.message}", "the run failed", differences)
    kind = check.kind
    if kind == "events":
        return _events(check, ref_result, stu_result, differences)
    q, mine = check.quantity, names.of(check.quantity)
    ys = _series(stu_result, mine)
    if ys is None:
        have = ", ".join(stu_result.series()) or "none"
        return failed(check, f"your case has no quantity {mine!r} (it has {have})", f"no quantity {q}")
    yr = _series(ref_result, q)
    ts, tr = stu_result.t, ref_result.t
    if kind == "headline":
        truth = _truth(ref_result, ts, q)
        from odelab.analysis.errors import summarize

        if truth is not None:
            student = summarize(q, ts, ys, truth).headline
        else:  # a high-accuracy reference: the run's own error, as odelab run reports it
            err = stu_result.errors.get(mine)
            student = err.headline if err is not None else None
        reference = ref_result.errors[q].headline
        if student is None:
            return failed(check, f"no relative error of {mine} could be measured for your run",
                          "no error measured", differences)
        return _scalar(check, f"headline relative error of {mine}", student, reference, differences)
    if kind == "final":
        if not math.isclose(float(ts[-1]), float(tr[-1]), rel_tol=1e-12, abs_tol=1e-12):
            return failed(check, f"your run ends at t = {fmt(ts[-1])}, the reference's at t = {fmt(tr[-1])}",
                          "another time span", differences)
        return _scalar(check, f"{mine} at t = {fmt(tr[-1])}", float(ys[-1]), float(yr[-1]), differences)
    if kind == "stepinfo":
        from odelab.analysis.control import step_metrics

        attr = STEPINFO_METRICS[check.metric]
        student = getattr(step_metrics(ts, ys, float(ys[-1])), attr)
        reference = getattr(step_metrics(tr, yr, float(yr[-1])), attr)
        return _scalar(check, f"{check.metric} of {mine}", float(student), float(reference), differences)
    # trajectory
    lo, hi = min(tr[0], tr[-1]), max(tr[0], tr[-1])
    order = np.argsort(ts, kind="stable")
    t_sorted = ts[order]
    if t_sorted[0] > lo + 1e-12 * max(1.0, abs(lo)) or t_sorted[-1] < hi - 1e-12 * max(1.0, abs(hi)):
        return failed(check, f"your run covers t = {fmt(t_sorted[0])} to {fmt(t_sorted[-1])}, not the reference's "
                      f"{fmt(tr[0])} to {fmt(tr[-1])}", "another time span", differences)
    at = ys if ts.shape == tr.shape and np.array_equal(ts, tr) else _interpolate(t_sorted, ys[order], tr)
    deviation = float(np.max(np.abs(at - yr)))
    scale = float(np.max(np.abs(yr)))
    ok = (check.abs is not None and deviation <= check.abs) or (
        check.rel is not None and deviation <= check.rel * scale)
    text = (f"{mine} at the reference's {tr.size} output times: largest deviation {fmt(deviation)} "
            f"(of a peak {fmt(scale)}; tolerance {check.tolerance_text()})")
    if ok:
        return Outcome(check, check.points, True, text, fmt(deviation), "0")
    return Outcome(check, 0.0, False, text, fmt(deviation), "0", list(differences),
                   failure=_reason(differences, "trajectory out of tolerance"))


def _interpolate(t: np.ndarray, y: np.ndarray, at: np.ndarray) -> np.ndarray:
    """y(t) at the times ``at``: a cubic spline through the output points (error O(h^4) on a smooth
    solution, so a student who stores fewer points is not failed by the interpolation), linear
    where the times repeat (an event's restart) or there are fewer than four points."""
    if t.size >= 4 and np.all(np.diff(t) > 0):
        from scipy.interpolate import CubicSpline

        return CubicSpline(t, y)(at)
    return np.interp(at, t, y)


def _events(check: CheckSpec, ref_result, stu_result, differences) -> Outcome:
    def times(result):
        return [float(e["t"]) for e in result.events if check.event is None or e.get("name") == check.event]

    which = f"events {check.event!r}" if check.event else "events"
    mine, ref = times(stu_result), times(ref_result)
    if len(mine) != len(ref):
        return failed(check, f"{which}: yours {len(mine)}, the reference's {len(ref)}", "another number of events",
                      differences)
    worst = max((abs(a - b) for a, b in zip(mine, ref)), default=0.0)
    bad = [i for i, (a, b) in enumerate(zip(mine, ref)) if not within(check, a, b)]
    text = (f"{which}: {len(mine)} located as in the reference; largest difference in time {fmt(worst)} "
            f"(tolerance {check.tolerance_text()})")
    if not bad:
        return Outcome(check, check.points, True, text, str(len(mine)), str(len(ref)))
    i = bad[0]
    text = (f"{which}: event {i + 1} at t = {fmt(mine[i])} where the reference's is at t = {fmt(ref[i])} "
            f"(tolerance {check.tolerance_text()})")
    return Outcome(check, 0.0, False, text, fmt(mine[i]), fmt(ref[i]), list(differences),
                   failure=_reason(differences, "event times out of tolerance"))


# --- checks on the file alone (no run needed) -----------------------------------------------------

def _normal(value):
    if isinstance(value, str) and value.lower() in ("on", "off"):
        return value.lower() == "on"
    return value


def _same(a, b) -> bool:
    a, b = _normal(a), _normal(b)
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b or a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=0.0)
    if isinstance(a, str) and isinstance(b, str):
        return a.casefold() == b.casefold()
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, (int, float)) and isinstance(b, (list, tuple)):  # a scalar atol asked, a vector given
        return all(_same(a, y) for y in b)
    return a == b


def evaluate_solver(check: CheckSpec, stu_case) -> Outcome:
    """A kind = "solver" check: each given key against the student's resolved [solver]."""
    used = stu_case.config.get("solver", {})
    wrong = []
    for key, (written, wanted) in check.solver.items():
        value = used.get(key)
        if not _same(wanted, value):
            if value is None:
                wrong.append(f"solver.{key} is not set, where the lab asks for {written} = {fmt(wanted)}")
            elif key == "method":
                wrong.append(f"solver.method is {fmt(value)} where the lab asks for {fmt(wanted)}")
            else:
                wrong.append(f"solver.{key} is {fmt(value)} where the lab asks for {written} = {fmt(wanted)}")
    asked = ", ".join(f"{w} = {fmt(v)}" for w, v in check.solver.values())
    if not wrong:
        return Outcome(check, check.points, True, f"solver: {asked}, as asked", asked, asked)
    return Outcome(check, 0.0, False, f"solver: {wrong[0]}", None, asked, wrong, failure=wrong[0])


def _matrices(problem):
    from odelab.systems.statespace import StateSpace

    system = problem.system.model
    if system is None:
        return None, "your system cannot be linearised from the file"
    if not isinstance(system, StateSpace):
        from odelab.analysis.linearize import linearize

        system = linearize(system, u0=np.zeros(len(problem.inputs)) if problem.inputs else None)
    return {"A": system.A, "B": system.B, "C": system.C, "D": system.D}, None


def evaluate_matrix(check: CheckSpec, ref_case, stu_case, names: NameMap, differences) -> Outcome:
    """A kind = "matrix" check: the student's A, B, C or D (in the reference's order of states and inputs)."""
    M = check.matrix
    ref, why = _matrices(ref_case.problem)
    if ref is None:  # pragma: no cover - refused when the rubric is checked
        return failed(check, why, why)
    try:
        mine, why = _matrices(stu_case.problem)
    except InputError as exc:
        mine, why = None, f"your system could not be linearised: {exc.message}"
    if mine is None:
        return failed(check, why, "no linear model", differences)
    rp, sp = ref_case.problem, stu_case.problem
    try:
        rows = {"A": sp.states, "B": sp.states, "C": sp.outputs, "D": sp.outputs}[M]
        cols = {"A": sp.states, "B": sp.inputs, "C": sp.states, "D": sp.inputs}[M]
        want_rows = {"A": rp.states, "B": rp.states, "C": rp.outputs, "D": rp.outputs}[M]
        want_cols = {"A": rp.states, "B": rp.inputs, "C": rp.states, "D": rp.inputs}[M]
        ri = [list(rows).index(names.of(n)) for n in want_rows]
        ci = [list(cols).index(names.of(n)) for n in want_cols]
        b = np.asarray(mine[M], dtype=float)[np.ix_(ri, ci)]
    except (ValueError, IndexError):
        return failed(check, f"your {M} is {np.shape(mine[M])[0]}-by-{np.shape(mine[M])[1]}, the reference's "
                      f"{np.shape(ref[M])[0]}-by-{np.shape(ref[M])[1]}", f"{M} of another size", differences)
    a = np.asarray(ref[M], dtype=float)
    deviation = float(np.max(np.abs(a - b))) if a.size else 0.0
    scale = float(np.max(np.abs(a))) if a.size else 0.0
    ok = (check.abs is not None and deviation <= check.abs) or (check.rel is not None and deviation <= check.rel * scale)
    text = f"{M}: largest difference from the reference's entries {fmt(deviation)} (tolerance {check.tolerance_text()})"
    if ok:
        return Outcome(check, check.points, True, text, fmt(deviation), "0")
    i, j = (int(k) for k in np.unravel_index(int(np.argmax(np.abs(a - b))), a.shape))
    text = f"{M}[{i}][{j}] is {fmt(b[i, j])} where the reference's is {fmt(a[i, j])} (tolerance {check.tolerance_text()})"
    return Outcome(check, 0.0, False, text, fmt(b[i, j]), fmt(a[i, j]), list(differences),
                   failure=_reason(differences, f"{M} out of tolerance"))
