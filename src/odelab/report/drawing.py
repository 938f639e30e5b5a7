"""Drawing a report's figures: each from the figure cache or drawn once, the drawing spread over the cores.

The figures of a report are independent of each other, and drawing one (matplotlib's
artists, one measuring pass for the layout and the Agg rasteriser) is almost all of a cold
report's time. So
:func:`render_pngs` looks every figure up in the cache (:mod:`odelab.report.figcache`)
first, then draws the missing ones: in this process when there are few of them or one core,
otherwise in a pool of processes forked from this one (matplotlib imported once, before the
fork, so no worker imports it again), one figure at a time per worker, the largest first.
The PNG bytes are the same either way (tests check it), and each drawn figure is stored in
the cache by this process.

Nothing here prints; a figure that fails to draw raises its error here, as drawing it
serially would.
"""

from __future__ import annotations

import os

import numpy as np

__all__ = ["POOL_MIN", "render_pngs"]

#: Figures to draw (cache misses) from which a pool of processes draws them: below this, the
#: fork and the transfer of the data cost more than the second core saves.
POOL_MIN = 3


def render_pngs(specs: list, *, jobs: int | None = None) -> list[bytes]:
    """The PNG bytes of every :class:`~odelab.report.plots.FigureSpec` in ``specs``, in order.

    ``jobs``: figures drawn at once (default: :func:`cores`; 1 draws them in this process)."""
    from odelab.report import figcache

    keys = [figcache.figure_key(spec) for spec in specs]
    pngs: list[bytes | None] = [figcache.load(key) for key in keys]
    missing = [i for i, png in enumerate(pngs) if png is None]
    for i, png in zip(missing, _draw_all([specs[i] for i in missing], jobs or cores())):
        figcache.store(keys[i], png)
        pngs[i] = png
    return pngs


def cores() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def _draw_all(specs: list, jobs: int) -> list[bytes]:
    from odelab.report import plots

    jobs = min(jobs, len(specs))
    if len(specs) < POOL_MIN or jobs < 2 or not _can_fork():
        return [plots._draw_png(spec) for spec in specs]
    from concurrent.futures.process import BrokenProcessPool

    try:
        return _draw_in_pool(specs, jobs)
    except BrokenProcessPool:  # a worker killed (out of memory...): draw them here instead
        return [plots._draw_png(spec) for spec in specs]


def _can_fork() -> bool:
    import multiprocessing

    return "fork" in multiprocessing.get_all_start_methods()


def _draw_one(spec) -> bytes:
    """In a worker: ``plots._draw_png`` looked up when called (a pool's pickled task names this function)."""
    from odelab.report import plots

    return plots._draw_png(spec)


def _size(spec) -> int:
    return sum(np.size(line.x) for panel in spec.panels for line in panel.lines) + 5000 * len(spec.panels)


def _draw_in_pool(specs: list, jobs: int) -> list[bytes]:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from odelab.report import plots

    plots._matplotlib()  # imported before the fork: the workers inherit matplotlib and its font cache
    order = sorted(range(len(specs)), key=lambda i: -_size(specs[i]))  # the largest first: no long tail
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("fork"))
    try:
        futures = {i: pool.submit(_draw_one, specs[i]) for i in order}
        return [futures[i].result() for i in range(len(specs))]
    finally:
        pool.shutdown(wait=True, cancel_futures=True)

