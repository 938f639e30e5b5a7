"""A system's inputs: one signal per input from what a caller gives, and the values around each
input jump for plots."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from odelab.exceptions import InputError
from odelab.signals.base import Constant, Signal, as_signal


def as_signals(u: Any, inputs: Sequence[str]) -> tuple[Signal, ...]:
    """One signal per input of a system whose inputs are named ``inputs``.

    ``u`` may be None (every input is 0), one signal / number / callable (a single-input
    system), a sequence with one per input, or a mapping from input names to signals
    (the inputs it leaves out are 0).
    """
    inputs = tuple(inputs)
    m = len(inputs)
    listed = ", ".join(inputs)
    if u is None:
        return tuple(Constant(0.0) for _ in inputs)
    if m == 0:
        raise InputError(f"The system has no inputs, so `u` must be None; got {u!r}.", key="u")
    if isinstance(u, Mapping):
        unknown = [key for key in u if key not in inputs]
        if unknown:
            raise InputError(
                f"`u` names {unknown[0]!r}, which is not an input of the system; its inputs "
                f"are: {listed}.",
                key="u",
            )
        return tuple(
            as_signal(u[name], name=f"u[{name!r}]") if name in u else Constant(0.0) for name in inputs
        )
    if isinstance(u, (Sequence, np.ndarray)) and not isinstance(u, str):
        items = list(u)
        if len(items) != m:
            raise InputError(
                f"`u` has {len(items)} signal{'' if len(items) == 1 else 's'} but the system has "
                f"{m} input{'' if m == 1 else 's'} ({listed}): give one signal per input.",
                key="u",
            )
        return tuple(as_signal(item, name=f"u[{i}]") for i, item in enumerate(items))
    if m != 1:
        raise InputError(
            f"The system has {m} inputs ({listed}), so `u` must be a sequence of {m} signals "
            "(one per input) or a mapping from input names to signals; got one signal.",
            key="u",
        )
    return (as_signal(u, name="u"),)


#: At most this many jumps are recorded by :func:`input_jumps` (beyond, a plot of the sampled
#: values is as good: the jumps are closer together than a figure's pixels).
MAX_RECORDED_JUMPS = 2000


def input_jumps(signals: Sequence[Signal], t0: float, tf: float) -> dict[str, list] | None:
    """The inputs' breakpoints strictly inside the span (where u or u' may jump; increasing) with
    every input's value just before and at each (its left limit, one ulp earlier, and its value),
    so that a plot against t draws a step as a step however the output rows fall (at a kink both
    points lie on the curve). None without breakpoints or with more than
    :data:`MAX_RECORDED_JUMPS` of them."""
    lo, hi = min(t0, tf), max(t0, tf)
    cuts = np.unique(np.concatenate([np.empty(0), *(s.breakpoints(lo, hi) for s in signals)]))
    if not cuts.size or cuts.size > MAX_RECORDED_JUMPS:
        return None
    before = [[float(s(float(np.nextafter(c, -math.inf)))) for s in signals] for c in cuts]
    at = [[float(s(float(c))) for s in signals] for c in cuts]
    return {"t": cuts.tolist(), "before": before, "after": at}
