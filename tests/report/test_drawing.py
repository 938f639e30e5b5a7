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
