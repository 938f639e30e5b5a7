"""Sample times of discrete blocks and the instants they are hit.

A discrete block's ``sample_time`` is ``Ts`` or ``[Ts, offset]`` (seconds, Simulink's
notation): it is hit at ``t = k*Ts + offset`` for the whole numbers k. The hits inside a span
are counted, never accumulated: each is ``k*Ts + offset`` computed afresh from its k, so the
hundredth hit of ``Ts = 0.1`` is ``100*0.1``, not a sum of a hundred 0.1s. Hits of several
rates that fall on the same instant up to round-off (``3*0.1`` and ``1*0.3``) are one
instant, so the blocks of both rates update together, as in Simulink's multirate diagrams.
"""

from __future__ import annotations

import math

import numpy as np

from odelab.systems.diagram.base import BlockError

__all__ = ["SampleTime", "sample_time", "hits"]


class SampleTime(tuple):
    """``(Ts, offset)`` with ``Ts > 0`` and ``0 <= offset < Ts``."""

    @property
    def period(self) -> float:
        return self[0]

    @property
    def offset(self) -> float:
        return self[1]

    def hits(self, t0: float, tf: float) -> np.ndarray:
        """The hit times k*Ts + offset in [t0, tf] (k counted, not accumulated)."""
        Ts, off = self
        lo, hi = min(t0, tf), max(t0, tf)
        k0 = math.ceil((lo - off) / Ts)
        k1 = math.floor((hi - off) / Ts)
        if k0 > k1 + 1:
            return np.empty(0)
        k = np.arange(k0 - 1, k1 + 2)
        times = k * Ts + off
        return times[(times >= lo) & (times <= hi)]

    def __str__(self) -> str:
        return f"{self[0]:g}" if self[1] == 0 else f"[{self[0]:g}, {self[1]:g}]"


def sample_time(value, key: str = "sample_time") -> SampleTime:
    """Check a ``sample_time`` value: a positive number, or ``[Ts, offset]`` with 0 <= offset < Ts."""
    vals = list(value) if isinstance(value, (list, tuple, np.ndarray)) else [value]
    try:
        nums = [float(v) for v in vals]
    except (TypeError, ValueError):
        nums = []
    if len(nums) not in (1, 2) or not all(math.isfinite(v) for v in nums) or nums[0] <= 0:
        raise BlockError(f"`{key}` must be a sample time in seconds, Ts > 0, or [Ts, offset]; got {value!r}.",
                         key=key)
    Ts, off = nums[0], (nums[1] if len(nums) == 2 else 0.0)
    if not 0 <= off < Ts:
        raise BlockError(f"`{key}` is [{Ts:g}, {off:g}]: the offset must be at least 0 and below Ts.", key=key)
    return SampleTime((Ts, off))


def hits(rates: dict[str, SampleTime], t0: float, tf: float) -> tuple[np.ndarray, list[list[str]]]:
    """Every instant in [t0, tf] some block is hit, in the direction t0 -> tf, and which blocks.

    Instants of different rates closer than 64 ulps of the span's scale are merged (the first
    of them is kept)."""
    if not rates:
        return np.empty(0), []
    pairs = sorted((float(t), name) for name, st in rates.items() for t in st.hits(t0, tf))
    scale = max(abs(t0), abs(tf), 1e-300)
    tol = 64 * math.ulp(scale)
    times: list[float] = []
    who: list[list[str]] = []
    for t, name in pairs:
        if times and t - times[-1] <= tol:
            if name not in who[-1]:
                who[-1].append(name)
        else:
            times.append(t)
            who.append([name])
    out = np.array(times)
    if tf < t0:
        return out[::-1], who[::-1]
    return out, who
