"""Drawing a report's figures: each from the figure cache or drawn once, the drawing spread over the cores.

The figures of a report are independent of each other, and drawing one (matplotlib's
artists, one measuring pass for the layout and the Agg rasteriser) is almost all of a cold
report's time. So
:func:`render_pngs` looks every figure up in the cache (:mod:`odelab.report.figcache`)
first, then draws the missing ones: in this process when there are few of them or one core,
otherwise by this process and workers forked from it once it has drawn the largest figure
(matplotlib imported, fonts, mathtext and the kept figure ready, so no worker makes them
again), one figure at a time per process, the largest first.
The PNG bytes are the same either way (tests check it), and each drawn figure is stored in
the cache by this process.

Nothing here prints; a figure that fails to draw raises its error here, as drawing it
serially would.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterable

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


def _draw_all(specs: list, jobs: int) -> Iterable[bytes]:
    """The PNGs of ``specs`` in order; drawn here one at a time (each cached by the caller as soon as it
    is drawn, so an interrupted report keeps what it drew), or in a pool."""
    from odelab.report import plots

    jobs = min(jobs, len(specs))
    if len(specs) < POOL_MIN or jobs < 2 or not _can_fork():
        return (plots._draw_png(spec) for spec in specs)
    return _draw_in_pool(specs, jobs)


def _can_fork() -> bool:
    import multiprocessing

    return "fork" in multiprocessing.get_all_start_methods()


def _size(spec) -> int:
    return sum(np.size(line.x) for panel in spec.panels for line in panel.lines) + 5000 * len(spec.panels)


def _take(order: list[int], counter) -> int | None:
    """The next figure to draw (an index into the specs), for whichever process asks first; None when none is left."""
    with counter.get_lock():
        k = counter.value
        counter.value = k + 1
    return order[k] if k < len(order) else None


def _worker(specs: list, order: list[int], counter, conn, parent: int) -> None:
    """In a forked worker: draw the figures it takes, sending each back as (index, PNG bytes or None)."""
    from odelab.run.lifeline import exit_with_parent
    from odelab.report import mplreuse, plots

    exit_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's: it stops (kills) the workers
    mplreuse.forked()
    try:
        while (i := _take(order, counter)) is not None:
            try:
                png = plots._draw_png(specs[i])
            except Exception:  # drawn again by the parent, which raises the error as drawing serially would
                png = None
            conn.send((i, png))
    finally:
        conn.close()


def _receive(conn, out: dict) -> None:
    """In the parent (a thread per worker): the worker's figures into ``out`` until it closes its end."""
    try:
        while True:
            i, png = conn.recv()
            if png is not None:
                out[i] = png
    except (EOFError, OSError):
        pass
    finally:
        conn.close()


def _draw_in_pool(specs: list, jobs: int) -> list[bytes]:
    """Drawn by this process and ``jobs - 1`` workers forked from it, the largest figure first.

    This process draws the smallest figure before forking, so the workers start warm: matplotlib
    imported, its fonts and mathtext parser loaded, the kept figure made (each worker paid
    that again before, 0.3-0.7 s of CPU). Then every process takes the
    next figure from a shared counter; the specs reach the workers by the fork, the PNGs come
    back through a pipe each, read by a thread so that no worker waits on this process. A
    figure a worker could not draw, or did not (a worker killed), is drawn here. The workers
    die with this process (:func:`odelab.run.lifeline.exit_with_parent`) and are
    joined before it returns."""
    import multiprocessing

    from odelab.report import plots

    order = sorted(range(len(specs)), key=lambda i: -_size(specs[i]))  # the largest first: no long tail
    first = order.pop()  # the smallest, drawn alone to warm matplotlib up for the workers
    pngs: dict[int, bytes] = {first: plots._draw_png(specs[first])}
    ctx = multiprocessing.get_context("fork")
    counter = ctx.Value("l", 0)
    procs, pipes = [], []
    try:
        for _ in range(jobs - 1):  # every worker forked before a reader thread starts
            receive, send = ctx.Pipe(duplex=False)
            proc = ctx.Process(target=_worker, args=(specs, order, counter, send, os.getpid()), daemon=True)
            proc.start()
            send.close()
            procs.append(proc)
            pipes.append(receive)
        readers = [threading.Thread(target=_receive, args=(pipe, pngs), daemon=True) for pipe in pipes]
        for reader in readers:
            reader.start()
        while (i := _take(order, counter)) is not None:
            pngs[i] = plots._draw_png(specs[i])
        for reader in readers:
            reader.join()
    finally:
        for proc in procs:
            if proc.is_alive() and not all(i in pngs for i in order):
                proc.kill()
            proc.join()
    return [pngs[i] if i in pngs else plots._draw_png(specs[i]) for i in range(len(specs))]
