"""A global error estimate from a second solve at tighter tolerances, and when to distrust a result.

The classical check of tolerance proportionality (Shampine, *Numerical Solution of Ordinary
Differential Equations*, 1994, Sec. 1.4 and 6.4; the check MATLAB's documentation suggests by
hand: "solve again with tighter tolerances and compare"): a good code's global error is roughly
proportional to its tolerance, so a second solve with ``RelTol`` and ``AbsTol`` divided by
:data:`ESTIMATE_FACTOR` (same method, output at the same points) has about a tenth of the first
one's error, and their difference measures the first one's:

    e(t) ~ |y(t) - y_tight(t)| * F / (F - 1),        F = ESTIMATE_FACTOR (10).

(A fixed-step method halves ``h`` instead: ``F = 2^p`` for its order p.) Per quantity this gives
the estimated maximum error over the output points and the estimated correct digits
``-log10(rel)``, ``rel`` by the error headlines' own rule (:data:`odelab.analysis.errors.HEADLINE_RULE`,
the tight solve in place of the reference). It is an estimate, not a bound: it fails when both
solves share an error that tolerances do not control (an instability both fall into the same
way, a feature both step over, round-off at tolerances near eps).

**When not to trust the result.** A result is ``unreliable`` (shown ``ok?``) when, for a state,

* the two solves disagree at some output point by more than :data:`DISAGREE_UNITS` times the
  accuracy the user asked for there, ``RelTol |y| + AbsTol`` (the solver's own terms, pointwise:
  a comparison relative to the peak cannot see a component that ends near 1e-22 while the user's
  ``AbsTol`` 1.7e-24 asked for it, Bari's E5), or
* the estimate leaves fewer than :data:`MIN_DIGITS` correct digit (for a state whose scale the
  tolerances control: its largest value above ten times its ``AbsTol``).

Global errors of tens of tolerance units are normal (an error per step of one unit accumulates
over the span), so the factor is a thousand. A suspect point is cleared when a shift in time of
at most :data:`PHASE_SHIFT` ``RelTol |t - t0|`` explains it (either curve, shifted, passes within
the same distance of the other's value): a phase error (van der Pol's relaxation jumps 1.35
``RelTol t`` earlier or later at ten times tighter tolerances, a trapezoidal oscillator's zero
crossings 19 ``RelTol t``), not a wrong value. The note then gives the largest shift one of them
needed. All points are checked a block at a time, whatever the run's length: a window's extent
comes from a table of the curve's extrema over blocks (:class:`_RangeExtrema`), not a pass over it.

Pure: arrays in, a frozen :class:`ErrorEstimate` out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from odelab.analysis.errors import summarize

__all__ = ["ESTIMATE_FACTOR", "DISAGREE_UNITS", "MIN_DIGITS", "PHASE_SHIFT", "MAX_DIGITS", "QuantityEstimate", "ErrorEstimate",
           "compare_solves", "digits_of"]

#: RelTol and AbsTol are divided by this in the second solve (global error ~ tolerance).
ESTIMATE_FACTOR = 10.0
#: Two solves that differ by more than this many times RelTol |y| + AbsTol at a point: unreliable.
DISAGREE_UNITS = 1000.0
#: An estimate of fewer correct digits than this (for a quantity the tolerances control): unreliable.
MIN_DIGITS = 1.0
#: A difference that a shift in time of this many RelTol |t - t0| explains is a phase error, not a wrong value.
PHASE_SHIFT = 100.0
#: Digits are not claimed beyond double precision's.
MAX_DIGITS = 15.9


def digits_of(rel: float | None) -> float | None:
    """Correct digits of a relative error: ``-log10(rel)`` within ``[0, MAX_DIGITS]`` (None if undefined)."""
    if rel is None or not math.isfinite(rel) and not math.isinf(rel):
        return None
    if rel <= 0:
        return MAX_DIGITS
    return float(min(MAX_DIGITS, max(0.0, -math.log10(rel))))


@dataclass(frozen=True)
class QuantityEstimate:
    """The estimate of one quantity's error."""

    name: str
    max_abs: float  # estimated max |error| over the output points compared
    t_max_abs: float
    rel: float | None  # the headline relative error (HEADLINE_RULE), estimated
    basis: str  # "pointwise" or "peak", as the error headlines
    digits: float | None  # estimated correct digits, -log10(rel)
    units: float | None = None  # max |difference| / (RelTol |y| + AbsTol) over the points (states)
    t_units: float | None = None
    value: float | None = None  # the run's value where ``units`` is largest
    tight: float | None = None  # the tighter solve's value there
    controlled: bool = True  # its scale is above ten times its AbsTol (the digits rule applies)
    flagged: bool = False  # the two solves disagree beyond the tolerances here: no digits are claimed
    phase_shift: float | None = None  # differences beyond the tolerances, all explained by shifts in time up to this
    t_phase_shift: float | None = None

    def as_dict(self) -> dict:
        return {"max_abs": self.max_abs, "t_max_abs": self.t_max_abs, "rel_error": self.rel, "rel_basis": self.basis,
                "digits": self.digits, "units": self.units, "t_units": self.t_units, "value": self.value,
                "tight": self.tight, "flagged": self.flagged,
                **({} if self.phase_shift is None else {"phase_shift": self.phase_shift,
                                                         "t_phase_shift": self.t_phase_shift})}


@dataclass(frozen=True)
class ErrorEstimate:
    """The estimate of a result's error from a tighter solve, and the verdict on the result."""

    factor: float  # how much tighter the second solve was (F)
    quantities: dict[str, QuantityEstimate]
    verdict: str  # "ok" or "unreliable"
    reasons: tuple[str, ...] = ()  # why unreliable, one sentence per quantity (the warning)
    points: int = 0  # output points compared
    notes: tuple[str, ...] = field(default=())

    @property
    def unreliable(self) -> bool:
        return self.verdict == "unreliable"

    def as_dict(self) -> dict:
        return {"factor": self.factor, "verdict": self.verdict, "reasons": list(self.reasons), "points": self.points,
                "quantities": {n: q.as_dict() for n, q in self.quantities.items()}, "notes": list(self.notes)}


def compare_solves(t: np.ndarray, run: dict[str, np.ndarray], tight: dict[str, np.ndarray], *, factor: float,
                   proportion: float | None = None, rtol: float | None = None,
                   atol: dict[str, float] | None = None, advice: str = "") -> ErrorEstimate:
    """Estimate the run's errors from a tighter solve at the same output times ``t``.

    ``run`` and ``tight`` map each quantity to its values; ``proportion`` is how much smaller the
    tight solve's error is (default ``factor``); ``rtol`` and ``atol`` (per state; outputs have
    none) are the run's tolerances, for the verdict; ``advice`` is what to try (the last of the
    reasons)."""
    proportion = factor if proportion is None else proportion
    scale_up = proportion / (proportion - 1.0)
    atol = atol or {}
    t = np.asarray(t, dtype=float)
    quantities: dict[str, QuantityEstimate] = {}
    reasons: list[str] = []
    notes: list[str] = []
    for name, values in run.items():
        if name not in tight:
            continue
        values = np.asarray(values, dtype=float)
        other = np.asarray(tight[name], dtype=float)
        if values.size == 0:
            continue
        s = summarize(name, t, values, other)
        rel = None if s.headline is None else s.headline * scale_up
        q = QuantityEstimate(name, s.max_abs * scale_up, s.t_max_abs, rel, s.basis, digits_of(rel))
        if rtol is not None and name in atol:
            q, reason, note = _judge(q, t, values, other, s, rtol, float(atol[name]), factor, scale_up)
            if reason:
                reasons.append(reason)
            if note:
                notes.append(note)
        quantities[name] = q
    if reasons and advice:
        reasons.append(advice)
    return ErrorEstimate(factor, quantities, "unreliable" if reasons else "ok", tuple(reasons), int(np.size(t)),
                         tuple(notes))


def _judge(q: QuantityEstimate, t, values, other, s, rtol: float, atol: float, factor: float, scale_up: float):
    """The verdict on one state: ``(estimate with its worst disagreement, reason or "", note or "")``.

    A point is suspect when the two solves differ there by more than :data:`DISAGREE_UNITS` of
    ``RelTol |y| + AbsTol``, or by more than a tenth of the quantity (the headline rule's
    denominator: its peak, or its value): fewer than one digit. A suspect point is cleared when a
    shift in time of at most :data:`PHASE_SHIFT` ``RelTol |t - t0|`` explains it (the tighter
    solve's curve passes within the same distance nearby): a fast transition a little earlier or
    later is a phase error, which tolerances proportionally control, not a wrong value."""
    peak_tenth = q.basis == "peak" or not math.isfinite(s.scale)
    controlled = bool(s.scale > 10 * atol) if math.isfinite(s.scale) else True
    tables = _Tables(t, values, other)
    top = top_units = None  # the largest units (the first of them)
    worst = worst_units = None  # the suspect point no shift explains: the first, then the first of the most units
    shift = shift_at = None  # the largest shift a cleared point needs (while every suspect point so far is cleared)
    for lo in range(0, t.size, _CHUNK):
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            o, dv = other[lo:lo + _CHUNK], values[lo:lo + _CHUNK]
            allowed = rtol * np.abs(o) + atol
            diff = np.abs(dv - o)
            units = diff / allowed
            units = np.where(np.isfinite(units), units, np.inf)
            if peak_tenth:
                tenth = 0.1 * s.scale / scale_up if math.isfinite(s.scale) else np.inf
            else:
                tenth = 0.1 * np.abs(o) / scale_up
            digit_bad = (diff > tenth) if controlled else np.zeros(diff.shape, dtype=bool)
        k = int(np.argmax(units))
        if top is None or units[k] > top_units:
            top, top_units = lo + k, units[k]
        local = np.flatnonzero((units > DISAGREE_UNITS) | digit_bad)
        if local.size == 0:
            continue
        suspect = lo + local
        width = PHASE_SHIFT * rtol * np.abs(t[suspect] - t[0])
        # either curve shifted onto the other: each is sampled densely only where it moves fast itself
        ahead, behind = tables.distances(suspect, width)
        d = np.where(behind < ahead, behind, ahead)  # min(ahead, behind), as Python's min (ahead where NaN)
        tenth_s = tenth if np.ndim(tenth) == 0 else tenth[local]
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            u = np.where(allowed[local] > 0, d / allowed[local], np.inf)
            rel_left = d / tenth_s if controlled else np.zeros(d.shape)
        bad = (u > DISAGREE_UNITS) | (rel_left > 1)
        if bad.any():  # the first not explained, replaced by each later one of more units (first of the largest)
            if worst is None:
                k = int(np.argmax(bad))
                worst, worst_units = int(suspect[k]), float(u[k])
            if not math.isnan(worst_units):
                more = np.where(bad & ~np.isnan(u), u, -np.inf)
                k = int(np.argmax(more))
                if more[k] > worst_units:
                    worst, worst_units = int(suspect[k]), float(u[k])
        elif worst is None:  # all cleared so far: the shift each needs (the shorter of either curve onto the other)
            band = DISAGREE_UNITS * allowed[local]
            if controlled:
                band = np.minimum(band, tenth_s)
            needed = np.minimum(np.minimum(*tables.needed(suspect, band)), width)  # each cleared within its window
            needed = np.where(np.isnan(needed), -np.inf, needed)
            k = int(np.argmax(needed))
            if shift is None or needed[k] > shift:
                shift, shift_at = float(needed[k]), int(suspect[k])
    i = top
    q = replace(q, units=float(top_units), t_units=float(t[i]), value=float(values[i]), tight=float(other[i]),
                controlled=controlled)
    if worst is None and shift is None:
        return q, "", ""
    name = q.name
    if worst is not None:
        j = worst
        # two solves that disagree beyond the tolerances do not measure each other's error: no digits claimed
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):  # as in the pass above
            units_j = np.abs(values[j] - other[j]) / (rtol * np.abs(other[j]) + atol)
        units_j = float(units_j) if np.isfinite(units_j) else math.inf
        q = replace(q, units=units_j, t_units=float(t[j]), value=float(values[j]), tight=float(other[j]),
                    digits=0.0, flagged=True)
        if worst_units > DISAGREE_UNITS:
            reason = (f"{name}: the run and a solve at tolerances {factor:g} times tighter disagree by "
                      f"{_units_text(units_j)} times the accuracy asked for (RelTol |{name}| + AbsTol) at "
                      f"t = {t[j]:.6g}: {name} = {values[j]:.6g} against {other[j]:.6g}")
        else:
            reason = (f"{name}: the estimated error is {q.max_abs:.3g} (at t = {q.t_max_abs:.6g}), fewer than "
                      f"{MIN_DIGITS:g} correct digit relative to {name}'s {'peak' if q.basis == 'peak' else 'values'} "
                      f"({name} = {values[j]:.6g} against {other[j]:.6g} at t = {t[j]:.6g})")
        return q, reason, ""
    # every suspect point cleared: the note gives the largest shift one of them needed, and where
    q = replace(q, phase_shift=shift, t_phase_shift=float(t[shift_at]))
    note = (f"{name}: its largest differences (estimated error {q.max_abs:.3g} at t = {q.t_max_abs:.6g}) are where "
            f"{name} moves fast, and a shift in time of at most {shift:.3g} explains them (at t = {t[shift_at]:.6g}): "
            "a phase error (a transition a little earlier or later), not a wrong value")
    return q, "", note


#: Points a block of the range-extremum table covers, and suspect points handled at a time (memory bound).
_BLOCK, _CHUNK = 64, 4096


def _shift_distances(t: np.ndarray, values: np.ndarray, tight: np.ndarray, points: np.ndarray,
                     width: np.ndarray, table: _RangeExtrema | None = None) -> np.ndarray:
    """For each point ``i`` of ``points``: the distance from the run's value there to the tighter
    solve's curve over ``[t_i - width, t_i + width]`` (linear between its points, its non-finite
    values left out): zero when a shift in time of at most ``width`` explains the difference.

    The curve's extent over a window is the extent of its points inside the window and of its
    values at the window's two ends (``np.interp``); the points inside are a range of indices,
    whose finite minimum and maximum come from :class:`_RangeExtrema` (a table of blocks), not
    from a pass over the window: each point costs the same whatever the window's width."""
    forward = t[-1] >= t[0]
    rt, rtight = (t, tight) if forward else (t[::-1], tight[::-1])
    table = table or _RangeExtrema(rtight)
    out = np.empty(points.size)
    for lo in range(0, points.size, _CHUNK):
        i, w = points[lo:lo + _CHUNK], width[lo:lo + _CHUNK]
        v = values[i]
        a, b = t[i] - w, t[i] + w
        j0, j1 = np.searchsorted(rt, a, side="left"), np.searchsorted(rt, b, side="right")
        least, most = table.extrema(j0, j1)
        for edge in (np.interp(a, rt, rtight), np.interp(b, rt, rtight)):
            finite = np.isfinite(edge)
            least = np.where(finite & (edge < least), edge, least)
            most = np.where(finite & (edge > most), edge, most)
        with np.errstate(invalid="ignore"):
            d = least - v  # max(least - v, v - most, 0), as Python's max; inf where no finite value is near
            d = np.where(v - most > d, v - most, d)
            d = np.where(0.0 > d, 0.0, d)
            # a run's value that is not finite, or the first point (no window): the plain difference
            plain = np.where(np.isfinite(v), np.abs(v - tight[i]), np.inf)
        out[lo:lo + _CHUNK] = np.where(np.isfinite(v) & (w > 0), d, plain)
    return out


class _Tables:
    """The range-extremum tables of both curves, made once for all the points of a comparison."""

    def __init__(self, t: np.ndarray, values: np.ndarray, other: np.ndarray):
        self.t, self.values, self.other = t, values, other
        self._made: dict = {}

    def _table(self, which: str, reverse: bool) -> _RangeExtrema:
        key = (which, reverse)
        if key not in self._made:
            x = self.values if which == "values" else self.other
            self._made[key] = _RangeExtrema(x[::-1] if reverse else x)
        return self._made[key]

    def distances(self, points: np.ndarray, width: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The run's values to the tighter solve's curve, and the tighter solve's to the run's."""
        t, reverse = self.t, bool(self.t[-1] < self.t[0])
        return (_shift_distances(t, self.values, self.other, points, width, self._table("other", reverse)),
                _shift_distances(t, self.other, self.values, points, width, self._table("values", reverse)))

    def needed(self, points: np.ndarray, band: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The shift each point needs: the tighter solve's curve onto the run's value, and the other way."""
        t = self.t
        return (_shifts_needed(t, self.values, self.other, points, band, self._table("other", False)),
                _shifts_needed(t, self.other, self.values, points, band, self._table("values", False)))


class _RangeExtrema:
    """The finite minimum and maximum of ``x[j0:j1]`` for many ranges at once (+inf and -inf where a
    range has no finite value): whole blocks of :data:`_BLOCK` points from a sparse table of the
    blocks' extrema (Bentley's range-minimum query), the partial blocks at either end directly."""

    def __init__(self, x: np.ndarray):
        self.finite = finite = bool(np.isfinite(x).all())
        self.low = x if finite else np.where(np.isfinite(x), x, np.inf)
        self.high = x if finite else np.where(np.isfinite(x), x, -np.inf)
        n = x.size
        padded = -(-n // _BLOCK) * _BLOCK
        blocks_low = np.full(padded, np.inf)
        blocks_low[:n] = self.low
        blocks_high = np.full(padded, -np.inf)
        blocks_high[:n] = self.high
        self.min_levels = [blocks_low.reshape(-1, _BLOCK).min(axis=1)]
        self.max_levels = [blocks_high.reshape(-1, _BLOCK).max(axis=1)]
        step = 1
        while 2 * step <= self.min_levels[0].size:  # level k: blocks [b, b + 2^k)
            lo, hi = self.min_levels[-1], self.max_levels[-1]
            self.min_levels.append(np.minimum(lo[:-step], lo[step:]))
            self.max_levels.append(np.maximum(hi[:-step], hi[step:]))
            step *= 2

    def extrema(self, j0: np.ndarray, j1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        first, last = -(-j0 // _BLOCK), j1 // _BLOCK  # the whole blocks [first, last)
        head_end = np.minimum(j1, first * _BLOCK)
        tail_start = np.maximum(head_end, last * _BLOCK)
        least, most = self._part(j0, head_end)
        tl, tm = self._part(tail_start, j1)
        least, most = np.minimum(least, tl), np.maximum(most, tm)
        whole = last > first
        if whole.any():
            b0, b1 = first[whole], last[whole]
            k = (np.frexp(b1 - b0)[1] - 1).astype(np.intp)  # floor(log2), in integers: 2^k <= b1 - b0 < 2^(k+1)
            span = np.left_shift(1, k)
            for level in np.unique(k):
                at = k == level
                lo, hi = self.min_levels[level], self.max_levels[level]
                m = np.minimum(lo[b0[at]], lo[b1[at] - span[at]])
                x = np.maximum(hi[b0[at]], hi[b1[at] - span[at]])
                where = np.flatnonzero(whole)[at]
                least[where] = np.minimum(least[where], m)
                most[where] = np.maximum(most[where], x)
        return least, most

    def first_beyond(self, start: np.ndarray, edge: np.ndarray, down: bool, forward: bool) -> np.ndarray:
        """For each ``start``: the nearest index after it (``forward``) or before it whose value is at
        or below ``edge`` (``down``) or at or above it; -1 where there is none."""
        x = self.low if down else self.high
        levels = self.min_levels if down else self.max_levels
        beyond = (lambda a, e: a <= e) if down else (lambda a, e: a >= e)
        n, nb = x.size, self.min_levels[0].size
        found = np.full(start.size, -1, dtype=np.intp)
        # the rest of the start's own block
        block = start // _BLOCK
        steps = np.arange(1, _BLOCK) if forward else -np.arange(1, _BLOCK)
        idx = start[:, None] + steps
        inside = (idx // _BLOCK == block[:, None]) & (idx >= 0) & (idx < n)
        hit = inside & beyond(x[np.clip(idx, 0, n - 1)], edge[:, None])
        some = hit.any(axis=1)
        found[some] = idx[some, np.argmax(hit[some], axis=1)]
        # whole blocks: skip those with no such value, 2^k blocks at a time
        rest = np.flatnonzero(~some)
        b = block[rest] + 1 if forward else block[rest]  # forward: the first block to look at; backward: one past
        e = edge[rest]
        for level in range(len(levels) - 1, -1, -1):
            span, table = 1 << level, levels[level]
            if forward:
                can = b + span <= nb
                skip = can & ~beyond(table[np.minimum(b, table.size - 1)], e)
                b = np.where(skip, b + span, b)
            else:
                can = b - span >= 0
                skip = can & ~beyond(table[np.clip(b - span, 0, table.size - 1)], e)
                b = np.where(skip, b - span, b)
        inner = (b < nb) if forward else (b > 0)
        rest, b, e = rest[inner], b[inner], e[inner]
        base = (b if forward else b - 1) * _BLOCK
        idx = base[:, None] + np.arange(_BLOCK)
        hit = (idx < n) & beyond(x[np.minimum(idx, n - 1)], e[:, None])
        first = np.argmax(hit, axis=1) if forward else _BLOCK - 1 - np.argmax(hit[:, ::-1], axis=1)
        found[rest] = base + first
        return found

    def _part(self, start: np.ndarray, stop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Extrema over ranges shorter than a block."""
        idx = start[:, None] + np.arange(_BLOCK)
        inside = idx < stop[:, None]
        idx = np.minimum(idx, self.low.size - 1)
        return (np.where(inside, self.low[idx], np.inf).min(axis=1, initial=np.inf),
                np.where(inside, self.high[idx], -np.inf).max(axis=1, initial=-np.inf))


def _shifts_needed(t: np.ndarray, values: np.ndarray, tight: np.ndarray, points: np.ndarray,
                   band: np.ndarray, table: _RangeExtrema | None = None) -> np.ndarray:
    """For each point ``i`` of ``points``: the smallest shift in time ``s`` for which the tighter
    solve's curve (linear between its points) over ``[t_i - s, t_i + s]`` passes within ``band`` of
    the run's value there (inf if it never does): how far in time the two solves' transitions lie
    apart at that point.

    The curve enters the band ``[v - band, v + band]`` first (looking forward, or backward, from
    ``t_i``) in the segment that ends at the first point beyond the band's near edge: a point at or
    below ``v + band`` for a curve above the band at ``t_i`` (continuous: it cannot pass the band
    between two points without such a point), found by skipping whole blocks whose minimum is above
    it (binary lifting over :class:`_RangeExtrema`'s levels), then the point within its block."""
    table = table or _RangeExtrema(tight)
    if not table.finite:  # a broken curve: point by point, its pieces' segments only
        span = abs(float(t[-1] - t[0]))
        return np.array([_shift_needed(t, values, tight, i, span, b) for i, b in zip(points.tolist(), band.tolist())])
    out = np.full(points.size, np.inf)
    for lo in range(0, points.size, _CHUNK):
        i = points[lo:lo + _CHUNK]
        v, here, b = values[i], tight[i], band[lo:lo + _CHUNK]
        upper, lower = v + b, v - b
        best = np.where((here >= lower) & (here <= upper), 0.0, np.inf)
        for above in (True, False):  # the curve above the band at t_i: it comes down to upper; below: up to lower
            rows = np.flatnonzero((here > upper) if above else (here < lower))
            if rows.size == 0:
                continue
            edge = (upper if above else lower)[rows]
            for forward in (True, False):
                k = table.first_beyond(i[rows], edge, above, forward)
                found = k >= 0
                if not found.any():
                    continue
                r, k, e = rows[found], k[found], edge[found]
                prev = k - 1 if forward else k + 1  # the segment's point on the far side of the edge
                y0, y1 = tight[prev], tight[k]
                with np.errstate(invalid="ignore", divide="ignore"):
                    f = (y0 - e) / (y0 - y1)  # where the segment meets the band's edge
                f = np.where(np.isfinite(f), np.clip(f, 0.0, 1.0), 1.0)
                tau = t[prev] + f * (t[k] - t[prev])
                best[r] = np.minimum(best[r], np.abs(tau - t[i[r]]))
        out[lo:lo + _CHUNK] = best
    return out


def _shift_needed(t: np.ndarray, values: np.ndarray, tight: np.ndarray, i: int, width: float, band: float) -> float:
    """The smallest shift in time ``s <= width`` for which the tighter solve's curve (linear between
    its points) over ``[t_i - s, t_i + s]`` passes within ``band`` of the run's value at point ``i``
    (inf if none does), one point at a time: :func:`_shifts_needed` where the curve has values that
    are not finite (it is then in pieces; only segments between finite values count)."""
    v = float(values[i])
    if not np.isfinite(v):
        return math.inf
    if abs(float(tight[i]) - v) <= band:
        return 0.0
    if not width > 0:
        return math.inf
    ti = float(t[i])
    rt, rtight = (t, tight) if t[-1] >= t[0] else (t[::-1], tight[::-1])
    a, b = ti - width, ti + width
    j0, j1 = np.searchsorted(rt, a, side="left"), np.searchsorted(rt, b, side="right")
    ends = np.interp([a, b], rt, rtight)
    times = np.concatenate([[a], rt[j0:j1], [b]])
    g = np.concatenate([[ends[0]], rtight[j0:j1], [ends[1]]]) - v  # the curve less the run's value
    g0, g1, s0, s1 = g[:-1], g[1:], times[:-1], times[1:]
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = g1 - g0
        # the part of each segment (fraction f in [0, 1]) where -band <= g0 + f slope <= band
        fa, fb = (-band - g0) / slope, (band - g0) / slope
        lo = np.where(slope == 0, np.where(np.abs(g0) <= band, 0.0, np.inf), np.maximum(0.0, np.minimum(fa, fb)))
        hi = np.where(slope == 0, np.where(np.abs(g0) <= band, 1.0, -np.inf), np.minimum(1.0, np.maximum(fa, fb)))
    ok = (lo <= hi) & np.isfinite(g0) & np.isfinite(g1)
    if not ok.any():
        return math.inf
    start, stop = s0[ok] + lo[ok] * (s1[ok] - s0[ok]), s0[ok] + hi[ok] * (s1[ok] - s0[ok])
    gap = np.where(stop < ti, ti - stop, np.where(start > ti, start - ti, 0.0))
    return float(min(gap.min(), width))


def _units_text(units: float) -> str:
    return "an infinite number of" if math.isinf(units) else f"{units:.3g}"
