"""Work and memory budgets: what one experiment file may ask for before anything runs.

A 1 MB file can ask for 10^9 output points, a fixed step of 1e-7 over 10^6 seconds, 40,000
cases or a 200,000-row input table; without a budget each ends in a MemoryError or runs for
minutes. Each request is estimated from the file alone, before the memory is allocated or the
solver started, and compared with a budget. The budgets are generous for a lab (a 1-million-
step run fits) and are raised by whoever runs the file, never by the file itself:
``odelab run --max-steps N`` and ``odelab run --limit NAME=N`` (``0``: no limit). A file's
own ``solver.max_steps`` is capped by ``--max-steps`` (its ``0``, "no limit", too): a file
cannot lift the budget of whoever runs it.

======================  ==========  =======================================================
budget (``--limit``)    default     what it bounds
======================  ==========  =======================================================
``steps``               1,000,000   steps of one solve: a fixed-step grid (known before the
                                    run), an adaptive solve's minimum (span / max_step), and
                                    an adaptive solve while it runs (``--max-steps``)
``points``              2,000,000   output points of a case (time.points, time.output, a
                                    fixed-step grid, span / max_step x refine): memory,
                                    about 100 bytes per point and quantity in all
``refine``              100         ``solver.refine`` (MATLAB's Refine; its default is 4)
``cases``               1,000       cases in one file: its ``[[case]]`` tables times its
                                    sweep's values times its ``[[problem]]`` tables, counted
                                    before anything is expanded
``amplitudes``          100         ``linearize.amplitudes`` (each is two solves)
``table_rows``          10,000      rows of an input table (each is a breakpoint at which
                                    the solver restarts)
``events``              10,000      ``events.max_events`` (each event restarts the solver)
``states``              5,000       states of one system, and blocks and ports of a diagram
                                    (a linear model's A is states x states)
======================  ==========  =======================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from odelab.exceptions import ExperimentError, InputError

__all__ = ["Limits", "DEFAULT_LIMITS", "parse_limit", "check_count", "check_solve", "capped_max_steps"]


@dataclass(frozen=True)
class Limits:
    """The budgets of one run; 0 means no limit."""

    steps: int = 1_000_000
    points: int = 2_000_000
    refine: int = 100
    cases: int = 1_000
    amplitudes: int = 100
    table_rows: int = 10_000
    events: int = 10_000
    states: int = 5_000

    def allows(self, name: str, value: float) -> bool:
        limit = getattr(self, name)
        return limit == 0 or value <= limit


DEFAULT_LIMITS = Limits()

_WHAT = {"steps": "steps per solve", "points": "output points per case", "refine": "for refine",
         "cases": "cases per file", "amplitudes": "amplitudes per study", "table_rows": "rows per input table",
         "events": "events per case", "states": "states (or blocks, or ports) per system"}


def parse_limit(text: str, limits: Limits = DEFAULT_LIMITS) -> Limits:
    """``"points=5000000"`` applied to ``limits`` (the CLI's ``--limit``); InputError naming the fix."""
    names = [f.name for f in fields(Limits)]
    name, sep, value = text.partition("=")
    name = name.strip().replace("-", "_")
    if not sep or name not in names:
        raise InputError(f"`--limit` is {text!r}; write NAME=N with NAME one of {', '.join(names)} "
                         "(0: no limit), e.g. --limit points=5000000.", key="--limit")
    try:
        number = int(value.strip().replace("_", ""))
    except ValueError:
        number = -1
    if number < 0:
        raise InputError(f"`--limit {name}` must be a whole number >= 0 (0: no limit); got {value.strip()!r}.",
                         key="--limit")
    return replace(limits, **{name: number})


def _how_to_raise(name: str, needed: float) -> str:
    flag = "--max-steps" if name == "steps" else f"--limit {name}="
    wanted = f"{math.ceil(needed):d}" if needed < 1e15 else "0"
    return f"raise it with `odelab run {flag}{'' if flag.endswith('=') else ' '}{wanted}` if you mean it"


def _refuse(key: str, asked: str, name: str, needed: float, limits: Limits, fix: str = "") -> ExperimentError:
    limit = getattr(limits, name)
    return ExperimentError(
        f"`{key}` {asked}; the budget is {limit:,} {_WHAT[name]}{fix}; {_how_to_raise(name, needed)}.", key=key)


def check_count(name: str, count: int, key: str, what: str, limits: Limits, *, asked: str | None = None) -> None:
    """A count known from the file (cases, amplitudes, output times) against its budget."""
    if not limits.allows(name, count):
        raise _refuse(key, asked or f"has {count:,} {what}", name, count, limits)


def fixed_step_count(tspan: np.ndarray, h: float) -> float:
    """The steps of a fixed-step solve, as ``solvers.api.fixed_grid`` takes them (without making the grid)."""
    spans = np.abs(np.diff(np.asarray(tspan, dtype=float)))
    return float(np.sum(np.maximum(1.0, np.ceil(spans / h - 1e-9))))


def check_solve(*, fixed_step: bool, tspan: np.ndarray, options: dict, refine_default: int, limits: Limits) -> None:
    """Estimate a solve's steps and output points from the file alone; refuse one over budget.

    Fixed-step methods: the grid is known, ceil(span / h) steps. Adaptive methods (explicit,
    implicit, SciPy's): a
    ``max_step`` forces at least span / max_step steps, each giving ``refine`` output points
    when no output times are given. Nothing is allocated here.
    """
    span = float(abs(tspan[-1] - tspan[0]))
    given_times = tspan.size > 2
    if fixed_step and "h" in options:
        h = float(options["h"])
        steps = fixed_step_count(tspan, h)
        if not limits.allows("steps", steps):
            raise _refuse("solver.h", f"= {h:g} over a span of {span:g} takes {steps:.3g} steps", "steps", steps,
                          limits, fix=" (or take a larger h)")
        points = tspan.size if given_times else steps + 1
        if not limits.allows("points", points):
            raise _refuse("solver.h", f"= {h:g} over a span of {span:g} stores {points:.3g} output points", "points",
                          points, limits, fix=" (or give fewer output times in time.output or time.points)")
        return
    # every other kind (MATLAB's explicit and implicit solvers, SciPy's) adapts its step
    refine = options.get("refine", refine_default)
    if isinstance(refine, (int, float)) and not isinstance(refine, bool) and not limits.allows("refine", refine):
        raise _refuse("solver.refine", f"is {refine:g}", "refine", refine, limits,
                      fix=" (MATLAB's default is 4 for ode45; give output times in time.points for a fine grid)")
    max_step = options.get("max_step")
    if isinstance(max_step, (int, float)) and not isinstance(max_step, bool) and max_step > 0:
        steps = math.ceil(span / max_step) if span / max_step < 1e300 else math.inf
        if not limits.allows("steps", steps):
            raise _refuse("solver.max_step", f"= {max_step:g} over a span of {span:g} takes at least {steps:.3g} "
                          "steps", "steps", steps, limits, fix=" (or take a larger max_step)")
        points = tspan.size if given_times else steps * int(refine) + 1
        if not limits.allows("points", points):
            raise _refuse("solver.max_step", f"= {max_step:g} with refine {refine} stores at least {points:.3g} "
                          "output points", "points", points, limits, fix=" (or lower refine)")


def capped_max_steps(asked: int | None, budget: int | None) -> tuple[int | None, bool]:
    """The ``max_steps`` a solve gets: the file's ``asked`` (None: not set; 0: no limit) within
    odelab run's ``budget`` (None or 0: no budget). Returns it and whether the budget cut it."""
    if not budget:
        return asked, False
    if asked is None:
        return budget, False
    if asked == 0 or asked > budget:
        return budget, True
    return asked, False
