"""Terminal tables for ``odelab run`` (Rich). Only the CLI imports this module."""

from __future__ import annotations

import math

import numpy as np
from rich.console import Console
from rich.text import Text

from odelab.cli.grid import fits, print_grid  # noqa: F401 (print_grid re-exported)
from odelab.experiment.studykinds import fmt_error
from odelab.store.spool import blocks
from odelab.terminal import shown, visible

__all__ = ["HEADLINE_NOTE", "fmt", "headline_text", "pointwise_text", "print_experiment", "print_grid"]

UNDEFINED_NOTE = "relative error undefined where the reference is zero or tiny"
# The terminal's statement of analysis.errors.HEADLINE_RULE (the report and README state the same).
POINTWISE_NOTE = "rel error = max |f - y| / |f| (the lab's), as |f| stays above 10% of max |f| throughout."
HEADLINE_NOTE = ("rel error = max |f - y| / |f| (the lab's) where |f| stays above 10% of max |f|; where the "
                 "reference nears zero it is max |f - y| / max |f|, marked 'of peak', with the pointwise maximum "
                 "beside it (its t and the |f| it divided by).")


def _shown(text, *, lines: bool = False) -> str:
    """A user string made safe for the terminal (see :mod:`odelab.terminal`): a name or title on
    one line; ``lines=True`` for a message, whose own line breaks are kept."""
    return shown(str(text), lines=lines)


fmt = fmt_error  # an error as the lab quotes it: 4 significant digits (1.068e-04), 'undefined' if missing


def _estimates(r) -> dict:
    """A result's estimated quantities (``estimate.quantities``), or {} (none made, or skipped)."""
    est = getattr(r, "estimate", None) or {}
    quantities = est.get("quantities")
    return quantities if isinstance(quantities, dict) else {}


def estimate_text(q) -> str:
    """One quantity's estimate: '1.2e-05 (4.3 digits)'."""
    if not q:
        return ""
    digits = q.get("digits")
    return f"{fmt(q.get('max_abs'))}" + ("" if digits is None else f" ({digits:.1f} digits)")


def headline_text(e) -> str:
    """The headline relative error of an ErrorSummary: '1.068e-04' or '9.093e-06 of peak'."""
    if e.basis == "peak":
        return "undefined" if e.headline is None else f"{fmt(e.headline)} of peak"
    return fmt(e.headline)


def pointwise_text(e) -> str:
    """Where the headline is 'of peak': the pointwise maximum, its t and the |f| it divided by."""
    if e.basis != "peak" or e.max_rel is None:
        return ""
    return f"{fmt(e.max_rel, 2)} at t = {e.t_max_rel:.3g} (|f| = {e.ref_at_max_rel:.1e})"


SWEEP_ROWS_SHOWN = 40


def print_experiment(console: Console, exp, results, *, table: bool = False) -> None:
    console.print(f"\n[bold]{_shown(exp.title)}[/]  [dim]({_shown(str(exp.source))})[/]")
    network = next((c.problem.system.network for c in exp.cases if c.problem.system.network is not None), None)
    if network is not None:  # kind = "network": the derived states and equations, compactly
        from odelab.systems.network.show import compact_lines

        console.print("[dim]" + _shown("\n".join(compact_lines(network)), lines=True) + "[/]")
    if getattr(exp, "sweep", None) is not None and (exp.study is not None or len(results) > SWEEP_ROWS_SHOWN):
        print_sweep(console, exp, results)
        return
    peak = any(e.basis == "peak" for r in results for e in r.errors.values())
    estimated = any(_estimates(r) for r in results)
    referenced = any(r.errors for r in results)
    valued = any(not r.errors for r in results)  # no reference: what the quantity did instead of dashes
    columns = [("case", "left"), ("method", "left"), ("points", "right"), ("steps", "right"), ("failed", "right"),
               ("fevals", "right"), ("quantity", "left")]
    if valued:
        columns += [("final", "right"), ("min", "right"), ("max", "right")]
    if referenced:
        columns += [("max abs error", "right"), ("rel error", "right")]
    if estimated:
        columns.append(("est. error", "right"))
    if peak:
        columns.append(("pointwise max |f - y| / |f|", "left"))
    columns.append(("status", "left"))
    rows = []
    for r in results:
        s = r.stats
        status = (Text("ok?", style="bold yellow") if r.unreliable else Text("ok", style="green")
                  if r.status == "success" else
                  Text("stopped, as expected", style="yellow") if r.expected_stop else Text("FAILED", style="bold red"))
        method = r.method if r.backend == "python" else f"{r.method} ({r.backend})"
        head = [visible(r.case.name), method, str(r.t.size), str(s.nsteps),
                "-" if s.nfailed is None else str(s.nfailed), str(s.nfevals)]
        est = _estimates(r)
        series = _valued(r, swept=getattr(exp, "sweep", None) is not None) if valued and not r.errors else {}
        names = list(r.errors) or list(est) or [n for n in series if n in est or not est]
        if not names:
            rows.append([*head, "-", *(["-"] * 3 if valued else []), *(["-", "-"] if referenced else []),
                         *(["-"] if estimated else []), *(["-"] if peak else []), status])
        for i, name in enumerate(names):
            cells = head if i == 0 else [""] * len(head)
            e = r.errors.get(name)
            extra = [pointwise_text(e) if e is not None else ""] if peak else []
            shown_est = [estimate_text(est.get(name))] if estimated else []
            values = _extent(series.get(name)) if valued else []
            errors = [fmt(e.max_abs) if e is not None else "-", headline_text(e) if e is not None else "-"] \
                if referenced else []
            rows.append([*cells, visible(name), *values, *errors, *shown_est, *extra, status if i == 0 else ""])
    marked = False
    if peak and not fits(console, columns, rows):  # narrow terminal: "of peak" becomes a mark
        marked = True
        at = [name for name, _ in columns].index("rel error")
        rows = [[*row[:at], row[at].replace(" of peak", " *") if isinstance(row[at], str) else row[at],
                 *row[at + 1:]] for row in rows]
    print_grid(console, columns, rows, wrap=("pointwise max |f - y| / |f|",))
    kinds = {r.reference_kind for r in results if r.errors}
    if kinds:
        names = {"linearization": "the linearised model (x̄ added back): errors are nonlinear minus linear",
                 "exact": "the exact solution in \\[exact]", "lti": "the exact LTI response (matrix exponential)",
                 "high-accuracy": "a high-accuracy solve", "data": "the measurements in \\[data] (at their times)"}
        console.print("[dim]errors against " + "; ".join(names.get(k, k) for k in sorted(kinds)) + ". "
                      + (HEADLINE_NOTE.replace("marked 'of peak'", "marked * (of peak)").replace(
                             "beside it", "listed after the table") if marked else
                         HEADLINE_NOTE if peak else POINTWISE_NOTE) + "[/]")
    if estimated:
        console.print("[dim]est. error: the largest difference from a second solve at RelTol and AbsTol / 10 (same "
                      "method), times 10/9, and the correct digits it implies (relative error by the same rule as "
                      "the rel error column); an estimate, not a bound. ok?: the two solves disagree far beyond the "
                      "tolerances, or leave less than one digit (see the note).[/]")
    undefined = []
    # a note every case has (a parameter shadowing a constant, a cache note) is said once, not once a case
    shared = [w for w in results[0].warnings if len(results) > 1 and not w.startswith(UNDEFINED_NOTE)
              and all(w in r.warnings for r in results[1:])]
    for w in shared:
        console.print(f"[yellow]every case: note: {_shown(w, lines=True)}[/]")
    for r in results:
        if r.status != "success":
            colour = "yellow" if r.expected_stop else "red"
            said = " (expected: the file says expect = " + repr(r.case.config["expect"]) + ")" if r.expected_stop else ""
            console.print(f"[{colour}]{_shown(r.case.name)}: {_shown(r.message, lines=True)}{said}[/]")
        for w in r.warnings:
            if w.startswith(UNDEFINED_NOTE):
                counts = ", ".join(f"{n} {e.undefined}" for n, e in r.errors.items() if e.undefined)
                undefined.append(f"{r.case.name}: {counts}")
            elif w not in shared:
                console.print(f"[yellow]{_shown(r.case.name)}: note: {_shown(w, lines=True)}[/]")
    if undefined:
        console.print("[dim]relative error undefined (reference zero or tiny; left out of the maximum) at this many "
                      f"points: {_shown('; '.join(undefined), lines=True)}[/]")
    if getattr(exp, "sweep", None) is not None and print_step_infos(console, results):
        pass  # a sweep's step metrics as one table, a row per case (each case's analysis: result.json, report)
    else:
        printed = []
        for r in results:
            info = r.extra.get("analysis")
            if info is not None and not any(info["A"] == a["A"] and info["B"] == a["B"] and info["C"] == a["C"]
                                            and info["D"] == a["D"] for a in printed):
                print_analysis(console, r.case.name if printed or len(results) == 1 else None, info)
                printed.append(info)
    fit = next((r.extra["fit"] for r in results if isinstance(r.extra.get("fit"), dict)), None)
    if fit is not None:
        from odelab.cli.fit_display import print_fit

        print_fit(console, fit)
    for r in results:
        if r.events:
            print_events(console, r)
    for r in results:
        if "linearization" in r.extra:
            print_linearization(console, r.case.name, r.extra["linearization"])
        if table and r.errors:
            print_point_table(console, r)


def print_point_table(console: Console, r) -> None:
    """The lab's 'relative error at each step': t, value, reference, absolute and relative error."""
    from rich.table import Table

    from odelab.analysis.errors import error_columns

    series = r.series()
    for name, ref in r.reference.items():
        t = Table(title=f"{_shown(r.case.name)}: {_shown(name)} at each output point", title_justify="left", show_edge=False,
                  header_style="bold")
        for col in ("t", name, "reference", "|f - y|", "|f - y| / |f|"):
            t.add_column(_shown(col), justify="right")
        abs_err, rel_err = error_columns(series[name], ref)
        for row in zip(r.t, series[name], ref, abs_err, rel_err):
            t.add_row(f"{row[0]:.6g}", f"{row[1]:.10g}", f"{row[2]:.10g}", fmt(float(row[3])),
                      fmt(None if np.isnan(row[4]) else float(row[4])))
        console.print(t)


def _matrix(rows) -> str:
    """MATLAB's notation; an empty matrix as MATLAB builds it, ``zeros(2, 0)`` (no inputs: B is 2-by-0)."""
    if not rows or not rows[0]:
        return f"zeros({len(rows)}, 0)"
    return "[" + "; ".join(" ".join(f"{v + 0.0:.6g}" for v in row) for row in rows) + "]"  # -0 shown as 0


def _num(v: float, digits: int = 4) -> str:
    if v is None or v != v:
        return "-"
    if v in (float("inf"), float("-inf")):
        return "inf" if v > 0 else "-inf"
    return f"{v:.{digits}g}"


def _valued(r, *, swept: bool) -> dict:
    """The quantities a case without a reference shows: its states and outputs (a sweep's: its outputs, or
    its states when it has none), not its inputs, which the file gives."""
    p = r.case.problem
    series = r.series()
    names = (list(p.outputs) or list(p.states)) if swept else [*p.states, *p.outputs]
    return {n: series[n] for n in names if n in series}


def _extent(column) -> list[str]:
    """A quantity without a reference: its final value, its minimum and its maximum over the run."""
    if column is None or not len(column):
        return ["-", "-", "-"]
    values = np.asarray(column, dtype=float)
    low, high = math.inf, -math.inf
    for piece in blocks(values, _EXTENT_BLOCK):  # a block at a time: no copy of a long run's column (a spooled
        # run's map hands its pages back after each: odelab.store.spool)
        finite = piece[np.isfinite(piece)]
        if finite.size:
            low, high = min(low, float(finite.min())), max(high, float(finite.max()))
    if low > high:  # no finite value
        low = high = math.nan
    return [f"{float(values[-1]):.6g}", f"{low:.6g}", f"{high:.6g}"]


#: Values of a column looked at a time for its extent (512 kB).
_EXTENT_BLOCK = 65536


def _never_settles(s: dict) -> bool:
    settling, final = s.get("SettlingTime"), s.get("SteadyStateValue")
    return (settling is None or settling != settling) and final is not None and final == final and final != 0


def _step_cell(s: dict, column: str) -> str:
    return "NaN" if column == "SettlingTime" and _never_settles(s) else _num(s[column])


def print_analysis(console: Console, case: str | None, info: dict) -> None:
    """[analysis]: transfer functions, poles, step metrics and margins of the linear model."""
    from rich.table import Table

    where = f" ({_shown(case)})" if case else ""
    if "operating_point" in info:
        op = info["operating_point"]
        point = ", ".join(f"{k} = {v:.6g}" for k, v in {**op["x"], **op["u"]}.items())
        console.print(f"[bold]analysis{where}[/]: linear model about the operating point {_shown(point)}")
    else:
        console.print(f"[bold]analysis{where}[/]: the system is linear; its own A, B, C, D")
    for g in info["transfer_functions"]:
        num, den = g["text"]
        console.print(f"  {_shown(g['output'])}/{_shown(g['input'])}: G(s) = ({_shown(num)}) / ({_shown(den)}), "
                      f"DC gain {_num(g['dc_gain'], 6)}")
    if "poles" in info:
        poles = ", ".join(f"{p['re']:.4g}{p['im']:+.4g}j" if p["im"] else f"{p['re']:.4g}" for p in info["poles"])
        console.print(f"  poles: {poles}")
        console.print("  natural frequency wn (rad/s) / damping ratio: "
                      + ", ".join(f"{p['wn']:.4g} / {p['zeta']:.4g}" for p in info["poles"]))
        for channel, zs in info["zeros"].items():
            if zs:
                console.print(f"  zeros of {_shown(channel)}: "
                              + ", ".join(f"{z['re']:.4g}{z['im']:+.4g}j" if z["im"] else f"{z['re']:.4g}"
                                          for z in zs))
    if "step_info" in info:
        cols = ("RiseTime", "SettlingTime", "Overshoot", "Undershoot", "Peak", "PeakTime", "SteadyStateValue")
        print_grid(console, [("step", "left"), *((c, "right") for c in cols)],
                   [[f"{_shown(s['input'])} -> {_shown(s['output'])}", *(_step_cell(s, c) for c in cols)]
                    for s in info["step_info"]])
        for s in info["step_info"]:
            if _never_settles(s):
                console.print(f"  {_shown(s['input'])} -> {_shown(s['output'])} does not settle (an undamped or "
                              "growing mode): SettlingTime is NaN, as MATLAB's stepinfo gives; Peak and PeakTime "
                              "are its first peak.")
    loop = info.get("loop")
    if loop:
        num, den = loop["text"]
        console.print(f"  loop opened at the input of {_shown(loop['at'])}: L(s) = ({_shown(num)}) / ({_shown(den)}); "
                      f"gain margin {_num(loop['gain_margin_db'])} dB at {_num(loop['phase_crossover'])} rad/s, "
                      f"phase margin {_num(loop['phase_margin'])} deg at {_num(loop['gain_crossover'])} rad/s")
    if "bode" in info:
        for m in info.get("margins", ()):
            console.print(f"  margins of {_shown(m['output'])}/{_shown(m['input'])} as a loop gain: gain margin "
                          f"{_num(m['gain_margin_db'])} dB at {_num(m['phase_crossover'])} rad/s, phase margin "
                          f"{_num(m['phase_margin'])} deg at {_num(m['gain_crossover'])} rad/s")
        w = info["bode"]["w"]
        console.print(f"  [dim]Bode data: {len(w)} frequencies from {w[0]:g} to {w[-1]:g} rad/s in --json, "
                      "result.json and the report[/]")


def print_linearization(console: Console, case: str, info: dict) -> None:
    """Operating point, linear model and the amplitude study of a [linearize] case."""
    from rich.table import Table

    op = info["operating_point"]
    point = ", ".join(f"{k} = {v:.6g}" for k, v in {**op["x"], **op["u"]}.items())
    console.print(f"[bold]{_shown(case)}[/]: operating point {_shown(point)} (residual {op['residual']:.1e})")
    console.print(f"  linear model in deviations: A = {_matrix(info['A'])}, B = {_matrix(info['B'])}, "
                  f"C = {_matrix(info['C'])}, D = {_matrix(info['D'])}")
    if "amplitudes" not in info:
        return
    q = info["quantity"]
    t = Table(show_edge=False, box=None, header_style="bold", pad_edge=False)
    t.add_column(f"step of {_shown(info['drive'])}", justify="right")
    t.add_column(f"max |{_shown(q)} nonlinear - linear|", justify="right")
    t.add_column("relative to peak response", justify="right")
    t.add_column("within threshold", justify="left")
    for a, e_abs, e_rel in zip(info["amplitudes"], info["abs_errors"][q], info["errors"][q]):
        ok = e_rel is not None and e_rel <= info["threshold"]
        t.add_row(f"{a:g}", fmt(e_abs), fmt(e_rel), "yes" if ok else "[red]no[/]")
    console.print(t)
    within = info["max_amplitude_within"]
    slope = info.get("slope")
    console.print(
        f"  largest step within {info['threshold']:.0%} of the peak response: "
        + (f"{within:g}" if within is not None else "none of those tested")
        + (f" (interpolated: {info['threshold_amplitude']:.3g})" if info.get("threshold_amplitude") else "")
        + (f"; log-log slope of the error over these amplitudes: {slope:.2f}" if slope is not None else ""))


STEP_COLUMNS = ("RiseTime", "SettlingTime", "Overshoot", "Undershoot", "Peak", "PeakTime", "SteadyStateValue")


def print_step_infos(console: Console, results) -> bool:
    """A sweep's [analysis] step_info, one row per case and channel (the first SWEEP_ROWS_SHOWN); False if
    no case has one."""
    rows = []
    for r in results:
        for s in (r.extra.get("analysis") or {}).get("step_info") or []:
            rows.append([visible(r.case.name), f"{_shown(s['input'])} -> {_shown(s['output'])}",
                         *(_step_cell(s, c) for c in STEP_COLUMNS)])
    if not rows:
        return False
    console.print("step response of each case (MATLAB's stepinfo of its linear model; every case's analysis is in "
                  "result.json and the report; all of them in sweep.csv):")
    print_grid(console, [("case", "left"), ("step", "left"), *((c, "right") for c in STEP_COLUMNS)],
               rows[:SWEEP_ROWS_SHOWN])
    if len(rows) > SWEEP_ROWS_SHOWN:
        console.print(f"[dim]... and {len(rows) - SWEEP_ROWS_SHOWN} more rows in sweep.csv[/]")
    for r in results:
        for s in (r.extra.get("analysis") or {}).get("step_info") or []:
            if _never_settles(s):
                console.print(f"  {_shown(r.case.name)}: {_shown(s['input'])} -> {_shown(s['output'])} does not "
                              "settle: SettlingTime is NaN, as MATLAB's stepinfo gives.")
    return True


EVENT_ROWS = 20  # events listed in the terminal; result.json and the report have them all


def print_events(console: Console, r) -> None:
    """The located events of a case: time (and exact time, if known), state, reset."""
    states = list(r.case.problem.states)
    exact = any("exact_t" in e for e in r.events)
    console.print(_shown(f"{r.case.name}: {len(r.events)} event{'s' if len(r.events) != 1 else ''}"))
    columns = [(col, "left" if col in ("event", "reset") else "right")
               for col in ("#", "event", "t", *(("exact t", "|t - exact|") if exact else ()), *states, "reset")]
    rows = []
    for i, e in enumerate(r.events[:EVENT_ROWS], start=1):
        cells = [str(i), visible(e["name"]), f"{e['t']:.10g}"]
        if exact:
            cells += ([f"{e['exact_t']:.10g}", fmt(abs(e["t"] - e["exact_t"]))] if "exact_t" in e else ["-", "-"])
        cells += [f"{e['state'][s]:.6g}" for s in states]
        cells.append(visible(", ".join(f"{k} = {v:.6g}" for k, v in e["reset"].items()
                                       if v != e["state"][k])) if "reset" in e else "")
        rows.append(cells)
    print_grid(console, [(visible(c), j) for c, j in columns], rows, wrap=("reset",))
    if len(r.events) > EVENT_ROWS:
        console.print(f"[dim]... and {len(r.events) - EVENT_ROWS} more events (all in result.json and the report)[/]")


def print_sweep(console: Console, exp, results) -> None:
    """A sweep in a few lines: how many cases ran, failures, and the study's table."""
    from rich.table import Table

    from odelab.experiment.study import run_study, sweep_rows

    failed = [r for r in results if r.status != "success"]
    keys = ", ".join(exp.sweep.keys)
    console.print(f"{len(results)} cases over {_shown(keys)} ({exp.sweep.mode}); {len(failed)} failed. "
                  f"The table of every case: sweep.csv in the results folder.")
    for r in failed[:5]:
        console.print(f"[red]{_shown(r.case.name)}: {_shown(r.message, lines=True)}[/]")
    print_step_infos(console, results)
    if exp.study is None:
        return
    study = run_study(exp.study, sweep_rows(results))
    over = exp.study.over.rsplit(".", 1)[-1]
    t = Table(show_edge=False, box=None, header_style="bold", pad_edge=False)
    from odelab.cli.study_views import terminal_view  # only a [study] draws one: not at start-up

    heading, columns, rows = terminal_view(study, over)
    console.print(_shown(heading))
    for i, col in enumerate(columns):
        t.add_column(_shown(col), justify="left" if i == 0 else "right")
    for row in rows:
        t.add_row(_shown(row[0]), *row[1:])
    console.print(t)
    for w in study["warnings"]:
        console.print(f"[yellow]note: {_shown(w)}[/]")
