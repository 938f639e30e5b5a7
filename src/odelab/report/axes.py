"""How a section's time axis and quantities are drawn: ``[plot] t_scale`` and ``[plot] scale``.

A process over many decades (Robertson's kinetics over [0, 4e10]) drawn on a linear time axis
is three vertical lines at t = 0: the time axis is logarithmic when the file says so, or, with
``t_scale = "auto"``, when most of the output times lie in the first thousandth of the span
(the solver's own steps say where the solution moves). ``scale`` multiplies a quantity for
display only ("10^4 y2"), for a quantity far smaller than the others in one panel.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from odelab.report.collect import StoredRun

__all__ = ["LOG_TIME_CROWDING", "apply_plot_settings", "plot_settings", "time_scale"]

# auto: a log time axis when the median positive output time is below this fraction of the span
LOG_TIME_CROWDING = 1e-3


def plot_settings(runs: list[StoredRun]) -> dict:
    """The section's [plot] table (the first run's; the cases of one file share it)."""
    for r in runs:
        plot = r.config.get("plot")
        if isinstance(plot, dict):
            return plot
    return {}


def _median(x: np.ndarray) -> float:
    """``np.median(x)`` of a 1-D array without NaN, to the bit, without importing numpy.ma as np.median does
    (45 ms of a report's start-up)."""
    s = np.sort(x)
    n = s.size
    return float(s[n // 2]) if n % 2 else float((s[n // 2 - 1] + s[n // 2]) / 2)


def time_scale(runs: list[StoredRun], plot: dict) -> str:
    """"log" or "linear" for the section's time axes."""
    asked = plot.get("t_scale", "auto")
    if asked in ("log", "linear"):
        return asked
    t0 = min((float(r.t[0]) for r in runs if r.t.size), default=0.0)
    if t0 < 0:
        return "linear"
    crowded = []
    for r in runs:
        t = r.t[r.t > 0]
        if t.size >= 3:
            crowded.append(_median(t) < LOG_TIME_CROWDING * float(t[-1]))
    return "log" if crowded and all(crowded) else "linear"


def _factor_label(factor: float, name: str) -> str:
    exponent = math.log10(abs(factor)) if factor else 0.0
    shown = f"10^{int(round(exponent))}" if factor > 0 and abs(exponent - round(exponent)) < 1e-12 else f"{factor:g}"
    return f"{shown} {name}"


def _scaled_panel(panel, scale: dict):
    for name, factor in scale.items():
        if panel.ylabel == name or panel.ylabel.startswith(f"{name} ("):
            lines = tuple(dataclasses.replace(line, y=np.asarray(line.y) * factor) for line in panel.lines)
            return dataclasses.replace(panel, lines=lines, ylabel=_factor_label(factor, panel.ylabel))
    lines = []
    for line in panel.lines:
        for name, factor in scale.items():
            if line.label.startswith(f"{name} ("):
                line = dataclasses.replace(line, y=np.asarray(line.y) * factor,
                                           label=_factor_label(factor, line.label))
                break
        lines.append(line)
    return dataclasses.replace(panel, lines=tuple(lines))


def apply_plot_settings(figure, runs: list[StoredRun], *, time_axes: bool = True, scaled: bool = True):
    """The figure with the section's time scale on its time axes and its display multipliers applied."""
    if figure is None:
        return None
    plot = plot_settings(runs)
    xscale = time_scale(runs, plot) if time_axes else None
    scale = {str(k): float(v) for k, v in (plot.get("scale") or {}).items()
             if isinstance(v, (int, float)) and not isinstance(v, bool) and v} if scaled else {}
    panels = []
    for panel in figure.panels:
        if xscale is not None and panel.xscale == "linear":
            panel = dataclasses.replace(panel, xscale=xscale)
        if scale:
            panel = _scaled_panel(panel, scale)
        panels.append(panel)
    caption = figure.caption
    if xscale == "log" and "log time axis" not in caption:
        caption += (" The time axis is logarithmic" + ("" if plot.get("t_scale") == "log" else
                                                        " (most output times lie in the first thousandth of the span)")
                    + ".")
    return dataclasses.replace(figure, panels=tuple(panels), caption=caption)
