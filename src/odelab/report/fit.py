"""The report's [data] and [fit] part: the fitted model over the data, residuals, their autocorrelation.

From the stored runs only: ``extra["data"]`` (the measured times, the measured values and the
case's model at those times) and ``extra["fit"]`` (the fit's summary, experiment/fit.py). The
estimates table gives each parameter with its standard error and 95 % interval; the figures are
one panel per measured quantity and case: the data as markers and the model as a line; the
residuals (model minus data) against time; and their autocorrelation with white noise's 95 %
band, +-1.96/sqrt(n), where correlated residuals say the model misses a dynamic.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.report.plots import MAX_MARKERS, REFERENCE_COLOR, SERIES_COLORS, FigureSpec, Line, Panel, RefLine

__all__ = ["FitView", "fit_view"]


@dataclass(eq=False)
class FitView:
    """What one experiment's fit part shows."""

    fit: dict[str, Any] | None  # the summary, None when the runs only compare with [data]
    rows: list[dict[str, Any]] = field(default_factory=list)  # one per parameter
    correlations: list[tuple[str, str, float]] = field(default_factory=list)
    files: list[str] = field(default_factory=list)
    figures: list = field(default_factory=list)  # FigureSpecs, then drawn Figures
    failed_trials: int = 0  # trial points where the model could not be solved (rejected steps)

    @property
    def converged(self) -> bool:
        return self.fit is not None and self.fit.get("status") == "converged"


def _axis(name: str, units: dict[str, str]) -> str:
    unit = units.get(name)
    return f"{name} ({unit})" if unit else name


def fit_view(stem: str, runs, units: dict[str, str]) -> FitView | None:
    """The section's fit part, or None when no run has [data]."""
    with_data = [r for r in runs if isinstance(r.extra.get("data"), dict)]
    fit = next((r.extra["fit"] for r in runs if isinstance(r.extra.get("fit"), dict)), None)
    if not with_data and fit is None:
        return None
    view = FitView(fit=fit)
    if fit is not None:
        failed = fit.get("failed_trials")
        if isinstance(failed, int) and not isinstance(failed, bool) and failed > 0:
            view.failed_trials = failed
        for name, p in fit.get("parameters", {}).items():
            est, se = p.get("estimate"), p.get("standard_error")
            rel = f"{abs(se / est):.2%}" if se is not None and est else "—"
            view.rows.append({"name": name, "estimate": est, "se": se, "lo": p.get("ci95", [None, None])[0],
                              "hi": p.get("ci95", [None, None])[1], "rel": rel, "initial": p.get("initial"),
                              "at_bound": p.get("at_bound", False)})
        names = fit.get("names", [])
        corr = fit.get("correlation") or []
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                try:
                    c = corr[i][j]
                except (IndexError, TypeError):
                    continue
                if isinstance(c, (int, float)):
                    view.correlations.append((names[i], names[j], float(c)))
    panels, residual_panels, acf_panels = [], [], []
    fitted_cases = set(fit.get("cases", [])) if fit else set()
    t_unit = units.get("t")
    for k, r in enumerate(with_data):
        d = r.extra["data"]
        if d.get("file") and d["file"] not in view.files:
            view.files.append(d["file"])
        try:
            t = np.asarray(d["t"], dtype=float)
        except (TypeError, ValueError):
            continue
        for name, measured in d.get("measured", {}).items():
            model = d.get("model", {}).get(name)
            try:
                y = np.asarray(measured, dtype=float)
                m = np.asarray(model, dtype=float)
            except (TypeError, ValueError):
                continue
            if y.shape != t.shape or m.shape != t.shape:
                continue
            where = f" ({r.case})" if len(with_data) > 1 else ""
            marker = "o" if t.size <= MAX_MARKERS else None
            data_line = Line(t, y, "measured", "#777777", linestyle="none" if marker else "-", marker=marker,
                             linewidth=0.8, markersize=3.5)
            label = "fitted model" if r.case in fitted_cases else "model"
            panels.append(Panel(f"{name}{where}: {label} over the data", _axis("t", units), _axis(name, units),
                                (data_line, Line(t, m, f"{label} ({r.method})", REFERENCE_COLOR, linewidth=1.4,
                                                 zorder=10))))
            # the fit's own residuals (the model at the fit's tight tolerances) where there is a fit, else the
            # case's (its own solver's values at the measured times)
            tr, res = t, m - y
            fitted = (fit or {}).get("residuals", {}).get(r.case, {}).get(name, {})
            try:
                if fitted.get("residuals") is not None:
                    tr, res = np.asarray(fitted["t"], dtype=float), np.asarray(fitted["residuals"], dtype=float)
                    if tr.shape != res.shape:
                        tr, res = t, m - y
            except (TypeError, ValueError, AttributeError):
                tr, res = t, m - y
            color = SERIES_COLORS[k % len(SERIES_COLORS)]
            residual_panels.append(Panel(f"residuals of {name}{where}", _axis("t", units), f"model - data",
                                         (Line(tr, res, "model - data", color, linestyle="-" if not marker else ":",
                                               marker=marker, linewidth=0.8, markersize=3),),
                                         reflines=(RefLine(0.0, "zero", color="#555555", linestyle="-"),),
                                         legend=False))
            acf = _acf(res)
            lags = np.arange(acf.size, dtype=float)
            band = 1.96 / np.sqrt(res.size) if res.size else np.nan
            acf_panels.append(Panel(f"autocorrelation of the residuals of {name}{where}", "lag (measurements)",
                                    "autocorrelation", (Line(lags, acf, "autocorrelation", color, marker="o",
                                                             linewidth=1.0),),
                                    reflines=(RefLine(band, "white noise 95 % band", linestyle="--"),
                                              RefLine(-band, "", linestyle="--")), legend=False))
    if panels:
        what = "the fitted model" if fit is not None else "the model"
        view.figures.append(FigureSpec(
            name=f"{stem}-data", caption=f"Measurements (grey) and {what} (black) at the measured times"
            + (f", t in {t_unit}" if t_unit else "") + "; the model's values come from the solver itself (its "
            "interpolant at the measured times), never extrapolated.",
            alt=f"{what.capitalize()} drawn over the measured data.", panels=tuple(panels),
            columns=2 if len(panels) > 1 else 1))
        view.figures.append(FigureSpec(
            name=f"{stem}-residuals", caption="Residuals (model minus data; of a fitted case, the fit's own, at its "
            "tolerances) against time, and their autocorrelation "
            "with white noise's 95 % band (+-1.96/sqrt(n)): residuals that stay on one side for long stretches, or an "
            "autocorrelation outside the band, say the model misses a dynamic (and the intervals are optimistic).",
            alt="Residuals against time and their autocorrelation.",
            panels=tuple(p for pair in zip(residual_panels, acf_panels) for p in pair), columns=2))
    return view


def _acf(r: np.ndarray) -> np.ndarray:
    from odelab.analysis.fit import autocorrelation

    return autocorrelation(r)
