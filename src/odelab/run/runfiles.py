"""Running experiment files: the core of ``odelab run``, which only parses arguments and draws.

:func:`run_files` loads the files (and fits their ``[fit]``), runs every case (serially, in a
process pool or on Dask), stores each case the moment it finishes (a sweep's table as it
grows), and yields :class:`Event` objects saying what happened, for the caller to draw. An
interrupt (Ctrl-C, or SIGTERM raised as :class:`Terminated`) while cases run stores what
finished, nothing half-written, and propagates; if it reaches the caller between two events,
``events.throw(exc)`` gives the run the same chance. Nothing here prints or exits.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from odelab.exceptions import InputError

if TYPE_CHECKING:
    from odelab.experiment.limits import Limits
    from odelab.formats import ImportOptions

__all__ = ["RunConfig", "run_files", "FileRun", "expand_paths", "error_text", "Terminated", "Event", "FileError",
           "Started", "References", "ExperimentStarted", "CaseDone", "ExperimentDone", "Notice", "Fatal",
           "Finished", "LeftoversRemoved"]


class Terminated(BaseException):
    """SIGTERM, raised like KeyboardInterrupt so that cleanup (temporary files, storing what finished) runs."""


@dataclass(eq=False)
class RunConfig:
    """What ``odelab run``'s options ask (see ``odelab run --help``)."""

    runs: Path = Path("runs")
    store: bool = True
    mat: bool = False
    max_steps: int = 1_000_000
    limits: Limits | None = None  # default: DEFAULT_LIMITS with steps = max_steps
    backend: str | None = None
    estimate: bool | None = None  # --estimate / --no-estimate: the global error estimate (odelab.run.estimate)
    strict: bool = False  # --strict: an unreliable result (ok?) fails the run too
    jobs: int | None = None
    executor: str = "process"
    scheduler: str | None = None
    validate_with: Path | None = None
    import_options: ImportOptions | None = None  # --workspace, --set, --call for MATLAB and Simulink files
    allow_native: bool = False  # --allow-native: files may load FMUs (their binaries run in this process)

    @property
    def budgets(self) -> Limits:
        from odelab.experiment.limits import DEFAULT_LIMITS

        return self.limits if self.limits is not None else replace(DEFAULT_LIMITS, steps=self.max_steps)


class Event:
    """Something the run says; subclasses carry what to draw. They are records the caller only reads:
    plain dataclasses without __eq__ (a frozen one costs ~3.3 M instructions to create at import, 1.4 M
    these; every run's start-up imports this module)."""


@dataclass(eq=False)
class FileError(Event):
    """A file, an experiment or a case that cannot run (the run goes on; it exits 2)."""

    message: str
    case: str | None = None  # a case found bad only when it ran


@dataclass(eq=False)
class Started(Event):
    """The cases are about to run."""

    total: int


@dataclass(eq=False)
class References(Event):
    """High-accuracy references shared by the cases: ``prepare(progress)`` computes them, ``progress(text)``
    (or None) hearing which solver, why, how far it got and when it is done."""

    prepare: Callable[[Callable[[str], None] | None], None]


@dataclass(eq=False)
class ExperimentStarted(Event):
    experiment: Any


@dataclass(eq=False)
class CaseDone(Event):
    """A case finished (and is stored): the counts so far."""

    finished: int
    failed: int


@dataclass(eq=False)
class ExperimentDone(Event):
    """Every case of an experiment ran: its results, in case order."""

    experiment: Any
    results: list = field(default_factory=list)


@dataclass(eq=False)
class Notice(Event):
    """Something that happened to the run and did not change its results (a Dask worker lost mid-run)."""

    message: str


@dataclass(eq=False)
class LeftoversRemoved(Event):
    """Before the run: the hidden folders that runs killed mid-write (SIGKILL, the OOM killer) left in the
    results folder, removed (``odelab.store.hidden.Stale``: path, bytes, the dead owner's pid)."""

    removed: tuple


@dataclass(eq=False)
class Fatal(Event):
    """The run cannot go on (an unreachable scheduler, a results folder that cannot be written): exit 2."""

    message: str


@dataclass(eq=False)
class Finished(Event):
    """The run's end: how many cases were stored, whether any failed unexpectedly, the errors."""

    stored: int
    any_failed: bool
    errors: tuple[str, ...]


def error_text(exc) -> str:
    """One or two lines: file, key, what is wrong, how to fix it."""
    text = str(exc)
    if getattr(exc, "key", None) and f"`{exc.key}`" not in text and exc.key not in text:
        prefix = f"{exc.source}: " if getattr(exc, "source", None) else ""
        text = prefix + f"`{exc.key}`: " + text[len(prefix):]
    return text


def expand_paths(paths: list[Path]) -> tuple[list[Path], list[tuple[Path, str]]]:
    """Files to run: files as given (any format :mod:`odelab.formats` reads), folders' experiment files
    (``*.toml``); missing paths are reported."""
    from odelab.formats import FOLDER_SUFFIXES, READERS

    files: list[Path] = []
    problems: list[tuple[Path, str]] = []
    for path in paths:
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.suffix in FOLDER_SUFFIXES and p.is_file())
            if not found:
                others = sorted(p.name for p in path.iterdir() if p.suffix.lower() in READERS and p.is_file())
                hint = (f" It holds {', '.join(others[:3])}{' ...' if len(others) > 3 else ''}: name MATLAB and "
                        "Simulink files one by one (the driver script or the model), or import them with "
                        "`odelab import`." if others else "")
                problems.append((path, "is a folder with no *.toml experiment files in it." + hint))
            files.extend(found)
        elif path.exists():
            files.append(path)
        else:
            problems.append((path, "no such file or folder; check the path."))
    return files, problems


def _fit_all(loaded, bad: list[str], validate_with):
    """Estimate each experiment's [fit] before its cases run (they then run at the estimates)."""
    from odelab.experiment.fit import fit_experiment

    if validate_with is not None and not any(e.fit is not None for e in loaded):
        bad.append(f"--validate-with {validate_with}: it checks a fitted model, and no experiment has a [fit].")
        return loaded
    out = []
    for exp in loaded:
        if exp.fit is None:
            out.append(exp)
            continue
        try:
            out.append(fit_experiment(exp, validate_with=str(validate_with) if validate_with else None))
        except InputError as exc:
            bad.append(error_text(exc.located(source=str(exp.source))))
    return out


def _native(allowed: bool):
    """``allow_native(allowed)`` (``--allow-native``: files may load FMUs, whose binaries run in this
    process). Nothing to set where odelab.fmi was never imported: nothing can have allowed them, and a run
    without FMUs does not import it."""
    if not allowed and "odelab.fmi.native" not in sys.modules:
        return contextlib.nullcontext()
    from odelab.fmi.native import allow_native

    return allow_native(allowed)


def load_files(paths: list[Path], config: RunConfig) -> tuple[list, list[str]]:
    """The experiments of ``paths`` (fitted where they have a [fit]) and one error line per one that cannot run."""
    from odelab.experiment.loader import load_experiments
    from odelab.experiment.naming import check_experiment_names

    files, problems = expand_paths(paths)
    bad = [f"{p}: {why}" for p, why in problems]
    loaded = []
    for file in files:
        try:
            with _native(config.allow_native):
                loaded.extend(load_experiments(file, limits=config.budgets, options=config.import_options))
        except InputError as exc:
            bad.append(error_text(exc))
    for exp, exc in check_experiment_names(loaded):  # two files that would share a results folder
        loaded.remove(exp)
        bad.append(error_text(exc))
    if any(e.fit is not None for e in loaded) or config.validate_with is not None:
        with _native(config.allow_native):  # a fit reloads its file with the estimates (an FMU too)
            loaded = _fit_all(loaded, bad, config.validate_with)
    return loaded, bad


class _StoreFailed(Exception):
    pass


def _case_key(case) -> tuple:
    return str(case.source), case.experiment, case.index


class FileRun:
    """One run of experiment files: iterate it for its events; ``finished`` and ``total`` count the cases."""

    def __init__(self, paths: list[Path], config: RunConfig):
        self.paths = list(paths)
        self.config = config
        self.total = 0
        self.finished = 0  # cases finished and stored
        self._stored_now: set[tuple] = set()
        self._unsynced: set[Path] = set()  # experiment folders whose renames are not yet flushed (store.py)

    def __iter__(self) -> Iterator[Event]:
        return self._events()

    # --- storing -------------------------------------------------------------------------------------------

    def _store(self, result) -> None:
        from odelab.store.results import write_case

        try:
            write_case(result, self.config.runs, mat=self.config.mat, unsynced=self._unsynced)
        except OSError as exc:
            raise _StoreFailed(f"cannot write results to {self.config.runs}: {exc}") from None

    def _store_sweep(self, exp, results) -> None:
        from odelab.store.sweeps import write_sweep

        try:
            write_sweep(exp, results, self.config.runs)
        except OSError as exc:
            raise _StoreFailed(f"cannot write results to {self.config.runs}: {exc}") from None

    def _store_interrupted(self, loaded, current, results, finished) -> int:
        """On an interrupt: the sweep tables of what finished, and the cases that finished while interrupted.

        ``finished``: the cases that finished but were not yet yielded in case order (those already
        stored are known by their keys). Returns how many cases were stored here."""
        from odelab.run.executors import CaseError

        extra: dict[tuple[str, str], list] = {}
        for r in finished:
            if not isinstance(r, CaseError):
                extra.setdefault((str(r.case.source), r.case.experiment), []).append(r)
        count = 0
        for exp in loaded:
            late = extra.get((str(exp.source), exp.name), [])
            fresh = [r for r in late if _case_key(r.case) not in self._stored_now]
            if exp.sweep is None or exp.sweep.store == "all":
                for r in fresh:
                    self._store(r)
            mine = (list(results) if exp is current else []) + late
            if exp.sweep is not None and mine:  # the sweep's table of what finished, in case order
                self._store_sweep(exp, sorted(mine, key=lambda r: r.case.index))
            count += len(fresh)
        return count

    def _on_result(self, by_key, partial, pace):
        """Store each case the moment it finishes, whichever process ran it: a killed run keeps what it finished
        (its folder or, for a sweep storing only its table, the table so far, rewritten at a pace that keeps its
        cost small)."""
        from odelab.run.executors import CaseError

        store = self.config.store

        def on_result(result):
            if isinstance(result, CaseError):
                return
            key = (str(result.case.source), result.case.experiment)
            exp = by_key[key]
            if store and (exp.sweep is None or exp.sweep.store == "all"):
                self._store(result)
            elif store:
                partial.setdefault(key, []).append(result)
                if pace.due(key) and len(partial[key]) < len(exp.cases):  # the last: written in full at the end
                    with pace.timed(key):
                        self._store_sweep(exp, sorted(partial[key], key=lambda r: r.case.index))
            self._stored_now.add(_case_key(result.case))
            self.finished += 1

        return on_result

    # --- the run ------------------------------------------------------------------------------------------

    def _events(self) -> Iterator[Event]:
        runs = self.config.runs
        made = self.config.store and not runs.exists()  # a results folder this run makes, if it stores nothing
        if self.config.store:
            from odelab.store.hidden import remove_stale

            removed = remove_stale(runs)
            if removed:
                yield LeftoversRemoved(tuple(removed))
        loaded, bad = load_files(self.paths, self.config)
        for line in bad:
            yield FileError(line)
        self.total = sum(len(e.cases) for e in loaded)
        try:
            yield from self._run(loaded, bad)
        except _StoreFailed as exc:
            yield Fatal(str(exc))
        finally:  # the run's durable point: every case folder renamed in place stays after a power cut
            from odelab.store.hidden import remove_if_empty
            from odelab.store.results import sync_folders

            sync_folders(self._unsynced)
            if made:
                remove_if_empty(runs)

    def _run(self, loaded, bad: list[str]) -> Iterator[Event]:
        from odelab.run.executors import CaseError, run_cases
        from odelab.store.results import Pace
        from odelab.store.spool import SpoolFailed

        config = self.config
        cases = [case for exp in loaded for case in exp.cases]
        counts = {"finished": 0, "failed": 0}

        def on_done(finished, failed):
            counts.update(finished=finished, failed=failed)

        by_key = {(str(e.source), e.name): e for e in loaded}
        on_result = self._on_result(by_key, {}, Pace())
        if any(c.problem.reference == "high-accuracy" for c in cases):
            from odelab.run.reference import prepare

            # in this process, before a pool forks (the workers inherit them)
            yield References(lambda progress: prepare(cases, config.max_steps or None, progress=progress))
        notes: list[str] = []
        try:  # a process pool forks its workers here, before the caller starts drawing
            stream = run_cases(cases, executor=config.executor, jobs=config.jobs, scheduler=config.scheduler,
                               max_steps=config.max_steps or None, on_done=on_done, backend=config.backend,
                               estimate=config.estimate, spool_in=config.runs if config.store else None,
                               on_result=on_result, limits=config.budgets,
                               import_options=config.import_options, on_note=notes.append)
            iterator = iter(stream)
        except InputError as exc:
            yield Fatal(error_text(exc))
            return
        yield Started(self.total)
        any_failed = False
        stored = 0
        for exp in loaded:
            yield ExperimentStarted(exp)
            results = []
            try:
                for case in exp.cases:
                    try:
                        result = next(iterator)
                    except SpoolFailed as exc:  # a long run's rows could not go to the results folder
                        raise _StoreFailed(f"cannot write results to {config.runs}: {exc}") from None
                    except InputError as exc:  # a Dask scheduler that cannot be reached, or lost mid-run
                        yield from (Notice(n) for n in notes)
                        if config.store:
                            self.finished += self._store_interrupted(loaded, exp, results,
                                                                     getattr(exc, "finished", ()))
                        stored_text = (f" {self.finished} of {self.total} case{'s' if self.total != 1 else ''} "
                                       f"finished{' and are stored' if config.store else ''}." if self.finished
                                       else " No case had finished.")
                        yield Fatal(error_text(exc) + stored_text)
                        return
                    while notes:
                        yield Notice(notes.pop(0))
                    if isinstance(result, CaseError):  # found only when running, e.g. no equilibrium for an input
                        message = error_text(result.error.located(source=str(case.source)))
                        bad.append(message)
                        yield FileError(message, case=case.name)
                        continue
                    results.append(result)
                    any_failed |= result.unexpected_failure or result.extra.get("fit", {}).get("status") == "failed"
                    any_failed |= config.strict and result.unreliable  # ok?: a failure only with --strict
                    yield CaseDone(counts["finished"], counts["failed"])
            except (KeyboardInterrupt, Terminated) as exc:
                if config.store:  # what finished: this experiment's cases so far, and any a pool finished out of order
                    self.finished += self._store_interrupted(loaded, exp, results, getattr(exc, "finished", ()))
                raise
            if config.store and exp.sweep is not None and results:
                self._store_sweep(exp, results)
            yield ExperimentDone(exp, results)
            stored += len(results) if config.store else 0
        yield Finished(stored, any_failed, tuple(bad))


def run_files(paths: list[Path], config: RunConfig | None = None) -> FileRun:
    """Run the experiment files (or folders of them) ``paths``; iterate the result for its events."""
    return FileRun(paths, config or RunConfig())
