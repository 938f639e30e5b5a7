"""The report's section of a ``[study]``, one drawing per study kind.

A study kind (:mod:`odelab.experiment.studykinds`) computes its curves; how the report shows them
is here: a function ``(record, study, section)`` that fills the section's summary, table and
figure specs, registered under the kind's name with :func:`register_section`. A kind without
one of its own gets :func:`generic_section`: its curves' numbers as a table.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from odelab.experiment.studykinds import error_phrase, fmt_number, key_label
from odelab.report.plots import SERIES_COLORS, FigureSpec, Line, Panel, method_color

__all__ = ["MARKERS", "SECTIONS", "register_section", "draw_study", "generic_section"]

MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")

Draw = Callable[[dict, dict, object], None]
SECTIONS: dict[str, Draw] = {}


def register_section(kind: str) -> Callable[[Draw], Draw]:
    """Register the report section of the study kind ``kind`` (a decorator)."""
    def register(draw: Draw) -> Draw:
        SECTIONS[kind] = draw
        return draw
    return register


def draw_study(record: dict, study: dict, section) -> None:
    """Fill ``section`` (summary, header, rows, figures) for the stored study."""
    SECTIONS.get(study["kind"], generic_section)(record, study, section)


def generic_section(record: dict, study: dict, section) -> None:
    """A row per curve: its label and each of its numbers (lists, such as the curve's points, left out)."""
    curves = study["curves"]
    names = [k for k, v in curves[0].items() if k != "label" and _scalar(v)] if curves else []
    section.summary = (f"{study['kind']} study of {study['quantity']} over {key_label(study['over'])}: the numbers "
                       "of each curve.")
    section.header = ["curve", *names]
    for c in curves:
        section.rows.append([str(c.get("label", "")), *(fmt_number(c.get(k)) if not isinstance(c.get(k), str)
                                                          else c.get(k) for k in names)])


def _scalar(value) -> bool:
    return (isinstance(value, (int, float, str)) or value is None) and not isinstance(value, bool)


def _curve_color(label: str, method: str, i: int) -> str:
    return method_color(label) if label == method else SERIES_COLORS[i % len(SERIES_COLORS)]


def off_log_axis(curves: list[dict]) -> str:
    """A sentence naming the curves (or points) a log error axis cannot draw: an error of 0 (exact
    to round-off) or none; empty when every point is drawn."""
    gone, some = [], []
    for c in curves:
        err = np.array([np.nan if e is None else e for e in c["error"]], dtype=float)
        bad = ~(np.isfinite(err) & (err > 0))
        zero = bool(np.any(err[bad] == 0))
        if bad.all():
            gone.append(f"{c['label']} (its error is {'0' if zero else 'undefined'} at every point)")
        elif bad.any():
            some.append(f"{c['label']} ({int(bad.sum())} of {err.size} points, error {'0' if zero else 'undefined'})")
    parts = []
    if gone:
        parts.append(("Not drawn: " + ", ".join(gone)) + ", which a log axis cannot show; the table lists it.")
    if some:
        parts.append("Points not drawn: " + ", ".join(some) + " (a log axis cannot show them).")
    return " ".join(parts)




@register_section("convergence")
def _convergence(record, study, section):
    over = key_label(study["over"])
    what = error_phrase(study)
    section.summary = (f"Global error of {study['quantity']} ({what}) against {over}, and the observed order: the "
                       f"least-squares slope of log error on log {over}. Points left out of the fit (crosses) are "
                       "spoiled by round-off or by steps too large for the asymptotic regime.")
    section.header = ["method", f"{over} from", f"{over} to", "points fitted", "observed order", "nominal order",
                      "observed − nominal"]
    lines = []
    for i, c in enumerate(study["curves"]):
        h = np.asarray(c["h"], dtype=float)
        err = np.array([np.nan if e is None else e for e in c["error"]], dtype=float)
        used = np.array([not why for why in c["excluded"]])
        order, nominal = c["order"], c["nominal"]
        color = _curve_color(c["label"], c["method"], i)
        marker = MARKERS[i % len(MARKERS)]
        fitted = order is not None and math.isfinite(order)
        name = f"{c['label']}: slope {order:.2f}" if fitted else f"{c['label']}: no fit"
        lines.append(Line(h[used], err[used], name, color, linestyle="none", marker=marker, markersize=5))
        if np.any(~used):
            lines.append(Line(h[~used], err[~used], "_left out", color, linestyle="none", marker="x", markersize=6))
        if fitted and np.count_nonzero(used) >= 2:
            hs = np.array([h[used].min(), h[used].max()])
            lines.append(Line(hs, 10.0 ** (c["intercept"] + order * np.log10(hs)), "_fit", color, linestyle="--",
                              linewidth=1.0))
        diff = order - nominal if fitted and nominal is not None else None
        section.rows.append([c["label"], fmt_number(min(h)), fmt_number(max(h)), f"{int(used.sum())} of {h.size}",
                             (f"{order:.3f} ({c['note']})" if c.get("note") else f"{order:.3f}") if fitted else "—",
                             "—" if nominal is None else f"{nominal:g}",
                             "—" if diff is None else f"{diff:+.3f}"])
    panel = Panel(title=record.get("title") or record["experiment"], xlabel=f"{over} (log)",
                  ylabel=f"{study['quantity']} error (log)", lines=tuple(lines), xscale="log", yscale="log",
                  legend_outside=True, decades=16)  # every point down to round-off
    section.figures.append(FigureSpec(
        name=f"{section.anchor}-convergence", panels=(panel,), panel_height=3.0,
        caption=(f"Convergence: {what} of {study['quantity']} against {over}, log-log; dashed: the fitted C "
                 f"{over}^p, crosses: points left out of the fit. " + off_log_axis(study["curves"])).strip(),
        alt=f"log-log plot of the error against {over} for " + ", ".join(c["label"] for c in study["curves"])))


@register_section("work-precision")
def _work_precision(record, study, section):
    what = error_phrase(study)
    section.summary = (f"Work-precision: the {what} of {study['quantity']} against the work it cost, over a "
                       f"sweep of {key_label(study['over'])}. Lower left is better: the same accuracy for less "
                       "work.")
    section.header = ["method", "loosest: error", "fevals", "tightest: error", "fevals", "time (s)",
                      "fevals ×10 per digit"]
    fev_lines, time_lines = [], []
    for i, c in enumerate(study["curves"]):
        err = np.array([np.nan if e is None else e for e in c["error"]], dtype=float)
        fev = np.asarray(c["nfevals"], dtype=float)
        sec = np.asarray(c["seconds"], dtype=float)
        color = _curve_color(c["label"], c["method"], i)
        marker = MARKERS[i % len(MARKERS)]
        fev_lines.append(Line(err, fev, c["label"], color, marker=marker))
        time_lines.append(Line(err, sec, c["label"], color, marker=marker))
        slope = c.get("slope")
        section.rows.append([c["label"], fmt_number(err[0], 3), fmt_number(fev[0], 6), fmt_number(err[-1], 3),
                             fmt_number(fev[-1], 6), fmt_number(float(np.nansum(sec)), 3),
                             "—" if slope is None or not math.isfinite(slope) else f"×{10 ** slope:.2f}"])
    title = record.get("title") or record["experiment"]
    section.figures.append(FigureSpec(
        name=f"{section.anchor}-work-precision", columns=2, panel_height=2.6,
        panels=(Panel(title="function evaluations", xlabel=f"{study['quantity']} error (log)",
                      ylabel="function evaluations (log)", lines=tuple(fev_lines), xscale="log", yscale="log",
                      decades=16),
                Panel(title="time", xlabel=f"{study['quantity']} error (log)", ylabel="seconds (log)",
                      lines=tuple(time_lines), xscale="log", yscale="log", decades=16)),
        caption=(f"{title}: {what} of {study['quantity']} against function evaluations (left) and time (right), "
                 "one curve per method, from loose to tight tolerances. Times of a few milliseconds are noisy. "
                 + off_log_axis(study["curves"])).strip(),
        alt="work-precision diagram of " + ", ".join(c["label"] for c in study["curves"])))
