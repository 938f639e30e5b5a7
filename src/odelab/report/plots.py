"""Figures of the report: declarative panel specs in, PNG bytes out.

The report's content code (:mod:`odelab.report.content`) decides *what* each figure shows as
plain :class:`FigureSpec` data; this module is the only place that knows matplotlib, which it
imports (with the non-interactive Agg backend) only when a figure is drawn, so importing the
report package stays light and works on a machine with no display.

Colours are fixed, not cycled, so a method has the same colour in every figure of a report:
:data:`METHOD_COLORS` for solvers, black for every reference (exact, LTI, high-accuracy or
the nonlinear model), :data:`SERIES_COLORS` for lines that are not methods (several states of
one solution, several cases of one method).
"""

from __future__ import annotations

import io
import math
import zlib
from dataclasses import dataclass

import numpy as np

__all__ = [
    "METHOD_COLORS",
    "REFERENCE_COLOR",
    "SERIES_COLORS",
    "FigureSpec",
    "Line",
    "Panel",
    "RefLine",
    "method_color",
    "render_png",
]

# Okabe & Ito's colour-blind-safe palette (Okabe, Ito 2008, "Color Universal Design"),
# one colour per method; ode23 and ode45, the lab's pair, get the two most distinct ones.
METHOD_COLORS: dict[str, str] = {
    "ode23": "#0072B2",  # blue
    "ode45": "#D55E00",  # vermillion
    "rk4": "#009E73",  # bluish green
    "euler": "#CC79A7",  # reddish purple
    "heun": "#E69F00",  # orange
    "midpoint": "#56B4E9",  # sky blue
    "ralston": "#8C6D31",
    "rk3": "#7F7F7F",
    "RK23": "#2B4C7E",
    "RK45": "#8E2C0E",
    "DOP853": "#3E7D5E",
    "Radau": "#6A3D9A",
    "BDF": "#B15928",
    "LSODA": "#1B9E77",
}
# Methods odelab does not know (a newer registry) still get a stable colour from this list.
_EXTRA_METHOD_COLORS = ("#882255", "#44AA99", "#999933", "#AA4499", "#332288", "#117733")
REFERENCE_COLOR = "#000000"
# Paul Tol's "muted" scheme: for lines that are not methods; none is a method colour above.
SERIES_COLORS = ("#332288", "#117733", "#AA4499", "#88CCEE", "#999933", "#CC6677", "#44AA99", "#882255")

# Above this many points a line is drawn without markers (they would merge into a band).
MAX_MARKERS = 150
# Width of a report figure in inches; the HTML shows it at the page width (about 60 rem).
FIGURE_WIDTH = 7.2
PANEL_HEIGHT = 2.7
DPI = 130


def method_color(method: str) -> str:
    """The report-wide colour of a solver method (stable for unknown names too)."""
    if method in METHOD_COLORS:
        return METHOD_COLORS[method]
    return _EXTRA_METHOD_COLORS[zlib.crc32(method.encode("utf-8")) % len(_EXTRA_METHOD_COLORS)]


@dataclass(frozen=True, eq=False)
class Line:
    """One curve of a panel. ``marker`` is drawn only if the line has few enough points."""

    x: np.ndarray
    y: np.ndarray
    label: str
    color: str
    linestyle: str = "-"
    marker: str | None = None
    linewidth: float = 1.5
    markersize: float = 4.0
    zorder: float = 2.0


@dataclass(frozen=True)
class RefLine:
    """A horizontal (``axis="y"``) or vertical (``axis="x"``) line at ``value``, e.g. a threshold."""

    value: float
    label: str
    axis: str = "y"
    color: str = "#B00020"
    linestyle: str = "--"


@dataclass(frozen=True, eq=False)
class Panel:
    """One axes: title, labelled axes (with units), lines, optional log scales."""

    title: str
    xlabel: str
    ylabel: str
    lines: tuple[Line, ...]
    xscale: str = "linear"
    yscale: str = "linear"
    reflines: tuple[RefLine, ...] = ()
    note: str = ""  # shown in the panel when it has nothing to draw
    legend_outside: bool = False  # right of the axes: for curves that fill the whole panel


@dataclass(frozen=True, eq=False)
class FigureSpec:
    """A figure: panels in a grid of ``columns`` columns, with a caption and alt text for the report."""

    name: str  # unique file stem within the report, e.g. "exercise1-solution"
    caption: str
    alt: str
    panels: tuple[Panel, ...]
    columns: int = 1
    panel_height: float = PANEL_HEIGHT


def _finite_positive(x: np.ndarray, y: np.ndarray, log_x: bool, log_y: bool) -> tuple[np.ndarray, np.ndarray]:
    """Points a log axis cannot show (zero, negative, NaN) become gaps, not errors."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float).copy()
    bad = ~np.isfinite(y) | ~np.isfinite(x)
    if log_y:
        bad |= y <= 0
    if log_x:
        bad |= x <= 0
    y[bad] = np.nan
    return x, y


def _draw_panel(ax, panel: Panel) -> None:
    log_x, log_y = panel.xscale == "log", panel.yscale == "log"
    drawn = 0
    for line in panel.lines:
        x, y = _finite_positive(line.x, line.y, log_x, log_y)
        if not np.any(np.isfinite(y)):
            continue
        marker = line.marker if line.marker and x.size <= MAX_MARKERS else None
        # an isolated finite point between gaps is invisible without a marker
        if marker is None and log_y and x.size <= 4 * MAX_MARKERS:
            marker = "."
        ax.plot(x, y, linestyle=line.linestyle, marker=marker, color=line.color, label=line.label,
                linewidth=line.linewidth, markersize=line.markersize, zorder=line.zorder)
        drawn += 1
    for ref in panel.reflines:
        if ref.value is None or not math.isfinite(ref.value):
            continue
        draw = ax.axhline if ref.axis == "y" else ax.axvline
        draw(ref.value, color=ref.color, linestyle=ref.linestyle, linewidth=1.2, label=ref.label, zorder=1)
    if log_x:
        ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
    ax.set_title(panel.title, fontsize=10)
    ax.set_xlabel(panel.xlabel)
    ax.set_ylabel(panel.ylabel)
    ax.grid(True, which="major", color="#DDDDDD", linewidth=0.6)
    if log_y or log_x:
        ax.grid(True, which="minor", color="#F0F0F0", linewidth=0.4)
    if not drawn:
        ax.text(0.5, 0.5, panel.note or "nothing to plot", transform=ax.transAxes, ha="center", va="center",
                fontsize=9, color="#555555")
    elif ax.get_legend_handles_labels()[0]:
        if panel.legend_outside:
            ax.legend(fontsize=8, frameon=False, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        else:
            ax.legend(fontsize=8, frameon=True, framealpha=0.85, loc="best")


def render_png(spec: FigureSpec) -> bytes:
    """Draw ``spec`` and return the PNG file's bytes (the figure is closed before returning)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    n = max(len(spec.panels), 1)
    cols = max(1, min(spec.columns, n))
    rows = math.ceil(n / cols)
    height = spec.panel_height * rows + 0.3
    style = {"font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "xtick.labelsize": 8,
             "ytick.labelsize": 8, "legend.fontsize": 8, "axes.spines.top": False, "axes.spines.right": False}
    with plt.rc_context(style):
        fig = plt.figure(figsize=(FIGURE_WIDTH, height), layout="constrained")
        try:
            # each panel spans two grid columns, so a short last row can be centred
            grid = fig.add_gridspec(rows, 2 * cols)
            for i, panel in enumerate(spec.panels):
                row, col = divmod(i, cols)
                in_row = min(cols, len(spec.panels) - row * cols)
                start = 2 * col + (cols - in_row)
                _draw_panel(fig.add_subplot(grid[row, start:start + 2]), panel)
            buf = io.BytesIO()
            # no timestamp in the metadata: the same data gives the same file, run after run
            fig.savefig(buf, format="png", dpi=DPI, facecolor="white", metadata={"Software": "odelab report"})
        finally:
            plt.close(fig)
    return buf.getvalue()
