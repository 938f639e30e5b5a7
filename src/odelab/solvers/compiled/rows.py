"""What a compiled loop hands back: its output rows, in arrays of their own size."""

from __future__ import annotations

import numpy as np

__all__ = ["exact_rows"]


def exact_rows(t_out: np.ndarray, y_out: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The loop's first ``count`` output rows, in arrays of their own size: the loop's buffers grow by
    doubling, so a view would keep up to twice the trajectory alive through the rest of the run (the
    error estimate, the store); the caller drops the buffers."""
    if count == t_out.size:
        return t_out, y_out
    return t_out[:count].copy(), y_out[:count].copy()
