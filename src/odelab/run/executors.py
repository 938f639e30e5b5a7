"""Running many cases: serially, in a process pool, or on a Dask cluster — with identical results.

Every executor runs :func:`odelab.run.runner.run_case` on the same cases and hands the
results back **in case order**, whatever order they finish in, so what is stored does not
depend on how it was run. Pool workers are forked from the running process and inherit the
experiments it has loaded. Dask workers receive the built cases themselves: a built case
pickles (its compiled functions travel as their expressions' texts and are compiled again in
the worker, :class:`odelab.expressions.compile.Portable`), so a worker neither reads nor
parses the experiment file. A case that cannot travel (:func:`travels`: an FMU's, whose binary
is loaded in this process, or one whose system is a user's Python function, whose module a worker
cannot import by name) goes by reference: the worker loads its file itself (once per process, at the
same path: a shared file system, as on any cluster) and runs the case by its index, checking
the file's SHA-256 so that an edited file is never mixed with the cases already run.

In a pool or on a cluster the cases are handed out **longest first** within each experiment
(:func:`schedule`: a fixed-step case costs its number of steps times its stages; an adaptive
one grows as its tolerance tightens), so that the last case to finish is a short one and no
worker idles while another runs a long tail. The experiments themselves keep their order, so
that the first one's results can be stored and printed while the next one runs.

``on_result(item)`` and then ``on_done(done, failed)`` are called in the calling thread the
moment each case finishes, in the order they finish, whichever process ran it: the caller
stores a case there (a killed run keeps every case it finished) and updates a progress bar;
nothing here prints. Pool workers, and the workers of a local Dask cluster, exit when the
process that started them dies (:mod:`odelab.run.lifeline`).
"""

from __future__ import annotations

import dataclasses
import importlib.machinery
import io
import math
import os
import signal
import sys
import threading
import time
import types
from pathlib import Path
from typing import Callable, Iterable, Iterator

from odelab import __version__
from odelab.exceptions import InputError

__all__ = ["EXECUTORS", "CaseError", "ClusterLost", "POOL_WORTHWHILE", "case_cost", "default_jobs", "run_cases", "schedule", "small_work", "source_digest"]

EXECUTORS = ("serial", "process", "dask")

# Experiments loaded in this process, by (path, sha256): forked workers inherit it.
_LOADED: dict[tuple[str, str], object] = {}


@dataclasses.dataclass(frozen=True)
class CaseError:
    """A case that could not run because of its input (e.g. no equilibrium for an input)."""

    case: object
    error: InputError


def default_jobs() -> int:
    """The number of cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def case_cost(case) -> float:
    """A relative estimate of a case's run time, for scheduling (only the order matters).

    A fixed-step method: steps (span / h) times stages. An adaptive one: its stages times
    rtol^(-1/order) per unit of span (the step size an error-per-step controller settles at),
    which orders a tolerance sweep correctly. Anything else counts 1.
    """
    from odelab.solvers.registry import get_method

    p = case.problem
    try:
        method = get_method(p.method)
        span = float(abs(p.tspan[-1] - p.tspan[0]))
        tableau = getattr(method, "tableau", None)
        stages = tableau.c.size if tableau is not None else 1
        options = p.solver_options  # resolved at load
        if not method.adaptive:
            return stages * span / options.h
        rtol = options.rtol
        order = float(method.order or 4)
        return stages * max(span, 1e-300) * rtol ** (-1.0 / order)
    except (TypeError, ValueError, KeyError, AttributeError, ZeroDivisionError, OverflowError):
        return 1.0


#: Below this much estimated work (:func:`case_cost`'s units, about right-hand-side evaluations
#: of the Python engine, a few microseconds each), a run with the default ``jobs`` stays in one
#: process: forking a pool and sending every result back costs 0.1-0.2 s, more than it saves.
POOL_WORTHWHILE = 50_000


def small_work(cases: list) -> bool:
    """Whether ``cases`` together are too little work to be worth a process pool."""
    total = 0.0
    for case in cases:
        cost = case_cost(case)
        total += cost if math.isfinite(cost) else POOL_WORTHWHILE
        if total >= POOL_WORTHWHILE:
            return False
    return True


def schedule(cases: list) -> list[int]:
    """The order in which to hand ``cases`` to a pool: experiments in order, each one's cases longest first."""
    position: dict[tuple[str, str], int] = {}
    keys = []
    for i, case in enumerate(cases):
        exp = position.setdefault((str(case.source), case.experiment), len(position))
        cost = case_cost(case)
        keys.append((exp, -cost if math.isfinite(cost) else 0.0, i))
    return [i for _, _, i in sorted(keys)]


def _case_in_worker(source: str, file_hash: str, index: int, experiment: str, limits=None, import_options=None):
    key = (source, file_hash, experiment)
    if key not in _LOADED:
        from odelab.experiment.limits import DEFAULT_LIMITS
        from odelab.experiment.loader import load_experiments

        for exp in load_experiments(Path(source), limits=limits or DEFAULT_LIMITS, options=import_options):
            _LOADED[(source, exp.file_hash, exp.name)] = exp.cases
    cases = _LOADED.get(key)
    if cases is None:
        raise RuntimeError(f"{source} changed since the run started (its SHA-256 is no longer {file_hash[:12]}); "
                           "run it again")
    return cases[index]


def _run_remote(source: str, file_hash: str, index: int, experiment: str, opts: dict, limits=None,
                import_options=None):
    """Run one case in a worker; the result travels without its (unpicklable) compiled case.

    ``limits`` and ``import_options``: those the file was loaded with (``--limit``; an imported file's
    ``--workspace``, ``--set`` and ``--call``), for a worker that loads it again."""
    from odelab.run.runner import run_case

    case = _case_in_worker(source, file_hash, index, experiment, limits, import_options)
    try:
        result = run_case(case, **opts)
    except InputError as exc:
        return "error", exc
    return "ok", dataclasses.replace(result, case=None)


def _attach(case, outcome):
    kind, value = outcome
    if kind == "error":
        return CaseError(case, value)
    return dataclasses.replace(value, case=case)


def _run_local(case, opts: dict):
    from odelab.run.runner import run_case

    try:
        return run_case(case, **opts)
    except InputError as exc:
        return CaseError(case, exc)


def _failed(item) -> bool:
    return isinstance(item, CaseError) or item.status != "success"


def _init_worker(parent: int) -> None:
    """A pool worker exits with its parent, and leaves Ctrl-C to it (the parent stops the pool
    and reports what finished)."""
    from odelab.run.lifeline import exit_with_parent

    exit_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def run_cases(cases: Iterable, *, executor: str = "serial", jobs: int | None = None, scheduler: str | None = None,
              max_steps: int | None = None, on_done: Callable[[int, int], None] | None = None,
              backend: str | None = None, on_result: Callable[[object], None] | None = None,
              limits=None, import_options=None, on_note: Callable[[str], None] | None = None,
              estimate: bool | None = None, spool_in=None) -> Iterator:
    """Run ``cases``; returns an iterator of each one's :class:`CaseResult` (or :class:`CaseError`), in case order.

    A process pool is started (its workers forked) before this returns; the cases run as the
    iterator is consumed or, in a pool or on a cluster, straight away.

    Parameters
    ----------
    executor
        ``"serial"`` (this process), ``"process"`` (a pool of ``jobs`` forked processes) or
        ``"dask"`` (a ``distributed`` cluster at ``scheduler``; without one, a local cluster
        of ``jobs`` worker processes is started for the run).
    on_result
        Called with each case's result (or :class:`CaseError`) as soon as it finishes, before
        ``on_done`` and before the iterator yields it in case order: the place to store it.
    limits
        The :class:`~odelab.experiment.limits.Limits` the cases' files were loaded with
        (``--limit``): a Dask worker loads each file again, within the same budgets.
    import_options
        The :class:`~odelab.formats.ImportOptions` an imported file (MATLAB, Simulink) was read with:
        a Dask worker reads it again with them.
    estimate
        True/False: every case gets (or none gets) the global error estimate (odelab.run.estimate);
        None: each case as its file says, by default.
    on_note
        Called with a sentence when something happened to the run that the user should know and
        that did not change its results (a Dask worker lost mid-run: its cases ran again).
    spool_in
        The results folder the cases are stored in: run in this process (serially), a long compiled run
        writes its rows beside its case's folder as it goes (``run_case``'s ``spool_in``,
        :mod:`odelab.store.spool`). A pool's or a cluster's cases send their rows back in memory.

    Raises
    ------
    ClusterLost
        The Dask scheduler went away mid-run (its process died, or it stopped answering for
        :data:`DASK_SILENT_SECONDS`); the cases that finished travel on it as ``finished``.
    """
    cases = list(cases)
    if executor not in EXECUTORS:
        raise InputError(f"`executor` is {executor!r}; it must be one of {', '.join(EXECUTORS)}.", key="executor")
    asked = jobs is not None
    jobs = jobs or default_jobs()
    if executor == "process" and (jobs < 2 or len(cases) < 2 or (not asked and small_work(cases))):
        executor = "serial"
    counts = [0, 0]

    def done(item):
        if on_result is not None:
            on_result(item)
        counts[0] += 1
        counts[1] += _failed(item)
        if on_done is not None:
            on_done(counts[0], counts[1])

    opts = {"max_steps": max_steps, **({"backend": backend} if backend is not None else {}),  # run_case's options
            **({"estimate": estimate} if estimate is not None else {})}
    if executor == "serial":
        return _run_serial(cases, {**opts, **({"spool_in": spool_in} if spool_in is not None else {})}, done)
    if executor == "process":
        return _run_pool(cases, jobs, opts, done)
    return _run_dask(cases, jobs, scheduler, opts, done, limits, import_options, on_note)


def _run_serial(cases, opts, done):
    for case in cases:
        item = _run_local(case, opts)
        done(item)
        yield item


def _source(case) -> str:
    """The case's file as an absolute path: a Dask worker may run in another folder."""
    return os.path.abspath(str(case.source))


def _submit_args(case, opts):
    return (_source(case), case.file_hash, case.index, case.experiment, opts)


def _run_pool(cases, jobs, opts, done):
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    from odelab.experiment.loader import load_experiments  # noqa: F401  (imported before forking)
    from odelab.run.runner import run_case  # noqa: F401

    _seed(cases)
    if any((opts.get("backend") or getattr(c.problem, "backend", "python")) != "python" for c in cases):
        from odelab.solvers.compiled.cache import compiled_folder

        try:  # checked once, here: the workers inherit the verdict (and a private cache, if one is needed)
            compiled_folder()
        except InputError:
            pass  # each case says so
        done = _with_notes(done)
    # The workers are forked here, before the caller starts any thread (a progress bar's), so
    # that no lock can be inherited held.
    pool = ProcessPoolExecutor(max_workers=min(jobs, len(cases)), mp_context=multiprocessing.get_context("fork"),
                               initializer=_init_worker, initargs=(os.getpid(),))
    futures = [None] * len(cases)
    for i in schedule(cases):
        futures[i] = pool.submit(_run_remote, *_submit_args(cases[i], opts))

    def results():
        try:
            yield from _in_order(cases, [(f, [i]) for i, f in enumerate(futures)], lambda f: [f.result()], done,
                                 lambda pending: wait(pending, return_when=FIRST_COMPLETED)[0])
        except BaseException:
            _stop_pool(pool)
            raise
        pool.shutdown(wait=True)

    return results()


def _with_notes(done):
    """``done``, adding this process's pending notes (odelab.cachedir) to the first case that
    finishes: taken before forking, so that the workers do not each repeat them."""
    from odelab.cachedir import take_notes

    notes = take_notes()

    def first_gets_notes(item):
        if notes and not isinstance(item, CaseError):
            item.warnings.extend(notes)
            notes.clear()
        done(item)

    return first_gets_notes


def _stop_pool(pool) -> None:
    """Stop at once: cancel what has not started, end the workers running a case."""
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        proc.terminate()
    # Wait for the pool's manager thread to see the workers gone, so that nothing is left for
    # the interpreter's exit hooks (which would otherwise print a traceback).
    pool.shutdown(wait=True, cancel_futures=True)


def _seed(cases) -> None:
    """Put the cases' experiments in the cache that forked workers inherit."""
    by_exp: dict[tuple[str, str, str], list] = {}
    for case in cases:
        by_exp.setdefault((_source(case), case.file_hash, case.experiment), []).append(case)
    for key, members in by_exp.items():
        table = [None] * (max(c.index for c in members) + 1)
        for c in members:
            table[c.index] = c
        _LOADED[key] = tuple(table)


def _in_order(cases, groups, result_of, done, wait_some):
    """Yield results in case order while reporting each completion as it happens.

    ``groups``: (future, case indices) pairs; ``result_of(future)`` is the list of those cases'
    outcomes (a pool's future runs one case, a Dask task a batch of them).

    If the wait is interrupted (Ctrl-C, SIGTERM), the cases that finished but could not be
    yielded yet (a case before them is still running) travel on the exception, as its
    ``finished`` list in case order, so that the caller can store them too.
    """
    members = {f: indices for f, indices in groups}
    ready: dict[int, object] = {}
    pending = set(members)
    nxt = 0
    try:
        while nxt < len(cases):
            for f in wait_some(pending):
                pending.discard(f)
                for i, outcome in zip(members[f], result_of(f)):
                    ready[i] = _attach(cases[i], outcome)
                    done(ready[i])
            while nxt in ready:
                yield ready.pop(nxt)
                nxt += 1
    except BaseException as exc:
        for f in pending:  # finished while we were interrupted
            try:
                if f.done():
                    for i, outcome in zip(members[f], result_of(f)):
                        if i not in ready:
                            ready[i] = _attach(cases[i], outcome)
            except BaseException:  # cancelled, failed or lost with its worker: not finished
                pass
        exc.finished = [ready[i] for i in sorted(ready)]
        raise


def _run_dask(cases, jobs, scheduler, opts, done, limits=None, import_options=None, on_note=None):
    try:
        from distributed import Client, LocalCluster, wait
    except ImportError:
        raise InputError("`--executor dask` needs Dask's distributed package: pip install 'odelab[dask]'.",
                         key="executor") from None
    _seed(cases)  # an in-process worker finds them here; others load the files
    return _dask_results(cases, jobs, scheduler, opts, done, Client, LocalCluster, wait, limits, import_options,
                         on_note)


#: How long to wait for a Dask scheduler to answer, and for it to have a worker.
DASK_CONNECT_SECONDS = 10.0
DASK_WORKERS_SECONDS = 30.0

#: While cases run on a cluster the run looks at it every DASK_POLL_SECONDS (workers that left
#: or joined); when no case has finished for DASK_PROBE_SECONDS it asks the scheduler to answer,
#: and one that does not within DASK_SILENT_SECONDS is lost. A scheduler whose process dies is
#: noticed at once (its connection closes).
DASK_POLL_SECONDS = 1.0
DASK_PROBE_SECONDS = 10.0
DASK_SILENT_SECONDS = 30.0


class ClusterLost(InputError):
    """The Dask scheduler went away mid-run: the cases that finished are on ``finished``."""


#: A Dask task runs a batch of consecutive cases (in :func:`schedule`'s order) of at most this
#: many, and there are at least :data:`DASK_TASKS_PER_WORKER` tasks per worker thread: the
#: scheduler's and the client's bookkeeping cost about a millisecond a task, as much as a small
#: case, so one task per case spends a core on bookkeeping; a few tasks per thread keep the
#: workers evenly busy to the end.
DASK_BATCH = 64
DASK_TASKS_PER_WORKER = 8


def dask_batches(order: list[int], threads: int) -> list[list[int]]:
    """``order`` cut into consecutive batches for ``threads`` worker threads (see :data:`DASK_BATCH`)."""
    size = max(1, min(DASK_BATCH, len(order) // max(1, threads * DASK_TASKS_PER_WORKER)))
    return [order[k:k + size] for k in range(0, len(order), size)]


def _run_batch(items: list, opts: dict, limits=None, import_options=None) -> list:
    """In a Dask worker: each case of a batch, in order: a built case as it came (:func:`_run_sent`), or one
    given by reference (file, hash, index, experiment) loaded here (:func:`_run_remote`)."""
    return [_run_sent(item, opts) if not isinstance(item, tuple) else _run_remote(*item, opts, limits, import_options)
            for item in items]


def _run_sent(case, opts: dict):
    """Run a built case sent to this worker; the result travels back without the case."""
    from odelab.run.runner import run_case

    try:
        result = run_case(case, **opts)
    except InputError as exc:
        return "error", exc
    return "ok", dataclasses.replace(result, case=None)


def _travelling(cases) -> Callable[[int], object]:
    """``item(i)``: what a Dask worker receives for case ``i``: the built case where the experiment's cases
    travel (:func:`travels`, tried on its first case), else the reference a worker loads it by."""
    sends: dict[tuple, bool] = {}

    def item(i):
        case = cases[i]
        key = (_source(case), case.file_hash, case.experiment)
        if key not in sends:
            sends[key] = travels(case)
        return case if sends[key] else _submit_args(case, {})[:4]

    return item


def travels(case) -> bool:
    """Whether a built case can be sent to another process as it is: it pickles, and every module its pickle
    names can be imported there by name (not a user's function file, loaded here from its path)."""
    import pickle

    dispatch = dict(pickle._Pickler.dispatch)  # its table calls save_global unbound: route it to the override
    dispatch[types.FunctionType] = dispatch[types.BuiltinFunctionType] = lambda self, obj: self.save_global(obj)

    class Modules(pickle._Pickler):  # the pure-Python pickler, which says what it saves by reference
        def save_global(self, obj, name=None):
            self.found.add(getattr(obj, "__module__", None) or pickle.whichmodule(obj, name or obj.__qualname__))
            super().save_global(obj, name)

    pickler = Modules(io.BytesIO(), protocol=4)  # 5 trips the pure-Python pickler on numpy buffers
    pickler.dispatch = dispatch
    pickler.found = set()
    try:
        pickler.dump(case)
    except Exception:  # noqa: BLE001 - whatever keeps it from pickling (a loaded FMU binary)
        return False
    tops = {m.partition(".")[0] for m in pickler.found}
    return all(top in sys.builtin_module_names or importlib.machinery.PathFinder.find_spec(top) is not None
               for top in tops)


_DIGEST: list[str] = []  # this process's source digest, computed once


def source_digest() -> str:
    """SHA-256 over the files of the odelab package this process imports (each file's path inside the
    package and its bytes, in sorted order; bytecode caches left out), computed once a process: a Dask
    worker must give the client's."""
    if not _DIGEST:
        import hashlib  # only a Dask run asks

        root = Path(__file__).resolve().parents[1]  # the odelab package this module belongs to
        digest = hashlib.sha256()
        for path in sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts
                           and p.suffix != ".pyc"):
            name = path.relative_to(root).as_posix().encode()
            data = path.read_bytes()
            digest.update(len(name).to_bytes(4, "little") + name + len(data).to_bytes(8, "little") + data)
        _DIGEST.append(digest.hexdigest())
    return _DIGEST[0]


def _dask_results(cases, jobs, scheduler, opts, done, Client, LocalCluster, wait, limits=None, import_options=None,
                  on_note=None):
    cluster = None
    if scheduler:
        client = _dask_client(scheduler, Client)
    else:
        cluster, client = _local_cluster(jobs, Client, LocalCluster)
    watch = _ClusterWatch(client, f"the Dask scheduler at {scheduler!r}" if scheduler else "the local Dask cluster",
                          on_note)
    futures: list = []
    try:
        watch.check_versions(set(client.scheduler_info(n_workers=-1)["workers"]))
        threads = sum(client.nthreads().values()) or jobs
        groups = []
        batches = dask_batches(schedule(cases), threads)
        item = _travelling(cases)
        for rank, batch in enumerate(batches):  # the scheduler runs higher priorities first
            items = [item(i) for i in batch]
            future = client.submit(_run_batch, items, opts, limits, import_options, pure=False,
                                   priority=len(batches) - rank)
            futures.append(future)
            groups.append((future, batch))

        def wait_some(pending):
            while True:
                try:
                    finished = wait(list(pending), timeout=DASK_POLL_SECONDS, return_when="FIRST_COMPLETED").done
                except TimeoutError:
                    watch.look(time.monotonic(), progressed=False)
                    continue
                watch.look(time.monotonic(), progressed=True)
                return finished

        try:
            yield from _in_order(cases, groups, lambda f: f.result(), done, wait_some)
        except Exception as exc:  # noqa: BLE001 - what the cluster raises when its scheduler is gone
            if isinstance(exc, InputError) or not watch.lost(exc):
                raise
            raise watch.lost_error(getattr(exc, "finished", [])) from None
    except BaseException:
        _cancel_quietly(client, futures)
        raise
    finally:
        _close_quietly(client)
        if cluster is not None:
            cluster.close()


class _ClusterWatch:
    """What the run sees of its cluster while it waits: workers that leave (their cases run again on
    the others: said once per worker), workers that join (their odelab checked), a scheduler gone."""

    def __init__(self, client, where: str, on_note) -> None:
        self.client, self.where, self.on_note = client, where, on_note
        self.known: dict[str, str] = {}  # worker address -> its name
        self.last = None  # when a case last finished (monotonic seconds), None before the first look
        self.looked = -math.inf  # when the workers were last looked at
        self.said: set[str] = set()

    def check_versions(self, addresses: set[str]) -> None:
        """Refuse workers whose odelab is not this process's (the results would mix versions): another version
        number, or the same number over other source files (a worker started from another checkout)."""
        info = self.client.get_versions(packages=["odelab"])
        for address in sorted(addresses):
            worker = info["workers"].get(address) or {}
            theirs = (worker.get("packages") or {}).get("odelab") if isinstance(worker, dict) else None
            if theirs != __version__:
                shown = f"odelab {theirs}" if theirs else "no odelab installed"
                raise InputError(f"the Dask worker {address} of {self.where} has {shown}, and this process runs "
                                 f"odelab {__version__}: every worker must run the same odelab, or the results would "
                                 f"mix versions. Install odelab {__version__} in the workers' environment (pip install "
                                 f"odelab=={__version__}) and restart them.", key="scheduler")
        self._check_sources(sorted(addresses), __version__)
        workers = self.client.scheduler_info(n_workers=-1)["workers"]
        self.known.update({a: str(workers.get(a, {}).get("name", a)) for a in addresses})

    def _check_sources(self, addresses: list[str], version: str) -> None:
        """The same version number is not the same code (a development tree, an edited install): each worker
        hashes its odelab's files (:func:`source_digest`) and must find this process's digest."""
        if not addresses:
            return
        mine = source_digest()
        try:
            theirs = self.client.run(source_digest, workers=addresses)
        except Exception as exc:  # noqa: BLE001 - a worker that cannot even run the check runs other code
            theirs = {a: f"unknown ({type(exc).__name__})" for a in addresses}
        for address in addresses:
            if theirs.get(address) != mine:
                raise InputError(f"the Dask worker {address} of {self.where} runs odelab {version} from other source "
                                 f"files than this process (their digest {str(theirs.get(address))[:12]}, this one's "
                                 f"{mine[:12]}): every worker must run the same odelab code, or the results would "
                                 "mix versions. Start the workers from the environment this process runs in (the "
                                 "same install or checkout) and restart them.", key="scheduler")

    def look(self, now: float, progressed: bool) -> None:
        """After each wait (at most every DASK_POLL_SECONDS): workers that left or joined; and when
        nothing has finished for DASK_PROBE_SECONDS, a probe of the scheduler."""
        if self.last is None or progressed:
            self.last = now
        if now - self.looked < DASK_POLL_SECONDS:
            return
        self.looked = now
        try:
            current = set(self.client.scheduler_info(n_workers=-1)["workers"])
        except Exception:  # noqa: BLE001 - the scheduler's state as last sent; a lost one is found below
            current = set(self.known)
        for address in sorted(set(self.known) - current - self.said):
            self.said.add(address)
            if self.on_note is not None:
                self.on_note(f"the Dask worker {self.known[address]} ({address}) left {self.where} mid-run; the "
                             "cases it was running ran again on the other workers (the results are the same).")
        joined = current - set(self.known)
        if joined:
            self.check_versions(joined)
        if now - self.last >= DASK_PROBE_SECONDS:
            try:
                self.client.sync(self.client.scheduler.identity, callback_timeout=DASK_SILENT_SECONDS)
            except Exception as exc:  # noqa: BLE001 - any failure to answer is a lost scheduler
                if self.lost(exc) or isinstance(exc, (TimeoutError, OSError)):
                    raise self.lost_error([]) from None
                raise
            self.last = now

    def lost(self, exc: BaseException) -> bool:
        """Whether ``exc`` says the scheduler is gone (a cancelled wait, a closed connection)."""
        import asyncio
        import concurrent.futures

        names = {type(e).__name__ for e in (exc, exc.__cause__, exc.__context__) if e is not None}
        return (isinstance(exc, (asyncio.CancelledError, concurrent.futures.CancelledError, OSError, TimeoutError))
                or bool(names & {"FuturesCancelledError", "FutureCancelledError", "CancelledError", "CommClosedError"})
                or self.client.status in ("closing", "closed", "connecting"))

    def lost_error(self, finished) -> ClusterLost:
        error = ClusterLost(f"lost {self.where} mid-run: its process ended, or it did not answer for "
                            f"{DASK_SILENT_SECONDS:g} s. Start it again and run the experiment again.",
                            key="scheduler")
        error.finished = list(finished)
        return error


def _cancel_quietly(client, futures) -> None:
    try:
        client.cancel(futures)
    except Exception:  # noqa: BLE001 - a client without its scheduler cannot cancel; nothing runs then
        pass


def _close_quietly(client) -> None:
    import logging

    quiet = logging.getLogger("distributed.client")
    level = quiet.level
    quiet.setLevel(logging.CRITICAL)  # "Failed to reconnect to scheduler" after a lost one: said once, by us
    try:
        client.close(timeout=DASK_CONNECT_SECONDS)
    except Exception:  # noqa: BLE001 - closing a client whose scheduler died
        pass
    finally:
        quiet.setLevel(level)


def _dask_client(scheduler: str, Client):
    """A client of the scheduler at ``scheduler`` that has at least one worker, or an InputError
    within :data:`DASK_CONNECT_SECONDS` + :data:`DASK_WORKERS_SECONDS`.

    distributed's own connect timeout does not cover the handshake: an address that accepts
    the connection and never answers would hang it for ever. So the handshake is tried first,
    under a deadline of our own.
    """
    import asyncio

    where = f"the Dask scheduler at {scheduler!r}"
    fix = "Check the address (tcp://host:8786) and that `dask scheduler` is running there."

    async def handshake():
        from distributed.comm import connect

        comm = await asyncio.wait_for(connect(scheduler, timeout=DASK_CONNECT_SECONDS), DASK_CONNECT_SECONDS)
        await comm.close()

    def probe():  # in a thread of its own: the caller may already run an event loop (Jupyter)
        try:
            asyncio.run(handshake())
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            failed.append(exc)

    failed: list[BaseException] = []
    thread = threading.Thread(target=probe, name="odelab-dask-probe", daemon=True)
    thread.start()
    thread.join()
    try:
        if failed:
            raise failed[0]
        client = Client(scheduler, timeout=DASK_CONNECT_SECONDS)
    except (OSError, TimeoutError, asyncio.TimeoutError, ValueError, TypeError) as exc:
        why = str(exc) or f"no answer within {DASK_CONNECT_SECONDS:g} s"
        raise InputError(f"cannot reach {where}: {why}. {fix}", key="scheduler") from None
    try:
        client.wait_for_workers(1, timeout=DASK_WORKERS_SECONDS)
    except (OSError, TimeoutError, asyncio.TimeoutError):
        client.close()
        raise InputError(f"{where} has no workers (none joined within {DASK_WORKERS_SECONDS:g} s): start some "
                         f"with `dask worker {scheduler}`, or leave out --scheduler for a local cluster.",
                         key="scheduler") from None
    return client


def _local_cluster(jobs: int, Client, LocalCluster):
    """A local cluster of ``jobs`` worker processes that die with this process, and its client."""
    from odelab.run.lifeline import exit_with_parent

    import logging

    spec_log = logging.getLogger("distributed.deploy.spec")  # "Cluster closed without starting up"
    level = spec_log.level
    spec_log.setLevel(logging.ERROR)
    try:
        cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None)
    except Exception as exc:  # noqa: BLE001 - distributed wraps whatever stopped it in a RuntimeError
        cause = exc.__cause__ or exc
        raise InputError(f"could not start a local Dask cluster: {cause}. Its workers need a folder they can "
                         "create: point DASK_TEMPORARY_DIRECTORY (or TMPDIR) at a folder you can write, or run "
                         "with --executor process.", key="executor") from None
    finally:
        spec_log.setLevel(level)
    client = Client(cluster)
    try:  # the workers are children of this process (their nannies run here)
        client.run(exit_with_parent, os.getpid())
    except BaseException:
        client.close()
        cluster.close()
        raise
    return cluster, client
