"""The registry of study kinds: what a ``[study]`` over a sweep's cases computes and how it is shown.

A study kind is one class: its TOML name (``kind = "convergence"``), a phrase for messages and
``odelab explain``, its own keys beyond the common ``over``/``error``/``quantity``, which swept
key it takes as its x axis and what that sweep must give (the [sweep] expands the cases; the kind
says which of its keys it reads and checks the cases), the curve it computes from the sweep's
rows (numbers from :mod:`odelab.analysis.studies`), the terminal's table, and the report's
section (a table and figure specs, drawn by :mod:`odelab.report.plots`). ``parse_study``,
``run_study``, ``odelab run``'s summary, ``odelab explain study.kind`` and the report read
:data:`STUDY_KINDS`; a new kind is one class decorated with :func:`register_study_kind`.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from odelab.exceptions import ExperimentError

__all__ = ["StudyKind", "STUDY_KINDS", "register_study_kind", "Convergence", "WorkPrecision", "fmt_number",
           "fmt_error", "key_label", "MARKERS"]

MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")


def fmt_number(value: Any, digits: int = 4) -> str:
    """A number for the report's tables (``—`` for none)."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if isinstance(value, (int, float)):
        return f"{value:.{digits}g}"
    return str(value)


def fmt_error(value, digits: int = 4) -> str:
    """An error as the lab quotes it: 4 significant digits (1.068e-04), 'undefined' if missing."""
    if value is None or (isinstance(value, float) and value != value):
        return "undefined"
    return f"{value:.{digits - 1}e}"


def key_label(key: str) -> str:
    """``solver.rtol`` -> ``rtol``."""
    return key.rsplit(".", 1)[-1]


def _curve_color(label: str, method: str, i: int) -> str:
    from odelab.report.plots import SERIES_COLORS, method_color

    return method_color(label) if label == method else SERIES_COLORS[i % len(SERIES_COLORS)]


def _error_phrase(study: dict) -> str:
    return "largest error over the span" if study["error"] == "max" else "error at the final time"


class StudyKind:
    """One kind of ``[study]``; subclasses set the class attributes and override what differs."""

    NAME: ClassVar[str]
    DOC: ClassVar[str]  # what it plots, for messages: "error against cost"
    KEYS: ClassVar[dict[str, Any]] = {}  # its own [study] keys and their defaults (beyond over/error/quantity)
    DOCS: ClassVar[dict[str, str]] = {}  # a sentence per own key, for odelab explain
    ERROR: ClassVar[str] = "max"  # the default `error`: "max" over the span or at the "end"

    def default_over(self, keys: tuple[str, ...]) -> str:
        """The swept key on the x axis when ``study.over`` is not given."""
        return "solver.rtol"

    def check_cases(self, over: str, cases) -> None:
        """Refuse cases the study cannot measure. A step-size study needs fixed-step methods, a tolerance
        study adaptive ones."""
        from odelab.solvers.registry import get_method

        for case in cases:
            method = get_method(case.problem.method)
            if over == "solver.h" and method.adaptive:
                raise ExperimentError(f"`study.over` is \"solver.h\", a step-size sweep, but case {case.name!r} uses "
                                      f"{method.name}, which chooses its own steps: sweep \"solver.rtol\" for adaptive "
                                      "methods.", key="study.over")
            if over != "solver.h" and not method.adaptive:
                raise ExperimentError(f"`study.over` is {over!r}, but case {case.name!r} uses the fixed-step "
                                      f"{method.name}, which has no tolerance: sweep \"solver.h\" for it.",
                                      key="study.over")

    def curve(self, spec, label: str, x: list[float], err: list[float], members: list[dict]) -> tuple[dict, list]:
        """One curve of the result (JSON-ready) and its warnings, from the sweep's rows of one label."""
        raise NotImplementedError

    def terminal(self, study: dict, over: str) -> tuple[str, list[str], list[list[str]]]:
        """The terminal's summary: a heading, the columns and the rows (plain text)."""
        raise NotImplementedError

    def draw(self, record: dict, study: dict, section) -> None:
        """The report's section: fill ``section.summary``, ``header``, ``rows`` and ``figures``."""
        raise NotImplementedError


STUDY_KINDS: dict[str, StudyKind] = {}


def register_study_kind(cls: type[StudyKind]) -> type[StudyKind]:
    """Register a study kind under its ``NAME`` (a class decorator)."""
    if not isinstance(getattr(cls, "NAME", None), str) or not getattr(cls, "DOC", ""):
        raise TypeError(f"{cls.__name__}: a study kind declares NAME and DOC.")
    clash = set(cls.KEYS) & {"kind", "over", "error", "quantity"}
    if clash:
        raise ValueError(f"study kind {cls.NAME!r}: its keys {sorted(clash)} are the common keys of [study].")
    STUDY_KINDS[cls.NAME] = cls()
    return cls


@register_study_kind
class Convergence(StudyKind):
    """Error against step size (or tolerance), with the observed order fitted on log-log axes."""

    NAME = "convergence"
    DOC = "error against step size or tolerance"

    def default_over(self, keys):
        return "solver.h" if "solver.h" in keys else "solver.rtol"

    def curve(self, spec, label, x, err, members):
        from odelab.analysis.studies import convergence_order
        from odelab.solvers.registry import get_method

        method = get_method(members[0]["method"])
        nominal = float(method.order) if spec.over == "solver.h" else None
        steps = [m["nsteps"] or 1 for m in members]
        scale = max(float(m["scale"].get(spec.quantity, 1.0)) for m in members)
        quadrature = None
        if nominal is not None and method.tableau is not None and all(m.get("quadrature") for m in members):
            from odelab.analysis.studies import quadrature_order, quadrature_rule

            quadrature = (quadrature_order(method.tableau.b, method.tableau.c),
                          quadrature_rule(method.tableau.b, method.tableau.c))
        fit = convergence_order(x, err, nominal=nominal, label=label, steps=steps, scale=scale, quadrature=quadrature)
        return {"method": method.name, **fit.as_dict()}, list(fit.warnings)

    def terminal(self, study, over):
        what = "max over the span" if study["error"] == "max" else "at the end"
        rows = []
        for c in study["curves"]:
            used = [h for h, why in zip(c["h"], c["excluded"]) if not why]
            rng = f"{min(c['h']):.3g} - {max(c['h']):.3g}"
            nominal = "-" if c["nominal"] is None else f"{c['nominal']:g}"
            diff = "-" if c["nominal"] is None or c["order"] != c["order"] else f"{c['order'] - c['nominal']:+.2f}"
            rows.append([c["label"], rng, f"{len(used)} of {len(c['h'])}", f"{c['order']:.3f}", nominal, diff])
        return (f"convergence of the {study['quantity']} error ({what}) against {over}:",
                ["method", f"{over} range", "points fitted", "observed order", "nominal", "difference"], rows)

    def draw(self, record, study, section):
        from odelab.report.plots import FigureSpec, Line, Panel

        over = key_label(study["over"])
        what = _error_phrase(study)
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
            caption=f"Convergence: {what} of {study['quantity']} against {over}, log-log; dashed: the fitted C "
                    f"{over}^p, crosses: points left out of the fit.",
            alt=f"log-log plot of the error against {over} for " + ", ".join(c["label"] for c in study["curves"])))


@register_study_kind
class WorkPrecision(StudyKind):
    """Error against cost (function evaluations and time), one curve per method, over a tolerance sweep."""

    NAME = "work-precision"
    DOC = "error against cost"
    ERROR = "end"

    def curve(self, spec, label, x, err, members):
        from odelab.analysis.studies import work_precision

        curve = work_precision(label, x, err, [m["nfevals"] for m in members], [m["elapsed_s"] for m in members])
        return {"method": members[0]["method"], **curve.as_dict()}, []

    def terminal(self, study, over):
        rows = []
        for c in study["curves"]:
            slope = c["slope"]
            rows.append([c["label"], fmt_error(c["error"][0]), f"{c['nfevals'][0]:.0f}", fmt_error(c["error"][-1]),
                         f"{c['nfevals'][-1]:.0f}", "-" if slope != slope else f"x{10 ** slope:.2f}"])
        return (f"work-precision ({study['quantity']} error at "
                f"{'the end' if study['error'] == 'end' else 'its largest'}) over {over}:",
                ["method", "loosest: error", "fevals", "tightest: error", "fevals", "fevals per digit"], rows)

    def draw(self, record, study, section):
        from odelab.report.plots import FigureSpec, Line, Panel

        what = _error_phrase(study)
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
            caption=f"{title}: {what} of {study['quantity']} against function evaluations (left) and time (right), "
                    "one curve per method, from loose to tight tolerances. Times of a few milliseconds are noisy.",
            alt="work-precision diagram of " + ", ".join(c["label"] for c in study["curves"])))
