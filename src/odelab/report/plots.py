"""Figures of the report: declarative panel specs in, PNG bytes out.

The report's content code (:mod:`odelab.report.figures`) decides *what* each figure shows as
plain :class:`FigureSpec` data; this module is the only place that knows matplotlib, which it
imports (with the non-interactive Agg backend) only when a figure is drawn, so importing the
report package stays light and works on a machine with no display.

One look for the whole report (every new section follows it; docs/REPORT-STYLE.md says why):

- **one colour meaning per quantity**: a solver method always has its :func:`method_style`
  (colour, marker and line style together, so lines survive grey-scale printing); the truth a
  run is compared with (exact, exact LTI, high-accuracy, the nonlinear model) is always
  :data:`REFERENCE` (thin, black, drawn on top); the linearised model is always
  :data:`LINEARISED` (purple, dashed); inputs u(t) are always :data:`INPUT` (grey); several
  states of one solution take :data:`SERIES_COLORS` in order;
- markers are hollow, and the line with fewer points is drawn above the one with more, so
  ode23's 12 output points are never hidden under ode45's 41;
- every axis label carries its unit ("x (m)", "t (s)"; see :func:`axis_label`); an error axis
  says what it divides by ("|f - y| / |f|" or "|f - y| / max |f|");
- titles wrap instead of running off the panel.
"""

from __future__ import annotations

import io
import math
import textwrap
import zlib
from dataclasses import dataclass

import numpy as np

from odelab.report.mplreuse import renderer, ticks_once
from odelab.solvers.registry import METHODS

__all__ = [
    "INPUT",
    "LINEARISED",
    "METHOD_COLORS",
    "REFERENCE",
    "REFERENCE_COLOR",
    "SERIES_COLORS",
    "FigureSpec",
    "Line",
    "LineStyle",
    "Panel",
    "RefLine",
    "axis_label",
    "clipped_texts",
    "legends_over_data",
    "draw_figure",
    "method_color",
    "method_style",
    "render_png",
]

# Each method's colour is its registry entry's (odelab.solvers.registry: Okabe & Ito's colour-blind-safe palette,
# Okabe, Ito 2008, "Color Universal Design"; the lab's pair, ode23 and ode45, get the two most distinct ones).
METHOD_COLORS: dict[str, str] = {m.name: m.color for m in METHODS.values() if m.color}
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
    known = METHODS.get(method)
    if known is not None and known.color:
        return known.color
    return _EXTRA_METHOD_COLORS[zlib.crc32(method.encode("utf-8")) % len(_EXTRA_METHOD_COLORS)]


@dataclass(frozen=True)
class LineStyle:
    """Colour, marker and line style of one role, used together everywhere in the report."""

    color: str
    marker: str | None = None
    linestyle: str = "-"
    linewidth: float = 1.2


# The lab's pair differ in colour, marker *and* dash (their registry entries), so they stay apart in grey-scale print.
_EXTRA_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "h")
_EXTRA_DASHES = ("-", "--", "-.", ":")

REFERENCE = LineStyle(REFERENCE_COLOR, None, "-", 0.9)  # the truth: thin, black, on top
LINEARISED = LineStyle("#AA4499", None, "--", 1.4)  # the linearised model (a series colour, never a method's)
INPUT = LineStyle("#555555", None, "-", 1.2)  # inputs u(t)
REFERENCE_ZORDER = 10.0


def method_style(method: str) -> LineStyle:
    """The report-wide colour, marker and dash of a solver method (stable for unknown names too)."""
    h = zlib.crc32(method.encode("utf-8"))
    known = METHODS.get(method)
    marker = (known and known.marker) or _EXTRA_MARKERS[h % len(_EXTRA_MARKERS)]
    dash = (known and known.dash) or _EXTRA_DASHES[(h >> 8) % len(_EXTRA_DASHES)]
    return LineStyle(method_color(method), marker, dash, 1.1)


def drawable(text: str) -> str:
    """``text`` as matplotlib can draw it: mathtext it cannot parse (a hand-edited result's
    ``$\\hspace$``, a case named ``a$b$\\foo``) is shown as plain text, its ``$`` escaped."""
    from odelab.experiment.fields import mathtext_problem

    if not text or "$" not in text or mathtext_problem(text) is None:
        return text
    return text.replace("\\$", "$").replace("$", "\\$")


def axis_label(name: str, unit: str | None = None) -> str:
    """``x (m)``; the name alone when no unit is known."""
    return f"{name} ({unit})" if unit else name


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
    height: float = 1.0  # relative height of the panel's row (an input under an output: 0.6)
    legend: bool = True  # False: the figure's shared legend (FigureSpec.legend) names these lines
    decades: int | None = None  # a log error axis's depth (default LOG_DECADES; a convergence plot needs more)


@dataclass(frozen=True, eq=False)
class FigureSpec:
    """A figure: panels in a grid of ``columns`` columns, with a caption and alt text for the report."""

    name: str  # unique file stem within the report, e.g. "exercise1-solution"
    caption: str
    alt: str
    panels: tuple[Panel, ...]
    columns: int = 1
    panel_height: float = PANEL_HEIGHT
    legend: bool = False  # one legend above the panels, of every distinct label (small multiples)


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


# A log error axis shows at most this many decades below its largest value: round-off-level
# errors at the first points (1e-20) would otherwise squeeze the errors that matter into a strip.
LOG_DECADES = 9


def _limit_decades(ax, panel: Panel, log_x: bool) -> None:
    values = [_finite_positive(ln.x, ln.y, log_x, True)[1] for ln in panel.lines]
    finite = np.concatenate([v[np.isfinite(v)] for v in values]) if values else np.array([])
    decades = panel.decades or LOG_DECADES
    if finite.size and finite.min() < finite.max() * 10.0 ** -decades:
        ax.set_ylim(bottom=finite.max() * 10.0 ** -decades)


def _draw_panel(ax, panel: Panel, columns: int = 1) -> None:
    log_x, log_y = panel.xscale == "log", panel.yscale == "log"
    drawn = 0
    # the sparser of two marked lines goes on top, so its markers are never hidden
    marked = sorted((ln for ln in panel.lines if ln.marker), key=lambda ln: -np.size(ln.x))
    rank = {id(ln): i for i, ln in enumerate(marked)}
    for line in panel.lines:
        x, y = _finite_positive(line.x, line.y, log_x, log_y)
        if not np.any(np.isfinite(y)):
            continue
        marker = line.marker if line.marker and x.size <= MAX_MARKERS else None
        # an isolated finite point between gaps is invisible without a marker
        if marker is None and log_y and x.size <= 4 * MAX_MARKERS:
            marker = "."
        # marked lines: by point count alone (sparsest on top), always under a reference line
        zorder = 2.0 + 0.5 * rank[id(line)] if id(line) in rank else line.zorder
        hollow = {"markerfacecolor": "none", "markeredgewidth": 0.9} if marker not in (None, ".") else {}
        ax.plot(x, y, linestyle=line.linestyle, marker=marker, color=line.color, label=drawable(line.label),
                linewidth=line.linewidth, markersize=line.markersize, zorder=zorder, **hollow)
        drawn += 1
    for ref in panel.reflines:
        if ref.value is None or not math.isfinite(ref.value):
            continue
        draw = ax.axhline if ref.axis == "y" else ax.axvline
        draw(ref.value, color=ref.color, linestyle=ref.linestyle, linewidth=1.2, label=drawable(ref.label), zorder=1)
    if log_x:
        ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
        _limit_decades(ax, panel, log_x)
    # characters that fit over one panel: titles wrap rather than run off the figure
    size = 9.5 if columns <= 2 else 8.5
    width = max(18, int((90 if columns <= 3 else 84) / max(columns, 1)))
    ax.set_title(drawable("\n".join(textwrap.wrap(panel.title, width))) if panel.title else "", fontsize=size)
    ax.set_xlabel(drawable(panel.xlabel))
    ax.set_ylabel(drawable(panel.ylabel))
    _grid(ax, minor=log_y or log_x)
    if not drawn:
        ax.text(0.5, 0.5, panel.note or "nothing to plot", transform=ax.transAxes, ha="center", va="center",
                fontsize=9, color="#555555")
    elif ax.get_legend_handles_labels()[0] and panel.legend:
        if panel.legend_outside:
            ax.legend(fontsize=8, frameon=False, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        else:
            ax.legend(fontsize=8, frameon=True, framealpha=0.85, loc="best")


def _grid(ax, *, minor: bool) -> None:
    """The major grid on, the minor one on ``minor`` (log) axes; set only when it changes: each
    ``ax.grid`` call restyles every tick the axes holds, which a kept figure's axes keep."""
    state = ax.__dict__.setdefault("_odelab_grid", set())
    if "major" not in state:
        ax.grid(True, which="major", color="#DDDDDD", linewidth=0.6)
        state.add("major")
    if minor and "minor" not in state:
        ax.grid(True, which="minor", color="#F0F0F0", linewidth=0.4)
        state.add("minor")
    elif not minor and "minor" in state:
        ax.grid(False, which="minor")
        state.discard("minor")


def _figure_legend(fig, axes: list):
    """One legend above the panels holding every distinct label once (small multiples)."""
    handles: dict[str, object] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, handle)
    if not handles:
        return None
    return fig.legend(list(handles.values()), list(handles), loc="upper center", ncols=min(len(handles), 5),
                      fontsize=8, frameon=False, bbox_to_anchor=(0.5, 1.0 - _PAD / fig.get_figheight()))


# Space (inches) around every panel's decorations and at the figure's edges: constrained
# layout's default pads (3 points), so the fixed layout below spaces panels as it did.
_PAD = 3 / 72


class _Grid:
    """Where each panel's axes go: a grid of ``rows`` rows and ``2 * cols`` columns (a panel spans
    two, so a short last row is centred), every column as wide and every row as tall (by its
    ratio) as the others, with per-column and per-row margins that hold the panels'
    decorations (tick labels, axis labels, titles, legends) as constrained layout sizes them.

    Margins are measured once, on the figure drawn at a first estimate of them (text
    extents, no pixels): the panels' sizes then change by a few percent at most, which is
    what one constrained-layout pass leaves too."""

    def __init__(self, width: float, height: float, ratios: list[float], cols: int, cells: list[tuple[int, int]]):
        self.width, self.height, self.ratios, self.cols, self.cells = width, height, ratios, cols, cells
        self.top_band = 0.0  # the figure legend's height, above the grid

    def rects(self, left: list[float], right: list[float], top: list[float], bottom: list[float]) -> list[tuple]:
        """Axes rectangles in figure fractions; margins in inches per grid column / row."""
        g = 2 * self.cols
        inner_w = max(self.width - 2 * _PAD - sum(left) - sum(right), 0.1 * self.width) / g
        x, edges = _PAD, []
        for j in range(g):
            x += left[j]
            edges.append(x)
            x += inner_w + right[j]
        inner_h = max(self.height - 2 * _PAD - self.top_band - sum(top) - sum(bottom), 0.1 * self.height)
        y, rows = self.height - _PAD - self.top_band, []
        for i, ratio in enumerate(self.ratios):
            y -= top[i]
            h = inner_h * ratio / sum(self.ratios)
            rows.append((y - h, y))
            y -= h + bottom[i]
        out = []
        for row, start in self.cells:
            x0, x1 = edges[start], edges[start + 1] + inner_w
            y0, y1 = rows[row]
            out.append((x0 / self.width, y0 / self.height, (x1 - x0) / self.width, (y1 - y0) / self.height))
        return out

    def guess(self, panels) -> tuple[list[float], ...]:
        """First margins: what a panel's labels usually take."""
        g = 2 * self.cols
        left, right = [0.0] * g, [0.0] * g
        top, bottom = [0.0] * len(self.ratios), [0.0] * len(self.ratios)
        for (row, start), panel in zip(self.cells, panels):
            left[start] = max(left[start], 0.62 if panel.ylabel else 0.45)
            right[start + 1] = max(right[start + 1], 1.6 if panel.legend_outside else 0.08)
            top[row] = max(top[row], 0.1 + 0.17 * (panel.title.count("\n") + 1) if panel.title else 0.15)
            bottom[row] = max(bottom[row], 0.45 if panel.xlabel else 0.25)
        return left, right, top, bottom

    def measured(self, fig, axes: list) -> tuple[list[float], ...]:
        """Margins that hold what each axes draws outside its frame, measured on ``fig``."""
        render = renderer(fig)
        dpi = fig.dpi
        g = 2 * self.cols
        left, right = [0.0] * g, [0.0] * g
        top, bottom = [0.0] * len(self.ratios), [0.0] * len(self.ratios)
        for (row, start), ax in zip(self.cells, axes):
            box = ax.get_tightbbox(render)
            frame = ax.get_window_extent(render)
            if box is None:
                box = frame
            left[start] = max(left[start], (frame.x0 - box.x0) / dpi + _PAD)
            right[start + 1] = max(right[start + 1], (box.x1 - frame.x1) / dpi + _PAD)
            top[row] = max(top[row], (box.y1 - frame.y1) / dpi + _PAD)
            bottom[row] = max(bottom[row], (frame.y0 - box.y0) / dpi + _PAD)
        return left, right, top, bottom


_STYLE = {"font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "xtick.labelsize": 8, "ytick.labelsize": 8,
          "legend.fontsize": 8, "axes.spines.top": False, "axes.spines.right": False,
          # ticks such as 0.00025 as 2.5 with a 1e-4 above the axis: long tick labels crowd the margins
          "axes.formatter.limits": (-3, 5),
          # never an offset (a "1e-4+3.333" over the axis, read as part of the values): the ticks say it all
          "axes.formatter.useoffset": False}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _matplotlib() -> None:
    """What a kept figure needs of matplotlib (its Figure and the Agg canvas, not pyplot), imported."""
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.figure  # noqa: F401


def _shape(spec: FigureSpec) -> tuple[_Grid, int, float]:
    """The grid of ``spec``'s panels, its number of columns and the figure's height (inches)."""
    n = max(len(spec.panels), 1)
    cols = max(1, min(spec.columns, n))
    rows = math.ceil(n / cols)
    ratios = [max((p.height for p in spec.panels[r * cols:(r + 1) * cols]), default=1.0) for r in range(rows)]
    height = spec.panel_height * sum(ratios) + 0.3 + (0.35 if spec.legend else 0.0)
    cells = []
    for i in range(len(spec.panels)):
        row, col = divmod(i, cols)
        in_row = min(cols, len(spec.panels) - row * cols)
        cells.append((row, 2 * col + (cols - in_row)))  # each panel spans two grid columns
    return _Grid(FIGURE_WIDTH, height, ratios, cols, cells), cols, height


def _lay_out(fig, axes: list, grid: _Grid, spec: FigureSpec, cols: int) -> None:
    """Draw ``spec``'s panels on ``axes`` (new or cleared) and place them with measured margins."""
    renderer(fig)  # this size's renderer, with the shared mathtext parser, before anything is measured
    for ax, rect, panel in zip(axes, grid.rects(*grid.guess(spec.panels)), spec.panels):
        ax.set_position(rect)
        _draw_panel(ax, panel, cols)
    if spec.legend:
        legend = _figure_legend(fig, axes)
        if legend is not None:
            grid.top_band = legend.get_window_extent(renderer(fig)).height / fig.dpi + _PAD
    with ticks_once(axes):
        margins = grid.measured(fig, axes)
    for ax, rect in zip(axes, grid.rects(*margins)):
        ax.set_position(rect)
    moved = [ax for ax in axes if _legend_over_data(ax)]
    for ax in moved:  # no place inside the axes is clear of the data: the legend goes right of it
        legend = ax.get_legend()
        ax.legend(legend.legend_handles, [t.get_text() for t in legend.get_texts()], fontsize=8, frameon=False,
                  loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if moved:
        with ticks_once(axes):
            margins = grid.measured(fig, axes)
        for ax, rect in zip(axes, grid.rects(*margins)):
            ax.set_position(rect)


def _legend_over_data(ax) -> bool:
    """Whether the legend inside ``ax`` lies over any of its curves (a line crossing its box)."""
    legend = ax.get_legend()
    if legend is None or not legend.get_visible() or legend.get_bbox_to_anchor() is not ax.bbox:
        return False
    box = legend.get_window_extent(renderer(ax.figure)).shrunk(0.98, 0.96)
    for line in ax.lines:
        if line.get_visible() and line.get_path().transformed(line.get_transform()).intersects_bbox(box, filled=False):
            return True
    return False


def legends_over_data(fig) -> list[str]:
    """The panels whose legend, inside the axes, covers a curve (none should: :func:`_lay_out` moves them)."""
    return [ax.get_title() or f"panel {i + 1}" for i, ax in enumerate(fig.axes) if _legend_over_data(ax)]


def _new_figure(height: float, n: int):
    """A figure of the report's width and ``height`` with ``n`` axes, on an Agg canvas of its own
    (not pyplot's: nothing to close, and pyplot is not imported for it)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(FIGURE_WIDTH, height), dpi=DPI)
    FigureCanvasAgg(fig)
    for _ in range(n):
        fig.add_axes((0.1, 0.1, 0.8, 0.8))
    return fig


def _clear(fig, axes: list) -> None:
    """``axes`` of ``fig`` as a new figure's, keeping the axes and their tick artists: what a panel
    drew (lines, texts, legends, log scales, limits, the minor grid) removed; the figure's legend too.

    Creating axes and their ticks is a third of a figure's time; the PNG drawn on a cleared
    figure is byte for byte the one a new figure gives (``tests/report/test_drawing.py``)."""
    for legend in list(fig.legends):
        legend.remove()
    for ax in axes:
        for artist in (*ax.lines, *ax.texts, *ax.collections, *ax.patches, *ax.images):
            artist.remove()
        if ax.get_legend() is not None:
            ax.get_legend().remove()
        ax.set_xscale("linear")
        ax.set_yscale("linear")
        ax.relim()
        ax.set_xlim(0.0, 1.0, auto=True)  # a new axes' view, autoscaled once something is drawn
        ax.set_ylim(0.0, 1.0, auto=True)


# The figure kept for the next one: its axes are the most any figure drawn so far had; a figure
# of fewer panels uses the first ones and hides the rest, its height is set for each figure.
_REUSABLE: dict[str, object] = {}
_REUSABLE_MAX = 1


def _reused_figure(spec: FigureSpec):
    """A laid-out figure of ``spec`` drawn on the kept figure (or a new one, then kept): resized,
    its axes cleared, axes added if it has fewer than ``spec`` has panels, the others hidden.

    The caller does not close it: it stays for the next figure."""
    grid, cols, height = _shape(spec)
    n = len(spec.panels)
    fig = _REUSABLE.pop("figure", None)
    with _rc_context():
        try:
            if fig is None:
                fig = _new_figure(height, n)
            else:
                if fig.get_figheight() != height:
                    fig.set_size_inches(FIGURE_WIDTH, height)
                _clear(fig, fig.axes[:n])
                while len(fig.axes) < n:
                    fig.add_axes((0.1, 0.1, 0.8, 0.8))
            axes = list(fig.axes[:n])
            for i, ax in enumerate(fig.axes):
                ax.set_visible(i < n)
            _lay_out(fig, axes, grid, spec, cols)
        except Exception:
            return None  # not kept: a half-drawn figure is never reused (nor kept on Ctrl-C, which goes on up)
    _REUSABLE["figure"] = fig
    return fig


def _rc_context():
    import matplotlib

    return matplotlib.rc_context(_STYLE)


def draw_figure(spec: FigureSpec, *, render: bool = True):
    """The matplotlib figure of ``spec``, laid out; the caller closes it (``render_png`` does).

    The layout is fixed margins measured once (:class:`_Grid`), not constrained layout,
    whose passes (two per draw, each measuring every tick label) cost three quarters of a
    figure's time. ``render=False`` lays it out without rasterising it: the same state for a
    caller that saves the figure, which draws it anyway.
    """
    plt = _pyplot()
    grid, cols, height = _shape(spec)
    with plt.rc_context(_STYLE):
        fig = plt.figure(figsize=(FIGURE_WIDTH, height), dpi=DPI)
        try:
            axes = [fig.add_axes((0.1, 0.1, 0.8, 0.8)) for _ in spec.panels]
            _lay_out(fig, axes, grid, spec, cols)
            if render:
                fig.canvas.draw()  # drawn now, so a caller can measure what was drawn
        except BaseException:
            plt.close(fig)
            raise
    return fig


def clipped_texts(fig) -> list[str]:
    """What reaches past the figure's edges, cut off in the PNG: titles, axis labels, tick labels, legends."""
    renderer = fig.canvas.get_renderer()
    width, height = fig.bbox.width, fig.bbox.height
    parts = []
    for ax in fig.axes:
        parts += [(f"title {ax.get_title()!r}", ax.title), (f"x label {ax.get_xlabel()!r}", ax.xaxis.label),
                  (f"y label {ax.get_ylabel()!r}", ax.yaxis.label), ("legend", ax.get_legend()),
                  (f"x ticks of {ax.get_title()!r}", ax.xaxis), (f"y ticks of {ax.get_title()!r}", ax.yaxis)]
    parts += [("figure legend", legend) for legend in fig.legends]
    out = []
    for what, artist in parts:
        if artist is None or not artist.get_visible():
            continue
        box = artist.get_tightbbox(renderer) if hasattr(artist, "get_ticklabels") else artist.get_window_extent(renderer)
        if box is None or box.width == 0:
            continue
        if box.x0 < -0.5 or box.y0 < -0.5 or box.x1 > width + 0.5 or box.y1 > height + 0.5:
            out.append(what)
    return out


def render_png(spec: FigureSpec) -> bytes:
    """The PNG file's bytes of ``spec``: from the figure cache, or drawn (and then cached).

    The same data gives the same file, run after run (no timestamp in the metadata), so the
    cache keyed by the data (:mod:`odelab.report.figcache`) returns exactly what drawing would.
    """
    from odelab.report import figcache

    key = figcache.figure_key(spec)
    png = figcache.load(key)
    if png is None:
        png = _draw_png(spec)
        figcache.store(key, png)
    return png


def _draw_png(spec: FigureSpec) -> bytes:
    """Laid out once (text extents only, no pixels) and rasterised once, by savefig, on a
    figure kept from the figure before when there is one (:func:`_reused_figure`)."""
    fig = _reused_figure(spec)
    fresh = fig is None
    if fresh:  # it failed on a kept figure: drawn on a new one (which raises the error, if it is the spec's)
        fig = draw_figure(spec, render=False)
    try:
        fig.patch.set_facecolor("white")
        with ticks_once(fig.axes):
            fig.canvas.draw()
        return _png(fig)
    finally:
        if fresh:
            _pyplot().close(fig)


def _png(fig) -> bytes:
    """The drawn canvas as a PNG of at most 256 colours (Pillow's fast octree, no dithering): a
    report figure is white paper, black text and a few line colours with their anti-aliased
    edges, which 256 colours hold to within 45 of 255 on a channel (the edges; 1 on average);
    the shipped set's figures take 693 KiB instead of 2331 and are encoded in half the time
    (0.20 s against 0.42). No timestamp in the metadata: the same data gives the same file."""
    from PIL import Image, PngImagePlugin

    width, height = fig.canvas.get_width_height()
    rgba = Image.frombuffer("RGBA", (width, height), fig.canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
    image = rgba.convert("RGB").quantize(256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    if rgba.getpixel((0, 0)) == (255, 255, 255, 255):  # the octree's white is its cell's centre, 254: the paper stays white
        palette = bytearray(image.getpalette() or b"")
        k = 3 * image.getpixel((0, 0))
        if k + 3 <= len(palette):
            palette[k:k + 3] = b"\xff\xff\xff"
            image.putpalette(palette)
    info = PngImagePlugin.PngInfo()
    info.add_text("Software", "odelab report")
    buf = io.BytesIO()
    image.save(buf, format="png", pnginfo=info, dpi=(DPI, DPI))
    return buf.getvalue()
