"""The terminal's table of a ``[study]`` (``odelab run``'s summary of a sweep), one view per study kind.

A study kind (:mod:`odelab.experiment.studykinds`) computes its curves; how they read in a
terminal is here: a function ``(study, over) -> (heading, columns, rows)`` registered under the
kind's name with :func:`register_terminal_view`. A kind without a view of its own is shown by
:func:`generic_view`: a row per curve with the curve's numbers.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from odelab.experiment.studykinds import fmt_error, fmt_number

__all__ = ["TERMINAL_VIEWS", "register_terminal_view", "terminal_view", "generic_view"]

View = Callable[[dict, str], tuple[str, list[str], list[list[str]]]]
TERMINAL_VIEWS: dict[str, View] = {}


def register_terminal_view(kind: str) -> Callable[[View], View]:
    """Register the terminal view of the study kind ``kind`` (a decorator)."""
    def register(view: View) -> View:
        TERMINAL_VIEWS[kind] = view
        return view
    return register


def terminal_view(study: dict, over: str) -> tuple[str, list[str], list[list[str]]]:
    """The heading, columns and rows of a study's terminal table."""
    return TERMINAL_VIEWS.get(study["kind"], generic_view)(study, over)


def _scalars(curve: dict) -> dict:
    return {k: v for k, v in curve.items() if k != "label" and (isinstance(v, (int, float, str)) or v is None)
            and not isinstance(v, bool)}


def generic_view(study: dict, over: str) -> tuple[str, list[str], list[list[str]]]:
    """A row per curve: its label and each of its numbers (lists, such as the curve's points, left out)."""
    curves = study["curves"]
    names = [k for k in _scalars(curves[0])] if curves else []
    rows = []
    for c in curves:
        values = _scalars(c)
        rows.append([str(c.get("label", "")), *(_cell(values.get(k)) for k in names)])
    return f"{study['kind']} of the {study['quantity']} error over {over}:", ["curve", *names], rows


def _cell(value) -> str:
    if isinstance(value, float):
        return "-" if not math.isfinite(value) else fmt_number(value)
    return "-" if value is None else str(value)


@register_terminal_view("convergence")
def _convergence(study, over):
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


@register_terminal_view("work-precision")
def _work_precision(study, over):
    rows = []
    for c in study["curves"]:
        slope = c["slope"]
        rows.append([c["label"], fmt_error(c["error"][0]), f"{c['nfevals'][0]:.0f}", fmt_error(c["error"][-1]),
                     f"{c['nfevals'][-1]:.0f}", "-" if slope != slope else f"x{10 ** slope:.2f}"])
    return (f"work-precision ({study['quantity']} error at "
            f"{'the end' if study['error'] == 'end' else 'its largest'}) over {over}:",
            ["method", "loosest: error", "fevals", "tightest: error", "fevals", "fevals per digit"], rows)
