"""The registry of study kinds: what a ``[study]`` over a sweep's cases computes and how it is shown.

A study kind is one class: its TOML name (``kind = "convergence"``), a phrase for messages and
``odelab explain``, its own keys beyond the common ``over``/``error``/``quantity``, which swept
key it takes as its x axis and what that sweep must give (the [sweep] expands the cases; the kind
says which of its keys it reads and checks the cases), the curve it computes from the sweep's
rows (numbers from :mod:`odelab.analysis.studies`). ``parse_study``, ``run_study``,
``odelab explain study.kind``, ``odelab run``'s summary and the report read :data:`STUDY_KINDS`;
a new kind is one class decorated with :func:`register_study_kind`. How a kind is shown lives
with the views: its terminal table in :mod:`odelab.cli.study_views`, its report section in
:mod:`odelab.report.study_sections` (a kind without one of its own gets the generic table of its
curves' numbers in both).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar


from odelab.exceptions import ExperimentError

__all__ = ["StudyKind", "STUDY_KINDS", "register_study_kind", "Convergence", "WorkPrecision", "fmt_number",
           "fmt_error", "key_label", "error_phrase"]

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


def error_phrase(study: dict) -> str:
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
