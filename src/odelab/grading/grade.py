"""Grading a class: match each student's experiments to the reference's, run them as ``odelab run``
does, evaluate the rubric's checks.

The runs go through the same library functions as ``odelab run``: experiment files are loaded by
:func:`odelab.experiment.loader.load_experiments` within the run's budgets
(:class:`odelab.experiment.limits.Limits`, ``max_steps``) and every case is run by
:func:`odelab.run.executors.run_cases` (serially or in its process pool, ``jobs``), so a
student's numbers are the ones ``odelab run`` prints for their file. Only the cases the rubric
checks are run, and each result is reduced to its checks as it arrives, so a class costs at most
(students x checked cases) solves, each within the budgets, and the memory of a few runs.

A student's problems (a file that cannot be read, a Python system, a file naming a table outside
their folder, a run that fails) cost that student's checks only, with the reason in their
feedback. Problems with the rubric or the reference are the instructor's: they raise
:class:`~odelab.grading.rubric.RubricError`.
"""

from __future__ import annotations

import difflib
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment.limits import DEFAULT_LIMITS, Limits
from odelab.grading.checks import Outcome, evaluate, evaluate_matrix, evaluate_solver, failed
from odelab.grading.compare import differences, name_map, same_system
from odelab.grading.rubric import CheckSpec, Rubric, RubricError, load_rubric
from odelab.grading.submissions import Student, StudentFile, find_students, python_keys

__all__ = ["ClassGrade", "StudentGrade", "grade_class"]

_RUN_KINDS = ("headline", "trajectory", "final", "stepinfo", "events")


@dataclass
class StudentGrade:
    name: str
    outcomes: list[Outcome]
    notes: list[str] = field(default_factory=list)  # about the submission as a whole
    matched: dict[str, str] = field(default_factory=dict)  # reference experiment -> how it was found, or why not

    @property
    def score(self) -> float:
        return sum(o.score for o in self.outcomes)

    @property
    def max_score(self) -> float:
        return sum(o.check.points for o in self.outcomes)


@dataclass
class ClassGrade:
    rubric: Rubric
    students: list[StudentGrade]
    single: bool = False  # the submissions folder was one student's submission (Gradescope's layout)


@dataclass
class _Match:
    """A student's experiment matched to a reference experiment."""

    file: StudentFile | None = None
    experiment: object = None  # LoadedExperiment
    how: str = ""
    error: str | None = None  # why it could not be loaded
    category: str = ""  # the same words for the same kind of problem (the class summary counts them)


def _reference_files(rubric: Rubric) -> list[Path]:
    files: list[Path] = []
    for path in rubric.reference:
        if path.is_dir():
            from odelab.formats import is_experiment

            found = sorted(p for p in path.iterdir() if p.is_file() and is_experiment(p))
            if not found:
                raise RubricError(f"`reference` is {str(path)!r}, a folder with no experiment files (*.toml, or "
                                  "MATLAB or Simulink files).",
                                  source=str(rubric.path), key="reference")
            files.extend(found)
        elif path.is_file():
            files.append(path)
        else:
            raise RubricError(f"`reference` names {str(path)!r}, which does not exist; give the instructor's "
                              "experiment files or their folder (relative to the rubric).",
                              source=str(rubric.path), key="reference")
    return files


def _load_reference(rubric: Rubric, limits: Limits) -> dict[str, object]:
    from odelab.experiment.loader import load_experiments

    experiments: dict[str, object] = {}
    for file in _reference_files(rubric):
        try:
            loaded = load_experiments(file, limits=limits)
        except InputError as exc:
            raise RubricError(f"the reference file does not load: {exc.message}", source=str(exc.source or file),
                              key=exc.key) from None
        for exp in loaded:
            experiments.setdefault(exp.name, exp)
    return experiments


def _reference_case(check: CheckSpec, experiments: dict, rubric: Rubric):
    src = str(rubric.path)
    exp = experiments.get(check.experiment)
    if exp is None:
        close = difflib.get_close_matches(check.experiment, list(experiments), n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise RubricError(f"`{check.key}.experiment` is {check.experiment!r}, not an experiment of the reference "
                          f"({', '.join(sorted(experiments))}).{hint}", source=src, key=f"{check.key}.experiment")
    names = [c.name for c in exp.cases]
    if check.case is None:
        if len(exp.cases) == 1:
            return exp, exp.cases[0]
        raise RubricError(f"`{check.key}.case` is required: {check.experiment!r} has {len(names)} cases "
                          f"({', '.join(names)}); name the one to grade.", source=src, key=f"{check.key}.case")
    for case in exp.cases:
        if case.name == check.case:
            return exp, case
    close = difflib.get_close_matches(check.case, names, n=1)
    hint = f" Did you mean {close[0]!r}?" if close else ""
    raise RubricError(f"`{check.key}.case` is {check.case!r}, not a case of {check.experiment!r} "
                      f"({', '.join(names)}).{hint}", source=src, key=f"{check.key}.case")


def _check_quantity(check: CheckSpec, case, rubric: Rubric) -> None:
    if check.quantity is None:
        return
    p = case.problem
    known = [*p.states, *p.inputs, *p.outputs]
    if check.quantity not in known:
        close = difflib.get_close_matches(check.quantity, known, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise RubricError(f"`{check.key}.quantity` is {check.quantity!r}, not a state, input or output of "
                          f"{check.experiment!r} ({', '.join(known)}).{hint}", source=str(rubric.path),
                          key=f"{check.key}.quantity")


def _run(cases: list, *, jobs, max_steps, backend, executor, on_done=None):
    """Run ``cases`` as ``odelab run`` does; yields (index, CaseResult | CaseError | str) in case order.

    Should the pool stop on an unexpected error of one case, the cases not yet handed back are run
    again one by one in this process, so that the error costs that case only (a str: why).
    """
    from odelab.run.executors import run_cases

    if not cases:
        return
    done = 0
    try:
        for item in run_cases(cases, executor=executor, jobs=jobs, max_steps=max_steps or None, backend=backend,
                              on_done=on_done):
            yield done, item
            done += 1
        return
    except InputError:
        raise
    except Exception:  # one case broke the pool's stream: find it, running the rest one at a time
        pass
    for i in range(done, len(cases)):
        try:
            item = next(iter(run_cases([cases[i]], executor="serial", max_steps=max_steps or None,
                                       backend=backend)))
        except Exception as exc:
            item = f"odelab could not run this case: {type(exc).__name__}: {exc}"
        yield i, item


def grade_class(rubric: Rubric | str | Path, submissions: str | Path | None = None, *,
                limits: Limits = DEFAULT_LIMITS, max_steps: int | None = 1_000_000, jobs: int | None = None,
                executor: str = "process", backend: str = "python", allow_python: bool = False,
                allow_native: bool = False, on_done: Callable[[int, int], None] | None = None) -> ClassGrade:
    """Grade every student of ``submissions`` (default: the rubric's ``submissions``) against the rubric.

    ``backend`` defaults to "python": the engine ``auto`` would choose depends on the machine's
    speed and compile cache, and grading must give the same numbers on every run.

    Raises
    ------
    RubricError
        For a problem with the rubric or the reference (the instructor's files).
    InputError
        For a submissions folder that does not exist.
    """
    if not isinstance(rubric, Rubric):
        rubric = load_rubric(rubric)
    if submissions is None:
        if rubric.submissions is None:
            raise RubricError("no submissions folder: give it on the command line (odelab grade rubric.toml "
                              "SUBMISSIONS) or as `submissions` in the rubric.", source=str(rubric.path),
                              key="submissions")
        submissions = rubric.submissions
    from odelab.fmi.native import allow_native as native

    with native(allow_native):  # the instructor's own FMU, if the reference is one, under the same word
        experiments = _load_reference(rubric, limits)
    targets = {c.index: _reference_case(c, experiments, rubric) for c in rubric.checks}
    for check in rubric.checks:
        _check_quantity(check, targets[check.index][1], rubric)
    ref_results = _run_reference(rubric, targets, max_steps=max_steps, backend=backend)

    students = find_students(Path(submissions))
    single = len(students) == 1 and students[0].folder == Path(submissions)
    wanted = list(dict.fromkeys(c.experiment for c in rubric.checks))
    outcomes: dict[tuple[int, int], Outcome] = {}
    grades: list[StudentGrade] = []
    to_run: list = []
    run_keys: list[tuple[int, str, str]] = []  # (student, experiment, reference case) of each case to run
    queued: set[tuple[int, str, str]] = set()
    contexts: dict[tuple[int, str, str], tuple] = {}  # (student, experiment, ref case) -> (case, names, diffs)
    for s, student in enumerate(students):
        grade = StudentGrade(student.name, [], notes=list(student.notes))
        grades.append(grade)
        matches = _match_student(student, wanted, experiments, limits, (allow_python, allow_native))
        for e in wanted:
            m = matches[e]
            if m.experiment is not None:
                grade.matched[e] = f"found {m.how}"
            elif m.error is not None:
                grade.matched[e] = f"found {m.how}, which could not be used ({m.category})"
            else:
                grade.matched[e] = "not found"
        for check in rubric.checks:
            ref_exp, ref_case = targets[check.index]
            m = matches[check.experiment]
            if m.experiment is None:
                reason = m.error or f"not found: expected {check.experiment}"
                outcomes[(s, check.index)] = failed(check, reason, m.category or reason)
                continue
            key = (s, check.experiment, ref_case.name)
            if key not in contexts:
                stu_case, how = _match_case(ref_exp, ref_case, m.experiment)
                if stu_case is None:
                    contexts[key] = (None, None, [], how)
                else:
                    names = (same_system(ref_case.problem, stu_case.problem) if m.how.startswith("by its system")
                             else None) or name_map(ref_case.problem, stu_case.problem)
                    try:
                        diffs = differences(ref_case, stu_case, names)
                    except Exception as exc:  # never let a comparison cost more than its words
                        diffs = [f"(the files could not be compared: {type(exc).__name__})"]
                    contexts[key] = (stu_case, names, diffs, how)
                    if how.startswith("by its position"):
                        grade.notes.append(f"{check.experiment} has no case named {ref_case.name!r}: your "
                                           f"{how[len('by its position ('):-1]}, was graded in its place.")
            stu_case, names, diffs, how = contexts[key]
            if stu_case is None:
                outcomes[(s, check.index)] = failed(check, how, f"not found: case {ref_case.name}")
            elif check.kind == "solver":
                outcomes[(s, check.index)] = evaluate_solver(check, stu_case)
            elif check.kind == "matrix":
                outcomes[(s, check.index)] = _guarded(check, lambda: evaluate_matrix(
                    check, ref_case, stu_case, names, diffs))
            elif key not in queued:
                queued.add(key)
                run_keys.append(key)
                to_run.append(stu_case)
    by_key: dict[tuple[int, str, str], list[CheckSpec]] = {}
    for s, _ in enumerate(students):
        for check in rubric.checks:
            if check.kind in _RUN_KINDS and (s, check.index) not in outcomes:
                by_key.setdefault((s, check.experiment, targets[check.index][1].name), []).append(check)
    for i, item in _run(to_run, jobs=jobs, max_steps=max_steps, backend=backend, executor=executor, on_done=on_done):
        key = run_keys[i]
        s = key[0]
        stu_case, names, diffs, _ = contexts[key]
        for check in by_key.get(key, []):
            ref_result = ref_results[(check.experiment, key[2])]
            if isinstance(item, str):
                outcomes[(s, check.index)] = failed(check, item, "odelab could not run it")
            elif not hasattr(item, "status"):  # a CaseError: found only when running
                message = item.error.message
                outcomes[(s, check.index)] = failed(check, f"your case could not run: {message}", "could not run",
                                                    diffs)
            else:
                outcomes[(s, check.index)] = _guarded(check, lambda: evaluate(check, ref_result, item, names, diffs))
    for s, grade in enumerate(grades):
        grade.outcomes = [outcomes[(s, c.index)] for c in rubric.checks]
    return ClassGrade(rubric=rubric, students=grades, single=single)


def _guarded(check: CheckSpec, fn) -> Outcome:
    """A check's evaluation, where a student's strange values cost that check only."""
    try:
        return fn()
    except Exception as exc:
        why = f"odelab could not evaluate this check on your file: {type(exc).__name__}: {exc}"
        return failed(check, why, "could not be evaluated")


def _run_reference(rubric: Rubric, targets: dict, *, max_steps, backend) -> dict:
    needed = []
    seen = set()
    for check in rubric.checks:
        exp, case = targets[check.index]
        if check.kind in _RUN_KINDS and (exp.name, case.name) not in seen:
            seen.add((exp.name, case.name))
            needed.append(case)
    results = {}
    # In this process: a few cases, and what they import (python-control for [analysis], scipy's
    # expm) is then inherited by the pool's forked workers instead of imported by each of them.
    for i, item in _run(needed, jobs=1, max_steps=max_steps, backend=backend, executor="serial"):
        case = needed[i]
        where = f"the reference's case {case.name!r} of {case.experiment!r}"
        if isinstance(item, str) or not hasattr(item, "status"):
            why = item if isinstance(item, str) else item.error.message
            raise RubricError(f"{where} could not run: {why}", source=str(case.source))
        if item.status != "success":
            raise RubricError(f"{where} failed: {item.message}", source=str(case.source))
        results[(case.experiment, case.name)] = item
    for check in rubric.checks:
        exp, case = targets[check.index]
        if check.kind == "headline" and check.quantity not in results[(exp.name, case.name)].errors:
            raise RubricError(f"`{check.key}` is a headline check of {check.quantity!r}, but the reference's case "
                              f"{case.name!r} has no error for it: give the reference an [exact] solution (or a "
                              "linear state-space model, whose exact response odelab computes), or grade it with "
                              "kind = \"trajectory\".", source=str(rubric.path), key=check.key)
        if check.kind == "matrix" and case.problem.system.model is None:
            raise RubricError(f"`{check.key}` is a matrix check, but the reference's system has no linear model "
                              "(a Python function): give the reference as equations or a state-space model.",
                              source=str(rubric.path), key=check.key)
    return results


def _normal_title(text: str | None) -> str | None:
    return " ".join(text.split()).casefold() if isinstance(text, str) and text.strip() else None


def _match_student(student: Student, wanted: list[str], experiments: dict, limits: Limits,
                   allow: tuple[bool, bool]) -> dict[str, _Match]:
    """Each wanted reference experiment's match among the student's files: by name, by title, by system."""
    matches = {e: _Match() for e in wanted}
    loaded: dict[int, list | InputError] = {}  # file index -> its experiments, or why it cannot be loaded
    used: set[tuple[int, str]] = set()  # (file, experiment name) already matched

    def load(i: int):
        if i not in loaded:
            loaded[i] = _load_student_file(student, student.files[i], limits, *allow)
        return loaded[i]

    def take(e: str, i: int, exp_name: str, how: str) -> None:
        m = matches[e]
        m.file = student.files[i]
        got = load(i)
        shown = _shown(student, student.files[i])
        if isinstance(got, InputError):
            m.error = f"{shown}: {got.message}" if not got.key or got.key in got.message else \
                f"{shown}: `{got.key}`: {got.message}"
            m.how = f"{how}: {shown}"
            m.category = _category(got)
            return
        for exp in got:
            if exp.name.casefold() == exp_name.casefold():
                m.experiment, m.how = exp, f"{how}: {shown}"
                used.add((i, exp.name))
                return
        m.error = f"{shown}: holds no experiment {exp_name!r} once loaded"

    for e in wanted:  # by name (an unreadable file is matched by its file name: its error is the feedback)
        for i, f in enumerate(student.files):
            hit = [n for n, _ in f.experiment_names() if n.casefold() == e.casefold()]
            if hit:
                take(e, i, hit[0], "by its name")
                break
    for e in wanted:  # by title
        if matches[e].file is not None:
            continue
        title = _normal_title(experiments[e].title)
        for i, f in enumerate(student.files):
            if f.data is None:
                continue
            hit = [n for n, t in f.experiment_names() if title and _normal_title(t) == title
                   and (i, n) not in used and n not in wanted]
            if hit:
                take(e, i, hit[0], "by its title")
                break
    for e in wanted:  # by the system it describes (same states and equations up to renaming)
        if matches[e].file is not None:
            continue
        ref_problem = experiments[e].cases[0].problem
        for i, f in enumerate(student.files):
            if f.data is None or f.error is not None:
                continue
            got = load(i)
            if isinstance(got, InputError):
                continue
            for exp in got:
                if (i, exp.name) in used or exp.name in wanted:
                    continue
                try:
                    same = same_system(ref_problem, exp.cases[0].problem) is not None
                except Exception:
                    same = False
                if same:
                    matches[e].file, matches[e].experiment = f, exp
                    matches[e].how = f"by its system (the same equations up to renaming): {_shown(student, f)}"
                    used.add((i, exp.name))
                    break
            if matches[e].file is not None:
                break
    return matches


def _category(exc: InputError) -> str:
    """A load error in a few words, the same for every student with that problem."""
    text = exc.message
    if text.startswith("TOML syntax error"):
        return "TOML syntax error"
    if "a Python function; grading never runs" in text:
        return "a Python function (not run)"
    if "a graded submission may only read files inside its own folder" in text:
        return "a file outside the submission's folder"
    if "the budget is" in text:
        return f"over a budget (`{exc.key}`)" if exc.key else "over a budget"
    return f"invalid file (`{exc.key}`)" if exc.key else "invalid file"


def _shown(student: Student, f: StudentFile) -> str:
    return f.path.relative_to(student.folder).as_posix()


def _load_student_file(student: Student, f: StudentFile, limits: Limits, allow_python: bool,
                       allow_native: bool = False):
    """A student's file loaded as ``odelab run`` loads it, confined to their folder; or the InputError why not."""
    from odelab.experiment.loader import load_experiments
    from odelab.experiment.userfiles import confined_to

    shown = _shown(student, f)
    if f.error is not None:
        return f.error
    code = python_keys(f.data)
    if code and not allow_python:
        key, value = code[0]
        return ExperimentError(f"`{key}` is {value!r}, a Python function; grading never runs a submission's code. "
                               "Write the system as [system.equations] (or a state-space model); the instructor can "
                               "allow Python with `odelab grade --allow-python`.", source=shown, key=key)
    system = f.data.get("system") if isinstance(f.data, dict) else None
    if isinstance(system, dict) and system.get("kind") == "fmu" and not allow_native:
        return ExperimentError(f"`system.file` is {system.get('file')!r}, an FMU; grading never runs a submission's "
                               "machine code. Write the system as [system.equations] (or a state-space model); the "
                               "instructor can allow FMUs with `odelab grade --allow-native`.", source=shown,
                               key="system.file")
    from odelab.fmi.native import allow_native as native

    try:
        with confined_to(student.folder), native(allow_native):
            return load_experiments(f.path, limits=limits)
    except InputError as exc:
        # paths in the message relative to the student's folder: the feedback does not depend on
        # where the class is stored, and does not show the grading machine's folders
        for folder in {str(student.folder.resolve()), str(student.folder)}:
            exc.message = exc.message.replace(folder + os.sep, "")
        return exc
    except RecursionError:
        return ExperimentError("is nested too deeply to be read.", source=shown)
    except Exception as exc:  # a bug odelab has with this file must not stop the class
        return ExperimentError(f"odelab could not load it: {type(exc).__name__}: {exc}.", source=shown)


def _match_case(ref_exp, ref_case, stu_exp):
    """The student's case for ``ref_case``: by name, else by position when the case counts agree."""
    for case in stu_exp.cases:
        if case.name.casefold() == ref_case.name.casefold():
            return case, "by its name"
    if len(stu_exp.cases) == len(ref_exp.cases):
        i = ref_exp.cases.index(ref_case)
        return stu_exp.cases[i], f"by its position (case {i + 1}, named {stu_exp.cases[i].name!r})"
    names = ", ".join(c.name for c in stu_exp.cases)
    return None, f"not found: expected case {ref_case.name!r} in {ref_exp.name} (your cases: {names})"

