"""What a compiled loop hands back: its output rows, in blocks while it runs, in arrays of their own size after.

Refine output (a two-element tspan) is written by the adaptive loop into blocks of
:data:`BLOCK_BYTES` (t and the states) that :func:`adaptive_rows` gives it one after another: the
loop returns when the next step's rows would not fit and is called again with a new block, so no
buffer is ever copied to grow, and the joined result (:func:`joined`) is built while the blocks
are given back, one at a time: the trajectory is never in memory twice. Given a ``sink`` (the run's
spool, :class:`odelab.store.spool.Spool`: ``append(t, y)`` and ``arrays()``), each full block goes to it
and the same block is filled again: the rows are on disk as the loop goes, and the run holds one block.
"""

from __future__ import annotations

import mmap

import numpy as np

__all__ = ["BLOCK_BYTES", "adaptive_rows", "exact_rows", "joined", "new_block"]

#: The size of one block of Refine output (t and the states), 2 MiB: 65,536 rows of three states.
BLOCK_BYTES = 1 << 21


def exact_rows(t_out: np.ndarray, y_out: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The loop's first ``count`` output rows, in arrays of their own size: the loop's buffers grow by
    doubling, so a view would keep up to twice the trajectory alive through the rest of the run (the
    error estimate, the store); the caller drops the buffers."""
    if count == t_out.size:
        return t_out, y_out
    return t_out[:count].copy(), y_out[:count].copy()


def block_rows(n: int, refine: int) -> int:
    """Rows in a block of Refine output for ``n`` states: :data:`BLOCK_BYTES`' worth, room for a step at least."""
    return max(refine + 1, BLOCK_BYTES // (8 * (n + 1)))


def new_block(rows: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Empty arrays for ``rows`` output rows of ``n`` states, in memory mapped for them alone: given back to
    the system as soon as they are dropped (a block freed by malloc can stay in the process's heap)."""
    t = np.frombuffer(mmap.mmap(-1, 8 * rows), dtype=float)
    y = np.frombuffer(mmap.mmap(-1, 8 * max(rows * n, 1)), dtype=float)[:rows * n].reshape(rows, n)
    return t, y


def joined(blocks: list, n: int) -> tuple[np.ndarray, np.ndarray]:
    """One ``t`` and one ``y`` from ``blocks``, a list of ``(t, y, count)`` that it empties: each block is
    dropped as soon as its rows are copied, so the trajectory is in memory about once."""
    if len(blocks) == 1:
        return exact_rows(*blocks.pop())
    total = sum(count for _, _, count in blocks)
    t = np.empty(total)
    y = np.empty((total, n))
    row = 0
    while blocks:
        bt, by, count = blocks.pop(0)
        t[row:row + count] = bt[:count]
        y[row:row + count] = by[:count]
        row += count
        del bt, by
    return t, y


def adaptive_rows(loop, args: tuple, tail: tuple, n: int, nevents: int, rows: int, refine_output: bool,
                  sink=None):
    """Run the adaptive ``loop`` (kernels.py.txt's ``_adaptive``) with ``args`` before its output arguments
    and ``tail`` after them (the events function and its data), block after block with Refine output
    (``rows`` rows a block), else in one block of ``rows``. Returns ``(t, y, nsteps, nfailed, nfevals,
    status, t_stop, h_stop, te, ye, ie)``, the rows joined; with a ``sink``, once a block has filled, every
    block is appended to it and the rows are the sink's ``arrays()`` (a run that never fills a block
    leaves the sink untouched)."""
    state = np.empty(3 + 3 * n + nevents)
    counts = np.zeros(6, dtype=np.int64)
    te = np.empty(4 * nevents + 4)
    ye = np.empty((te.size, n))
    ie = np.empty(te.size, dtype=np.int64)
    t_out, y_out = new_block(rows, n) if refine_output else (np.empty(rows), np.empty((rows, n)))
    blocks = []
    while True:
        (t_out, y_out, count, nsteps, nfailed, nfevals, status, t_stop, h_stop, te, ye, ie, nev,
         full) = loop(*args, t_out, y_out, state, counts, te, ye, ie, *tail)
        if full and sink is not None:  # to disk, and the same block filled again
            sink.append(t_out[:count], y_out[:count])
            continue
        blocks.append((t_out, y_out, count))
        if not full:
            break
        t_out, y_out = new_block(rows, n)
    del t_out, y_out
    if sink is not None and sink.rows:
        (bt, by, count), = blocks
        sink.append(bt[:count], by[:count])
        del bt, by
        blocks.clear()
        t, y = sink.arrays()
    else:
        t, y = joined(blocks, n)
    return t, y, nsteps, nfailed, nfevals, status, t_stop, h_stop, te[:nev].copy(), ye[:nev].copy(), ie[:nev].copy()
