"""Drawing a report's figures: from the cache, else drawn once, in a pool of processes when there are many."""

import sys

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


def test_ticks_worked_out_once_draw_the_bytes_matplotlib_draws(monkeypatch):
    """mplreuse.ticks_once (each axis's ticks once a pass) and the shared mathtext parser change no
    pixel: every figure drawn with them is the PNG matplotlib's own repeated work gives, and the
    ticks are worked out fewer times."""
    import contextlib

    from matplotlib.axis import Axis

    specs = [_varied(k) for k in range(3)] + [spec(0)]
    calls = []
    real = Axis._update_ticks
    monkeypatch.setattr(Axis, "_update_ticks", lambda self: calls.append(1) or real(self))
    plots._REUSABLE.clear()
    once = [plots._draw_png(s) for s in specs]
    fewer = len(calls)
    calls.clear()
    monkeypatch.setattr(plots, "ticks_once", lambda axes: contextlib.nullcontext())
    monkeypatch.setattr(plots, "renderer", lambda fig: fig.canvas.get_renderer())
    plots._REUSABLE.clear()
    assert [plots._draw_png(s) for s in specs] == once
    assert 0 < 2 * fewer <= len(calls)  # at most half the work
    plots._REUSABLE.clear()


def test_renderers_of_figures_of_other_sizes_share_one_mathtext_parser():
    from odelab.report import mplreuse

    small, tall = plots.draw_figure(spec(0), render=False), plots.draw_figure(_varied(1), render=False)
    try:
        assert small.get_figheight() != tall.get_figheight()
        assert mplreuse.renderer(small).mathtext_parser is mplreuse.renderer(tall).mathtext_parser
    finally:
        plots._pyplot().close(small)
        plots._pyplot().close(tall)


def _broken(k: int) -> FigureSpec:
    return FigureSpec(name=f"b{k}", caption="c", alt="a", panels=(
        Panel(title="bad", xlabel="t", ylabel="x", lines=(Line(np.arange(3.0), np.ones(3), "l", "not-a-colour"),)),))


@pytest.mark.skipif(not drawing._can_fork() or drawing.cores() < 2, reason="needs fork and two cores")
def test_a_figure_that_fails_in_a_worker_raises_here_as_drawn_serially(tmp_path, monkeypatch):
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path))
    specs = [spec(k) for k in range(4)] + [_broken(0)]
    with pytest.raises(ValueError) as serial:  # drawn one by one as they are taken (878ec8d)
        list(drawing._draw_all(specs, 1))
    with pytest.raises(ValueError) as pooled:
        list(drawing._draw_all(specs, 3))
    assert str(pooled.value) == str(serial.value) and "not-a-colour" in str(serial.value)
    assert not multiprocessing_children()


def multiprocessing_children() -> list:
    import multiprocessing

    return [p for p in multiprocessing.active_children() if p.is_alive()]


# A script drawing many figures of many panels with two processes: long enough to be killed mid-way.
_MANY = """
import numpy as np, sys
from odelab.report import drawing
from odelab.report.plots import FigureSpec, Line, Panel
t = np.linspace(0.01, 10, 400)
specs = [FigureSpec(name=f"m{k}", caption="c", alt="a", columns=3, panels=tuple(
    Panel(title=f"p{k}.{j}", xlabel="t (s)", ylabel="|e|", yscale="log",
          lines=(Line(t, np.abs(np.sin(t * (j + 1))) + 1e-9 * (k + 1), "ode45", "#D55E00"),)) for j in range(12)))
    for k in range(200)]
print("drawing", flush=True)
list(drawing._draw_all(specs, 2))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux") or not drawing._can_fork(), reason="reads /proc, forks")
@pytest.mark.parametrize("how", ["SIGKILL to the report", "Ctrl-C to its process group"])
def test_a_killed_report_leaves_no_drawing_worker(tmp_path, how):
    import os
    import signal
    import subprocess
    import time

    def children(pid):
        out = set()
        for entry in os.listdir("/proc"):
            try:
                stat = open(f"/proc/{entry}/stat").read()
            except OSError:
                continue
            if entry.isdigit() and int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.add(int(entry))
        return out

    def alive(pid):
        try:
            return open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"
        except OSError:
            return False

    env = {**os.environ, "ODELAB_CACHE_DIR": str(tmp_path)}
    proc = subprocess.Popen([sys.executable, "-c", _MANY], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    workers: set[int] = set()
    try:
        assert proc.stdout.readline().strip() == "drawing"
        end = time.monotonic() + 120
        while not workers and time.monotonic() < end and proc.poll() is None:
            workers = children(proc.pid)
            time.sleep(0.02)
        assert workers, "no worker was forked"
        if how.startswith("SIGKILL"):
            proc.send_signal(signal.SIGKILL)
        else:  # the parent stops and kills its workers; a worker ignores it (no traceback of its own)
            os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=60)
        if not how.startswith("SIGKILL"):
            err = proc.stderr.read()
            assert "KeyboardInterrupt" in err and "Process ForkProcess" not in err, err[-2000:]
        end = time.monotonic() + 30  # the kernel kills them at once; this only waits for a loaded machine
        while any(map(alive, workers)) and time.monotonic() < end:
            time.sleep(0.02)
        assert not [p for p in workers if alive(p)]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for p in workers:
            if alive(p):
                os.kill(p, signal.SIGKILL)
