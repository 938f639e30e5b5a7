"""Drawing a report's figures: from the cache, else drawn once, in a pool of processes when there are many."""

import numpy as np
import pytest

from odelab.report import drawing, figcache, plots
from odelab.report.plots import FigureSpec, Line, Panel


def spec(k: int) -> FigureSpec:
    t = np.linspace(0, 1, 20)
    return FigureSpec(name=f"f{k}", caption="c", alt="a", panels=(
        Panel(title=f"x{k}(t)", xlabel="t", ylabel="x", lines=(Line(t, np.sin((k + 1) * t), "ode45", "#D55E00"),)),))


@pytest.mark.skipif(not drawing._can_fork() or drawing.cores() < 2, reason="needs fork and two cores")
def test_the_pool_draws_the_same_bytes_as_this_process(tmp_path, monkeypatch):
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path / "serial"))
    specs = [spec(k) for k in range(3)]
    serial = drawing.render_pngs(specs, jobs=1)
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path / "pool"))
    pooled = []
    real = drawing._draw_in_pool
    monkeypatch.setattr(drawing, "_draw_in_pool", lambda s, jobs: pooled.append(jobs) or real(s, jobs))
    assert drawing.render_pngs(specs, jobs=2) == serial
    assert pooled == [2]  # drawn by two worker processes
    assert len(set(serial)) == 3 and all(png.startswith(b"\x89PNG") for png in serial)
    for s, png in zip(specs, serial):  # every drawn figure is in the cache, under its key
        assert figcache.load(figcache.figure_key(s)) == png


def test_figures_in_the_cache_are_not_drawn_and_few_are_drawn_here(tmp_path, monkeypatch):
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path))
    specs = [spec(k) for k in range(4)]
    first = drawing.render_pngs(specs[:2], jobs=4)  # two misses: fewer than POOL_MIN, drawn here
    drawn = []
    monkeypatch.setattr(drawing, "_draw_in_pool", lambda s, jobs: pytest.fail("no pool for two figures"))
    monkeypatch.setattr(plots, "_draw_png", lambda s: drawn.append(s.name) or plots_png(s))
    again = drawing.render_pngs(specs[:3], jobs=4)
    assert again[:2] == first and drawn == ["f2"]


def plots_png(s):
    return b"\x89PNG drawn " + s.name.encode()


def test_a_figure_is_rasterised_once(monkeypatch):
    """Laid out at the screen's dpi and again at the PNG's, but its pixels drawn once: as many paths
    reach the Agg renderer as one canvas.draw() sends (a pass without rendering sends none)."""
    from matplotlib.backends.backend_agg import RendererAgg

    paths = []
    real = RendererAgg.draw_path
    monkeypatch.setattr(RendererAgg, "draw_path", lambda self, *a, **k: paths.append(1) or real(self, *a, **k))
    fig = plots.draw_figure(spec(0))  # laid out and rasterised once, at the screen's dpi
    plots._pyplot().close(fig)
    once = len(paths)
    paths.clear()
    png = plots._draw_png(spec(0))
    assert once > 0 and len(paths) == once and png.startswith(b"\x89PNG")


def _varied(k: int) -> FigureSpec:
    """Two panels whose content differs in everything a panel sets: scales, limits, legends, notes, lines."""
    t = np.linspace(0.01, 10, 60 + 40 * k)
    e = np.abs(np.sin(t)) * 10.0 ** (-3 * k) + 1e-14
    panels = [
        (Panel("a log error", "t (s)", "|e|", (Line(t, e, "ode23", "#0072B2", marker="o"),), yscale="log",
               xscale="log" if k == 2 else "linear", legend_outside=k == 0),
         Panel("nothing", "t (s)", "y", (), note="no data"),
         Panel("a long title that wraps over two lines of this panel, maybe more", "", "y (m)",
               (Line(t, 1e4 * np.cos(t), "ode45", "#D55E00", linestyle="--"),),
               reflines=(plots.RefLine(0.5, "threshold"),))),
    ][0]
    return FigureSpec(name=f"v{k}", caption="c", alt="a", panels=panels[k % 3:] + panels[:k % 3], columns=3,
                      legend=k == 1)


def test_a_kept_figure_draws_the_bytes_of_a_new_one(monkeypatch):
    """A figure drawn on the kept figure (resized, axes added or hidden, cleared of the last one's
    lines, legends, texts, log scales and limits) is byte for byte the PNG a new figure gives, in any order."""
    specs = [_varied(k) for k in range(3)] + [spec(0), spec(1)]
    fresh = []
    for s in specs:
        plots._REUSABLE.clear()
        fresh.append(plots._draw_png(s))
    assert len(set(fresh)) == len(specs)
    for order in ([0, 1, 2, 3, 4], [2, 1, 0, 4, 3], [1, 1, 0, 2, 2], [3, 0, 4, 1]):  # axes hidden, then added
        plots._REUSABLE.clear()
        for i in order:
            assert plots._draw_png(specs[i]) == fresh[i], (order, i)
    assert 1 <= len(plots._REUSABLE) <= plots._REUSABLE_MAX
    new = plots.draw_figure(specs[0], render=False)  # the public figure is never a kept one
    try:
        assert all(new is not kept for kept in plots._REUSABLE.values())
    finally:
        plots._pyplot().close(new)
