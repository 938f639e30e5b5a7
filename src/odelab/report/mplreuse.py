"""What matplotlib works out again and again for a report figure, worked out once.

**Ticks.** Each axis's ticks are worked out once per measuring pass or draw, not six times.

Matplotlib places an axis's ticks (locates them, formats their labels, updates each tick's
artists: ``Axis._update_ticks``) and measures their labels (``Axis._get_ticklabel_bboxes``)
whenever it needs them: in one draw of a titled panel that is three times for the y axis
(placing the title asks the y axis's extent; placing each axis label asks its ticks again,
``_get_tick_boxes_siblings``) and twice for the x axis, and the measuring pass before it does
as much again. That was a third of a report figure's time (profiled, issue 27).

Within one pass nothing those two methods read changes (the view limits, the axes' place on
the figure, the scale's locator and formatter), so :func:`ticks_once` keeps, for the
duration of a ``with`` block, each axis's last answer and gives it back while what it was
worked out from is the same; the pixels are the same bytes (``tests/report/test_drawing.py``).
Outside the block the axes are matplotlib's own again. This leans on the two private methods'
names; the figure cache is keyed by matplotlib's version, and were they ever gone the block
simply does nothing.

**Mathtext.** A log axis's tick labels (``$\\mathdefault{10^{-6}}$``) are mathtext, and parsing
one costs a few milliseconds. Matplotlib keeps parses per renderer, and an Agg canvas makes a
new renderer whenever the figure's size changes, which the kept figure's does from one figure
to the next: the shipped set's 29 figures parsed their 29 distinct labels 99 times.
:func:`renderer` gives every renderer one parser (a parse depends on the text, its font and
the dpi, not on the renderer), so each label is parsed once a process.
"""

from __future__ import annotations

import sys
from contextlib import contextmanager

__all__ = ["forked", "renderer", "ticks_once"]

_METHODS = ("_update_ticks", "_get_ticklabel_bboxes")


def _state(axis) -> tuple:
    """What an axis's ticks and their labels' boxes are worked out from (objects by identity)."""
    major, minor = axis.major, axis.minor
    return (tuple(axis.get_view_interval()), axis.axes.bbox.bounds, axis.get_scale(),
            id(major.locator), id(major.formatter), id(minor.locator), id(minor.formatter))


def _remember(axis) -> None:
    update, boxes = axis._update_ticks, axis._get_ticklabel_bboxes
    kept: dict = {}

    def update_ticks():
        state = _state(axis)
        if kept.get("state") != state:
            kept.clear()
            kept["ticks"] = update()
            kept["state"] = state
        return kept["ticks"]

    def ticklabel_bboxes(ticks, renderer):
        if ticks is not kept.get("ticks") or kept.get("state") != _state(axis):
            return boxes(ticks, renderer)
        key = ("boxes", id(renderer))
        if key not in kept:
            kept[key] = boxes(ticks, renderer)
        return kept[key]

    axis._update_ticks = update_ticks
    axis._get_ticklabel_bboxes = ticklabel_bboxes


@contextmanager
def ticks_once(axes: list):
    """Within the block, each axis of ``axes`` works out its ticks once per state (see the module)."""
    axises = [axis for ax in axes for axis in (ax.xaxis, ax.yaxis)
              if all(hasattr(type(axis), name) for name in _METHODS)]
    for axis in axises:
        _remember(axis)
    try:
        yield
    finally:
        for axis in axises:
            for name in _METHODS:
                axis.__dict__.pop(name, None)


_PARSER: list = []


def renderer(fig):
    """``fig``'s Agg renderer, its mathtext parser the one every renderer from here shares."""
    out = fig.canvas.get_renderer()
    parser = getattr(out, "mathtext_parser", None)
    if parser is not None:
        if not _PARSER:
            _PARSER.append(parser)
        elif parser is not _PARSER[0] and type(parser) is type(_PARSER[0]):
            out.mathtext_parser = _PARSER[0]
    return out


def forked() -> None:
    """In a process forked from one that drew figures: forget the parses that hold the parent's fonts.

    A parsed mathtext label keeps the font objects it was laid out with, and those read their
    font file through a descriptor the fork shares with the parent (one file offset for both):
    a worker drawing from them garbles the parent's glyph loads ("FT_Load_Glyph ... too many
    hints"). Matplotlib empties its own font cache in a forked child for that reason; the parses
    go too, and the child parses again with fonts of its own (the grammar, the costly part, is
    kept)."""
    mathtext = sys.modules.get("matplotlib.mathtext")
    if mathtext is not None:
        mathtext.MathTextParser._parse_cached.cache_clear()
