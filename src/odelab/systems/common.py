"""Checks shared by the system functions (simulate, exact LTI responses, linearisation)."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from odelab.exceptions import InputError

__all__ = ["as_initial_state"]


def as_initial_state(x0: Any, nx: int, states: Sequence[str] | None = None) -> np.ndarray:
    """An initial state: ``nx`` finite numbers, one per state (named in the message)."""
    try:
        x0 = np.array(x0, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"`x0` must be an array of {nx} numbers; got {x0!r}.", key="x0") from None
    if x0.size != nx:
        names = f" ({', '.join(states)})" if states else ""
        raise InputError(
            f"`x0` has {x0.size} entr{'y' if x0.size == 1 else 'ies'} but the system has {nx} "
            f"state{'' if nx == 1 else 's'}{names}: give one initial value per state.",
            key="x0",
        )
    if not np.all(np.isfinite(x0)):
        raise InputError(f"`x0` must be finite; got {x0.tolist()!r}.", key="x0")
    return x0
