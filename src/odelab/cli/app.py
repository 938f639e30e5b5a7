"""The ``odelab`` command line: a thin layer over the library.

Commands turn the package's exceptions into one clear message and an exit code:
0 everything ran, 1 some case failed in integration, 2 bad input or usage. Nothing heavy is
imported at module level, so ``odelab --help`` starts fast (no numpy, scipy or matplotlib).
The annotations are evaluated when the functions are defined (no ``from __future__ import
annotations``): Typer reads every command's parameters on every start, and string annotations
would cost it a compile and an eval each (18 ms of a start, against 4).
"""

import contextlib
import os
import signal
import sys
import textwrap
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Optional

import typer

from odelab import __version__
from odelab.exceptions import InputError
from odelab.run import runfiles as rf
from odelab.run.runfiles import RunConfig, Terminated, error_text, expand_paths, run_files

app = typer.Typer(
    name="odelab",
    help="Model and simulate engineering systems from TOML experiment files, with MATLAB-faithful ode23/ode45.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)

EXIT_OK, EXIT_FAILED, EXIT_INPUT = 0, 1, 2
MAX_STEPS_HELP = ("Budget of steps per solve: an adaptive solve stops there, a fixed-step one over it is refused "
                  "before it runs, a file's own max_steps is capped by it (0: no limit).")
LIMIT_HELP = ("Raise (or lower) a work or memory budget, NAME=N: points (2000000 output points per case), refine "
              "(100), cases (1000 per file), amplitudes (100), table_rows (10000), events (10000 per case), states "
              "(5000 per system); 0: no limit. Repeatable.")
NATIVE_HELP = ("Allow [system] kind = \"fmu\" files: simulating an FMU runs the machine code inside it, with your "
               "permissions; give this only for FMUs you trust.")


WORKSPACE_HELP = ("A MATLAB script that assigns the workspace variables a MATLAB or Simulink file uses (read, never "
                  "run); repeatable, read in order.")
SET_HELP = "Set a workspace variable or parameter of a MATLAB or Simulink file, NAME=VALUE (a MATLAB value). Repeatable."
CALL_HELP = ("The solver call for a MATLAB function file that has none, as typed at MATLAB's prompt: "
             "\"[t,y] = ode23(@eq1, [0 pi], 2)\".")


class _Command(typer.core.TyperCommand):
    """A command whose arguments show their metavar as written (``FILES...``), not Typer's ``<list[Path]>``."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        for param in self.params:
            if isinstance(param, typer.core.TyperArgument) and param.metavar:
                shown = param.metavar if param.required else f"[{param.metavar}]"
                param.display_type = lambda ctx: ""  # the metavar says it: no type after it
                param._usage_display_name = lambda shown=shown: shown


def _version(value: bool) -> None:
    if value:
        typer.echo(f"odelab {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[Optional[bool], typer.Option("--version", callback=_version, is_eager=True,
                                                    help="Show the version and exit.")] = None,
) -> None:
    """odelab: MATLAB-faithful ODE experiments, error tables and lab reports."""


def _one_blas_thread() -> None:
    """One BLAS thread per process, set before numpy loads it (as joblib does for its workers),
    unless the user's environment says otherwise. ``run`` and ``grade`` make thousands of tiny
    calls (a 2-by-2 expm per case, a small LU per step), where OpenBLAS's threads only contend:
    8 ms an expm on a busy 2-core machine, 35 us on one thread; --jobs runs processes instead."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def _consoles(width: int | None = None):
    """The output and error consoles. Their width: ``--width``, else ``COLUMNS``, else the terminal's; piped
    or redirected with neither, 200 (a table is never cut to 80 columns for a file)."""
    from rich.console import Console

    if width is None:
        try:
            width = int(os.environ.get("COLUMNS", "")) or None
        except ValueError:
            width = None
        width = width if width is None or width >= 20 else 20
    # emoji=False: ":x:" in a user's title or message stays ":x:" (user text reaches Rich only
    # through odelab.terminal.shown, which escapes markup and makes control characters visible)
    out = Console(highlight=False, emoji=False, width=width)
    if not out.is_terminal:  # piped or redirected: never truncate a table to 80 columns unless asked to
        # and settle it once (Rich's default height, 25, as it finds no terminal): otherwise Rich asks the
        # environment and the terminal's size again at every print, a third of the cost of a short line
        out = Console(highlight=False, emoji=False, width=width or 200, height=25, force_terminal=False)
    return out, Console(stderr=True, highlight=False, soft_wrap=True, emoji=False)


_error_text = error_text  # the core's one-line form of an error (odelab.run.runfiles)


@app.command(cls=_Command)
def run(
    paths: Annotated[list[Path], typer.Argument(help="Experiment files or folders of them.", show_default=False,
                                                metavar="FILES...")],
    runs: Annotated[Path, typer.Option("--runs", help="Results folder.", metavar="FOLDER")] = Path("runs"),
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON document instead of tables.")] = False,
    trajectories: Annotated[bool, typer.Option(
        "--trajectories", help="With --json: add each case's trajectory (t, states, inputs, outputs, references, "
        "errors); --table does too.")] = False,
    table: Annotated[bool, typer.Option("--table", help="Print the per-point error table of every case.")] = False,
    mat: Annotated[bool, typer.Option("--mat", help="Also store result.mat for MATLAB.")] = False,
    max_steps: Annotated[int, typer.Option("--max-steps", min=0, help=MAX_STEPS_HELP, metavar="N")] = 1_000_000,
    limit: Annotated[Optional[list[str]], typer.Option("--limit", help=LIMIT_HELP, show_default=False,
                                                               metavar="NAME=N")] = None,
    store: Annotated[bool, typer.Option("--store/--no-store", help="Write results to the results folder.")] = True,
    backend: Annotated[Optional[str], typer.Option(
        "--backend", help="auto, python or compiled (numba); overrides [solver] backend.", show_default=False,
        metavar="NAME")] = None,
    jobs: Annotated[Optional[int], typer.Option("--jobs", "-j", min=1, show_default="the number of cores", metavar="N",
                                                help="Cases run at once (a process pool).")] = None,
    executor: Annotated[str, typer.Option("--executor", metavar="NAME", help="process (a local pool; 1 job: serial), serial or "
                                                             "dask.")] = "process",
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", metavar="ADDRESS", help="Dask scheduler address (tcp://host:8786) "
                                                     "for --executor dask; none: a local Dask cluster.")] = None,
    validate_with: Annotated[Optional[Path], typer.Option(
        "--validate-with", metavar="CSV", help="Check each [fit]'s fitted model against a second data set (read as "
        "[data] reads its file).", show_default=False)] = None,
    width: Annotated[Optional[int], typer.Option(
        "--width", min=40, metavar="N", show_default="COLUMNS, else the terminal's (200 when piped)",
        help="Lay the tables out for this many columns (numbers are never cut: a table too wide is split).")] = None,
    allow_native: Annotated[bool, typer.Option("--allow-native", help=NATIVE_HELP)] = False,
    workspace: Annotated[Optional[list[Path]], typer.Option(
        "--workspace", metavar="SCRIPT.m", help=WORKSPACE_HELP, show_default=False)] = None,
    sets: Annotated[Optional[list[str]], typer.Option("--set", metavar="NAME=VALUE", help=SET_HELP,
                                                      show_default=False)] = None,
    call: Annotated[Optional[str], typer.Option("--call", metavar="CALL", help=CALL_HELP, show_default=False)] = None,
    estimate: Annotated[Optional[bool], typer.Option(
        "--estimate/--no-estimate", show_default=False,
        help="The global error estimate (a second solve at RelTol and AbsTol / 10) for every case, or for none; "
        "default: every case without a reference, except a [sweep]'s (overrides [solver] estimate_error).")] = None,
    strict: Annotated[bool, typer.Option(
        "--strict", help="Exit 1 also when a result is unreliable (ok?: its error estimate disagrees with it).")
    ] = False,
) -> None:
    """Run experiments: solve every case, print the error tables and store the results."""
    _one_blas_thread()  # before numpy's import

    from odelab.run.executors import EXECUTORS

    # Everything worth saying (RelTol raised, equilibrium residuals...) reaches the user as a
    # note in the output; Python's own warning lines would only repeat it.
    warnings.simplefilter("ignore")
    out, err = _consoles(width)
    limits = _limits(max_steps, limit, err)
    if backend is not None and backend not in ("auto", "python", "compiled"):
        err.print(f"[bold red]error:[/] `--backend` is {_escape(repr(backend))}; use auto, python or compiled.")
        raise typer.Exit(EXIT_INPUT)
    if executor not in EXECUTORS:
        err.print(f"[bold red]error:[/] `--executor` is {_escape(executor)!r}; it must be one of "
                  f"{', '.join(EXECUTORS)}.")
        raise typer.Exit(EXIT_INPUT)
    if scheduler and executor != "dask":
        err.print("[bold red]error:[/] `--scheduler` is the address of a Dask scheduler: add `--executor dask`.")
        raise typer.Exit(EXIT_INPUT)
    config = RunConfig(runs=runs, store=store, mat=mat, max_steps=max_steps, limits=limits, backend=backend,
                       jobs=jobs, executor=executor, scheduler=scheduler, validate_with=validate_with,
                       allow_native=allow_native, import_options=_import_options(workspace, sets, call, err),
                       estimate=estimate, strict=strict)
    _draw_run(run_files(paths, config), out, err, runs=runs, json_out=json_out, table=table or trajectories)


def _import_options(workspace, sets, call, err, output=None):
    """--workspace, --set and --call for the readers of MATLAB and Simulink files (a bad --set is exit 2)."""
    from odelab.formats.base import ImportOptions

    pairs = []
    for text in sets or []:
        name, sep, value = text.partition("=")
        if not sep or not name.strip() or not value.strip():
            err.print(f"[bold red]error:[/] `--set {_escape(text)}`: write NAME=VALUE, e.g. --set k=2.")
            raise typer.Exit(EXIT_INPUT)
        pairs.append((name.strip(), value.strip()))
    if not (workspace or pairs or call or output):
        return None
    return ImportOptions(workspace=tuple(workspace or ()), sets=tuple(pairs), call=call, output=output)


@contextlib.contextmanager
def _stopped_by_signals(err, what: str):
    """Ctrl-C (exit 130) and SIGTERM (exit 143) stop the command with one line saying ``what`` of its
    output (it writes each file whole or not at all), no traceback."""
    def on_term(signum, frame):
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    except (KeyboardInterrupt, Terminated) as exc:
        word, code = ("interrupted", 130) if isinstance(exc, KeyboardInterrupt) else ("terminated", 143)
        err.print(f"[bold red]{word}:[/] {what}.")
        raise typer.Exit(code) from None
    finally:
        signal.signal(signal.SIGTERM, previous)


def _limits(max_steps: int, limit: list[str] | None, err):
    """The run's budgets from --max-steps and --limit NAME=N (a bad --limit is a usage error, exit 2)."""
    from odelab.experiment.limits import DEFAULT_LIMITS, parse_limit

    limits = replace(DEFAULT_LIMITS, steps=max_steps)
    for text in limit or []:
        try:
            limits = parse_limit(text, limits)
        except InputError as exc:
            err.print(f"[bold red]error:[/] {_escape(str(exc))}")
            raise typer.Exit(EXIT_INPUT) from None
    return limits


def _draw_run(run, out, err, *, runs, json_out: bool, table: bool) -> None:
    """Draw a run's events (odelab.run.runfiles): errors, a progress bar, each experiment's tables or one
    JSON document; Ctrl-C and SIGTERM stop it cleanly (finished cases stay stored, nothing half-written)."""
    def on_term(signum, frame):
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, on_term)
    events = iter(run)
    try:
        code = _draw_events(events, out, err, runs=runs, json_out=json_out, table=table)
    except (KeyboardInterrupt, Terminated) as exc:
        try:  # an interrupt between two events: the run stores what finished all the same
            events.throw(exc)
        except (KeyboardInterrupt, Terminated):
            pass
        total = run.total
        what = "interrupted" if isinstance(exc, KeyboardInterrupt) else "terminated"
        err.print(f"[bold red]{what}:[/] {run.finished} of {total} case{'s' if total != 1 else ''} finished and "
                  "stored; the case that was running was not stored.")
        raise typer.Exit(130 if isinstance(exc, KeyboardInterrupt) else 143) from None
    finally:
        signal.signal(signal.SIGTERM, previous)
    raise typer.Exit(code)


def _draw_events(events, out, err, *, runs, json_out: bool, table: bool) -> int:
    """The exit code, after drawing every event."""
    report_json = {"experiments": []}
    progress = task = None
    with contextlib.ExitStack() as stack:
        for event in events:
            if isinstance(event, rf.FileError):
                where = f" (case {_escape(repr(event.case))})" if event.case is not None else ""
                err.print(f"[bold red]error:[/] {_escape(event.message)}{where}")
            elif isinstance(event, rf.Notice):
                err.print(f"[yellow]warning:[/] {_escape(event.message)}")
                report_json.setdefault("warnings", []).append(event.message)
            elif isinstance(event, rf.LeftoversRemoved):
                err.print(f"note: {_escape(leftovers_line(event.removed))}")
                report_json["removed"] = [{"path": str(s.path), "bytes": s.size, "pid": s.pid} for s in event.removed]
            elif isinstance(event, rf.Fatal):
                err.print(f"[bold red]error:[/] {_escape(event.message)}")
                return EXIT_INPUT
            elif isinstance(event, rf.References):
                _prepare_references(event, err)
            elif isinstance(event, rf.Started):
                progress = stack.enter_context(_progress(err, shown=event.total >= 2 and err.is_terminal))
                task = progress.add_task("running", total=event.total, failed=0)
            elif isinstance(event, rf.ExperimentStarted):
                progress.update(task, description=_escape(event.experiment.name))
            elif isinstance(event, rf.CaseDone):
                progress.update(task, completed=event.finished, failed=event.failed)
            elif isinstance(event, rf.ExperimentDone):
                _draw_experiment(event.experiment, event.results, out, report_json if json_out else None, table)
            elif isinstance(event, rf.Finished):
                finished = event
    if json_out:
        import json

        if finished.errors:
            report_json["errors"] = list(finished.errors)
        sys.stdout.write(json.dumps(report_json, indent=2, allow_nan=False) + "\n")
    elif finished.stored:
        out.print(f"results stored in {_escape(str(runs))}/")
    return EXIT_INPUT if finished.errors else EXIT_FAILED if finished.any_failed else EXIT_OK


def _draw_experiment(exp, results, out, report_json: dict | None, table: bool) -> None:
    if report_json is not None:
        from odelab.store.results import summary

        report_json["experiments"].append({
            "name": exp.name, "title": exp.title, "file": str(exp.source),
            "cases": [{"name": r.case.name, **summary(r), **(_trajectory(r) if table else {})} for r in results]})
    elif results:
        from odelab.cli.display import print_experiment

        print_experiment(out, exp, results, table=table)


class _NoProgress:
    """What ``_draw_events`` asks of a progress bar, when none is shown (one case, or output not a terminal)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    def add_task(self, *args, **kwargs) -> int:
        return 0

    def update(self, *args, **kwargs) -> None:
        return None


def leftovers_line(removed) -> str:
    """One line for the hidden folders of killed runs that a run removed first (odelab.store.hidden.Stale):
    where and how much (the dead process's pid is in each name)."""
    size = _megabytes(sum(s.size for s in removed))
    if len(removed) == 1:
        return f"removed {removed[0].path} ({size}), left by a killed run."
    named = ", ".join(str(s.path) for s in removed[:2]) + (f" and {len(removed) - 2} more" if len(removed) > 2 else "")
    return f"removed {len(removed)} folders ({size}) left by killed runs: {named}."


def _megabytes(size: int) -> str:
    return f"{size / 1e6:.1f} MB" if size >= 1_000_000 else f"{size / 1e3:.1f} kB"


def _prepare_references(event, err) -> None:
    """The high-accuracy references the cases share, with a status line on stderr: which solver (and why a
    stiff one), then how far it got, then done (see docs/guide/references.md)."""
    if not err.is_terminal:  # a log or a pipe: the case's notes say which solver and why
        event.prepare(None)
        return
    with err.status("", spinner="dots") as live:
        def line(text: str) -> None:
            if ": t = " not in text:  # which solver, why, done: kept; how far it got: the status line only
                err.print(f"[dim]{_escape(text)}[/]")
            live.update(_escape(text))

        event.prepare(line)


def _progress(err, *, shown: bool):
    """Rich's progress bar on the error console, or a stand-in (rich.progress is imported only when shown)."""
    if not shown:
        return _NoProgress()
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("[red]{task.fields[failed]} failed[/]"), TimeRemainingColumn())
    return Progress(*columns, console=err, transient=True)


def _trajectory(result) -> dict:
    """``--json --trajectories`` (or ``--table``): every column of the case at its output times."""
    from odelab.analysis.errors import error_columns
    from odelab.store.results import json_safe

    columns = {"t": result.t, **result.series()}
    for name, ref in result.reference.items():
        abs_err, rel_err = error_columns(columns[name], ref)
        columns.update({f"{name}_ref": ref, f"{name}_abs_err": abs_err, f"{name}_rel_err": rel_err})
    return {"trajectory": json_safe(columns)}


def _escape(text: str) -> str:
    """User text (or a message quoting it) for a Rich markup string: see :mod:`odelab.terminal`."""
    from odelab.terminal import shown

    return shown(text, lines=True)


@app.command(cls=_Command)
def report(
    experiments: Annotated[Optional[list[str]], typer.Argument(
        help="Experiments to include, by name or by experiment file (default: every one in the results folder).",
        show_default=False, metavar="EXPERIMENTS...")] = None,
    runs: Annotated[Path, typer.Option("--runs", help="Results folder to read.", metavar="FOLDER")] = Path("runs"),
    out: Annotated[Path, typer.Option("--out", help="Folder to write the report to.", metavar="FOLDER")] = Path("report"),
    fmt: Annotated[str, typer.Option("--format", help="html, md or both.", metavar="FORMAT")] = "both",
    template: Annotated[Optional[Path], typer.Option("--template", metavar="FOLDER",
                                                     help="A folder of Jinja templates to use instead.")] = None,
    jobs: Annotated[Optional[int], typer.Option("--jobs", "-j", min=1, show_default="the number of cores",
                                                metavar="N", help="Figures drawn at once (processes).")] = None,
) -> None:
    """Build the lab report (HTML and Markdown, with plots and error tables) from stored runs."""
    from odelab.report import build_report

    warnings.simplefilter("ignore")
    out_console, err = _consoles()
    try:
        with _stopped_by_signals(err, "the report was not written; the one in "
                                 f"{_escape(str(out))}/ is as it was (figures drawn so far may be newer)"):
            result = build_report(runs, out, formats=fmt, experiments=_experiment_names(experiments) or None,
                                  template_dir=template, jobs=jobs)
    except InputError as exc:
        err.print(f"[bold red]error:[/] {_escape(_error_text(exc))}")
        raise typer.Exit(EXIT_INPUT) from None
    for line in result.warnings:
        err.print(f"[yellow]warning:[/] {_escape(line)}")
    for path in result.paths:
        if path.suffix in (".html", ".md"):
            out_console.print(f"wrote {_escape(str(path))}")
    figures = sum(1 for p in result.paths if p.suffix in (".png", ".svg"))
    if figures:
        out_console.print(f"wrote {figures} figures in {_escape(str(out / 'figures'))}/")


def _experiment_names(given: list[str] | None) -> list[str]:
    """`odelab report pendulum.toml` (or `rigid.m`, `msd.slx`) as well as `odelab report pendulum`: a file
    stands for its experiment (a TOML file's `name`, else the file's stem)."""
    from odelab.formats import is_experiment_file

    names = []
    for item in given or []:
        path = Path(item)
        if is_experiment_file(path) and path.suffix.lower() == ".toml" and path.is_file():
            from odelab.formats.toml import read_toml

            try:
                data, _ = read_toml(path)
            except InputError:
                data = {}
            name = data.get("name") if isinstance(data.get("name"), str) else None
            names.append(name or path.stem)
        else:
            names.append(path.stem if is_experiment_file(path) else item)
    return names


@app.command(cls=_Command)
def validate(
    paths: Annotated[list[Path], typer.Argument(help="Experiment files or folders of them.", show_default=False,
                                                metavar="FILES...")],
    max_steps: Annotated[int, typer.Option("--max-steps", min=0, help=MAX_STEPS_HELP, metavar="N")] = 1_000_000,
    limit: Annotated[Optional[list[str]], typer.Option("--limit", help=LIMIT_HELP, show_default=False,
                                                               metavar="NAME=N")] = None,
) -> None:
    """Check experiment files without running them (with the budgets `odelab run` would use)."""
    from odelab.experiment.loader import load_experiments
    from odelab.experiment.naming import check_experiment_names

    out, err = _consoles()
    limits = _limits(max_steps, limit, err)
    files, problems = expand_paths(paths)
    bad = len(problems)
    for path, why in problems:
        err.print(f"[bold red]error:[/] {_escape(str(path))}: {_escape(why)}")
    loaded = []
    for file in files:
        try:
            exps = load_experiments(file, limits=limits)
            for _, exc in check_experiment_names([*loaded, *exps]):
                raise exc
        except InputError as exc:
            bad += 1
            err.print(f"[bold red]error:[/] {_escape(_error_text(exc))}")
            continue
        loaded.extend(exps)
        from odelab.terminal import shown

        cases = [c for exp in exps for c in exp.cases]
        # names of a sweep hold ", " themselves ("h=0.05, method=rk4"): quote each, join with "; "
        sep = "; " if any(", " in c.name for c in cases) else ", "
        quote = (lambda n: f'"{n}"') if sep == "; " else (lambda n: n)
        names = sep.join(quote(c.name) for c in cases[:20]) + (f"{sep}... ({len(cases) - 20} more)"
                                                               if len(cases) > 20 else "")
        out.print(f"ok: {_escape(str(file))} ({len(cases)} case{'s' if len(cases) != 1 else ''}: "
                  f"{shown(names)})")
    raise typer.Exit(EXIT_INPUT if bad else EXIT_OK)


@app.command(cls=_Command)
def export(
    file: Annotated[Path, typer.Argument(help="The experiment file.", show_default=False, metavar="FILE.toml")],
    case: Annotated[Optional[str], typer.Option("--case", help="The case to export (default: the first).",
                                                show_default=False, metavar="NAME")] = None,
    output: Annotated[Optional[Path], typer.Option("-o", "--output", help="The FMU to write (default: the "
                                                   "experiment's name, .fmu, in the current folder).",
                                                   show_default=False, metavar="MODEL.fmu")] = None,
    fmi: Annotated[int, typer.Option("--fmi", help="The FMI version: 2 (FMI 2.0, which every tool loads) or 3 "
                                     "(FMI 3.0).", metavar="2|3")] = 2,
) -> None:
    """Export a case as an FMU (FMI 2.0 or 3.0, Model Exchange and Co-Simulation) for other simulation tools."""
    from odelab.experiment.loader import load_experiment
    from odelab.fmi import export as export_fmu

    out, err = _consoles()
    try:
        experiment = load_experiment(file)
        target = output if output is not None else Path(f"{experiment.name}.fmu")
        done = export_fmu(experiment, target, case=case, fmi=fmi)
    except InputError as exc:
        err.print(f"[bold red]error:[/] {_escape(_error_text(exc))}")
        raise typer.Exit(EXIT_INPUT) from None
    except OSError as exc:
        err.print(f"[bold red]error:[/] cannot write the FMU: {_escape(str(exc))}")
        raise typer.Exit(EXIT_INPUT) from None
    m = done.model
    chosen = case or experiment.cases[0].name
    more = f" (the first of {len(experiment.cases)}; --case picks another)" if case is None and \
        len(experiment.cases) > 1 else ""
    out.print(f"wrote {_escape(str(target))}: case {_escape(chosen)}{_escape(more)}, FMI {fmi}.0 Model Exchange and "
              f"Co-Simulation, {len(m.states)} state{'s' if len(m.states) != 1 else ''}, {len(m.outputs)} "
              f"output{'s' if len(m.outputs) != 1 else ''}, {len(m.parameters)} tunable parameter"
              f"{'s' if len(m.parameters) != 1 else ''}; compiled with {_escape(Path(done.compiler).name)} in "
              f"{done.compile_seconds:.2f} s")


@app.command(cls=_Command)
def new(
    file: Annotated[Path, typer.Argument(help="The experiment file to write.", show_default=False, metavar="FILE")],
    kind: Annotated[str, typer.Option("--kind", help="ode, state-space, diagram, network, python, sweep or study (every "
                                      "starter in odelab/templates).", metavar="KIND")] = "ode",
    force: Annotated[bool, typer.Option("--force", help="Overwrite an existing file.")] = False,
) -> None:
    """Write a commented starter experiment file."""
    from odelab.cli.templates import write_template
    from odelab.terminal import visible

    _, err = _consoles()
    try:
        written = write_template(file, kind, force=force)
    except ValueError as exc:
        err.print(f"[bold red]error:[/] {_escape(str(exc))}")
        raise typer.Exit(EXIT_INPUT) from None
    for path in written:
        typer.echo(f"wrote {visible(str(path))}")
    typer.echo(f"run it with: odelab run {visible(str(file))}")


@app.command(cls=_Command)
def grade(
    rubric: Annotated[Path, typer.Argument(help="The rubric file (rubric.toml).", show_default=False,
                                           metavar="RUBRIC")],
    submissions: Annotated[Optional[Path], typer.Argument(
        help="One folder per student (default: the rubric's `submissions`).", show_default=False,
        metavar="SUBMISSIONS")] = None,
    out: Annotated[Path, typer.Option("--out", help="The grades folder to write.", metavar="FOLDER")] = Path("grades"),
    json_out: Annotated[bool, typer.Option("--json", help="Print results.json (Gradescope's format) instead of "
                                                          "the table.")] = False,
    jobs: Annotated[Optional[int], typer.Option("--jobs", "-j", min=1, show_default="the number of cores",
                                                metavar="N", help="Students' cases run at once (a process pool).")] = None,
    max_steps: Annotated[int, typer.Option("--max-steps", min=0, help=MAX_STEPS_HELP, metavar="N")] = 1_000_000,
    limit: Annotated[Optional[list[str]], typer.Option("--limit", help=LIMIT_HELP, show_default=False,
                                                       metavar="NAME=N")] = None,
    allow_python: Annotated[bool, typer.Option("--allow-python", help="Run submissions whose system is a Python "
                                               "`function` (it runs the students' code).")] = False,
    backend: Annotated[str, typer.Option("--backend", metavar="NAME", help="python (the same numbers on every "
                                         "machine and run), auto or compiled.")] = "python",
    allow_native: Annotated[bool, typer.Option("--allow-native", help="Load submissions' FMUs (kind = \"fmu\"): "
                                               "it runs the machine code inside them.")] = False,
) -> None:
    """Grade a class's experiment files against a reference: summary.csv, feedback, results.json."""
    _one_blas_thread()

    warnings.simplefilter("ignore")
    out_console, err = _consoles()
    limits = _limits(max_steps, limit, err)
    if backend not in ("auto", "python", "compiled"):
        err.print(f"[bold red]error:[/] `--backend` is {_escape(repr(backend))}; use python, auto or compiled.")
        raise typer.Exit(EXIT_INPUT)
    from odelab.grading import class_document, grade_class, write_grades

    try:
        with _stopped_by_signals(err, "nothing was written"):
            grades = grade_class(rubric, submissions, limits=limits, max_steps=max_steps, jobs=jobs, backend=backend,
                                 allow_python=allow_python, allow_native=allow_native)
            written = write_grades(grades, out)
    except InputError as exc:
        err.print(f"[bold red]error:[/] {_escape(_error_text(exc))}")
        raise typer.Exit(EXIT_INPUT) from None
    except OSError as exc:
        err.print(f"[bold red]error:[/] cannot write the grades to {_escape(str(out))}: {_escape(str(exc))}")
        raise typer.Exit(EXIT_INPUT) from None
    if json_out:
        import json

        sys.stdout.write(json.dumps(class_document(grades), indent=2, ensure_ascii=False, allow_nan=False) + "\n")
        return
    from odelab.cli.grade_display import print_grades

    print_grades(out_console, grades)
    out_console.print(f"wrote {_escape(str(written[0]))}, results.json, summary.html and "
                      f"{len(grades.students)} feedback file{'s' if len(grades.students) != 1 else ''} in "
                      f"{_escape(str(out))}/")


@app.command("import", cls=_Command)
def import_(
    paths: Annotated[list[Path], typer.Argument(help="MATLAB (.m) or Simulink (.slx, .mdl) files.",
                                                show_default=False, metavar="FILES...")],
    out: Annotated[Optional[Path], typer.Option("--out", "-o", metavar="DIR", show_default="beside each file",
                                                help="The folder to write NAME.toml to.")] = None,
    workspace: Annotated[Optional[list[Path]], typer.Option(
        "--workspace", metavar="SCRIPT.m", help=WORKSPACE_HELP, show_default=False)] = None,
    sets: Annotated[Optional[list[str]], typer.Option("--set", metavar="NAME=VALUE", help=SET_HELP,
                                                      show_default=False)] = None,
    call: Annotated[Optional[str], typer.Option("--call", metavar="CALL", help=CALL_HELP, show_default=False)] = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite a NAME.toml that odelab import did not write.")]
    = False,
) -> None:
    """Write the experiment file of a MATLAB or Simulink file and show what was translated (never runs it).

    Exit 0: everything translated; 1: written with gaps to fill in (marked GAP:); 2: nothing usable."""
    from odelab.cli.import_view import print_import
    from odelab.formats import read

    out_console, err = _consoles()
    code = EXIT_OK
    for path in paths:
        target_dir = out if out is not None else path.parent
        options = _import_options(workspace, sets, call, err, output=target_dir)
        try:
            doc = read(path, options)
        except InputError as exc:
            err.print(f"[bold red]error:[/] {_escape(_error_text(exc))}")
            code = EXIT_INPUT
            continue
        if not doc.imported:
            err.print(f"[bold red]error:[/] {_escape(str(path))}: is already an experiment file; `odelab import` "
                      "translates MATLAB and Simulink files.")
            code = EXIT_INPUT
            continue
        target = target_dir / f"{path.stem}.toml"
        problem = _write_import(target, doc.text, force)
        if problem:
            err.print(f"[bold red]error:[/] {_escape(str(target))}: {_escape(problem)}")
            code = EXIT_INPUT
            continue
        print_import(out_console, str(path), str(target), doc.notes)
        if doc.gaps and code == EXIT_OK:
            code = EXIT_FAILED
    raise typer.Exit(code)


def _write_import(target: Path, text: str, force: bool) -> str | None:
    """Write the imported experiment file; why not (it would replace a file odelab import did not write)."""
    if target.exists() and not force:
        try:
            with open(target, encoding="utf-8", errors="replace") as fh:
                first = fh.readline()
        except OSError:
            first = ""
        if not first.startswith("# Imported from "):
            return "exists and was not written by `odelab import`; give another folder with -o or --force."
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_name(f".{target.name}.tmp")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, target)
    except OSError as exc:
        return f"cannot be written: {exc.strerror or exc}."
    return None


@app.command(cls=_Command)
def network(
    file: Annotated[Path, typer.Argument(help="An experiment file with kind = \"network\".", show_default=False,
                                         metavar="FILE.toml")],
    width: Annotated[int, typer.Option("--width", min=40, help="Wrap the text at this many columns.",
                                       metavar="N")] = 80,
) -> None:
    """Show how a network's equations are derived (element laws, interconnection laws, states,
    state equations; A, B, C, D and transfer functions if linear). Runs nothing."""
    from odelab.cli.network_view import describe_file

    out, err = _consoles()
    try:
        text = describe_file(file, width=width)
    except InputError as exc:
        err.print(f"[bold red]error:[/] {_escape(_error_text(exc))}")
        raise typer.Exit(EXIT_INPUT) from None
    out.print(_escape(text), end="", highlight=False, soft_wrap=True)


@app.command(cls=_Command)
def schema(
    out: Annotated[Optional[Path], typer.Option("--out", "-o", metavar="FILE", show_default=False,
                                                help="Write the schema to FILE instead of printing it.")] = None,
) -> None:
    """Print the JSON Schema of experiment files, for editors (Taplo, VS Code's Even Better TOML): keys
    completed and explained as you type. `odelab new` files point at it with a #:schema line."""
    from odelab.experiment.jsonschema import schema_text

    text = schema_text()
    if out is None:
        sys.stdout.write(text)
        return
    _, err = _consoles()
    try:
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        err.print(f"[bold red]error:[/] cannot write {_escape(str(out))}: {_escape(exc.strerror or str(exc))}")
        raise typer.Exit(EXIT_INPUT) from None
    typer.echo(f"wrote {out}")


@app.command()
def solvers() -> None:
    """List the integration methods: what they are for (non-stiff, stiff, DAE), order, defaults."""
    from rich.table import Table

    from odelab.solvers.registry import METHODS

    out, _ = _consoles()
    table = Table(title="odelab methods", title_justify="left")
    for col in ("method", "for", "order", "defaults", "description"):
        table.add_column(col)
    for m in METHODS.values():
        table.add_row(m.name, m.kind_label, m.order_label, m.defaults, m.description)
    out.print(table)


@app.command(cls=_Command)
def explain(
    key: Annotated[Optional[str], typer.Argument(help="A key of experiment files, e.g. inputs.pulse or solver.rtol.",
                                                 show_default=False, metavar="[KEY]")] = None,
) -> None:
    """Print the reference entry of an experiment-file key: type, default, choices, MATLAB names."""
    from odelab.experiment.keyref import entries, explain as entry_text
    from odelab.terminal import visible

    _, err = _consoles()
    if key is None:
        tops = [e for e in entries() if "." not in e.path]
        for e in tops:
            typer.echo(f"{e.path:<12} {textwrap.shorten(e.text, 66, placeholder=' ...')}")
        typer.echo("\nodelab explain TABLE.KEY for one key (e.g. odelab explain inputs.pulse).")
        return
    try:
        typer.echo(entry_text(key))
    except LookupError as exc:
        err.print(f"[bold red]error:[/] {_escape(visible(str(exc.args[0])))}")
        raise typer.Exit(EXIT_INPUT) from None


def main() -> None:  # pragma: no cover - the console-script entry point
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
