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
crossings 19 ``RelTol t``), not a wrong value.

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

    def as_dict(self) -> dict:
        return {"max_abs": self.max_abs, "t_max_abs": self.t_max_abs, "rel_error": self.rel, "rel_basis": self.basis,
                "digits": self.digits, "units": self.units, "t_units": self.t_units, "value": self.value,
                "tight": self.tight, "flagged": self.flagged}


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
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        allowed = rtol * np.abs(other) + atol
        diff = np.abs(values - other)
        units = diff / allowed
        units = np.where(np.isfinite(units), units, np.inf)
        if q.basis == "peak" or not math.isfinite(s.scale):
            tenth = 0.1 * s.scale / scale_up if math.isfinite(s.scale) else np.inf
        else:
            tenth = 0.1 * np.abs(other) / scale_up
        controlled = bool(s.scale > 10 * atol) if math.isfinite(s.scale) else True
        digit_bad = (diff > tenth) if controlled else np.zeros(diff.shape, dtype=bool)
    i = int(np.argmax(units))
    q = replace(q, units=float(units[i]), t_units=float(t[i]), value=float(values[i]), tight=float(other[i]),
                controlled=controlled)
    suspect = np.flatnonzero((units > DISAGREE_UNITS) | digit_bad)
    if suspect.size == 0:
        return q, "", ""
    worst, worst_units, shifted = None, 0.0, 0.0
    for j in suspect.tolist():
        width = PHASE_SHIFT * rtol * abs(t[j] - t[0])
        # either curve shifted onto the other: each is sampled densely only where it moves fast itself
        d = min(_shift_distance(t, values, other, j, width), _shift_distance(t, other, values, j, width))
        u = d / allowed[j] if allowed[j] > 0 else math.inf
        rel_left = d / (tenth if np.ndim(tenth) == 0 else tenth[j]) if controlled else 0.0
        if u > DISAGREE_UNITS or rel_left > 1:
            if worst is None or u > worst_units:
                worst, worst_units = j, u
        else:
            shifted = max(shifted, width)
    name = q.name
    if worst is not None:
        j = worst
        # two solves that disagree beyond the tolerances do not measure each other's error: no digits claimed
        q = replace(q, units=float(units[j]), t_units=float(t[j]), value=float(values[j]), tight=float(other[j]),
                    digits=0.0, flagged=True)
        if worst_units > DISAGREE_UNITS:
            reason = (f"{name}: the run and a solve at tolerances {factor:g} times tighter disagree by "
                      f"{_units_text(float(units[j]))} times the accuracy asked for (RelTol |{name}| + AbsTol) at "
                      f"t = {t[j]:.6g}: {name} = {values[j]:.6g} against {other[j]:.6g}")
        else:
            reason = (f"{name}: the estimated error is {q.max_abs:.3g} (at t = {q.t_max_abs:.6g}), fewer than "
                      f"{MIN_DIGITS:g} correct digit relative to {name}'s {'peak' if q.basis == 'peak' else 'values'} "
                      f"({name} = {values[j]:.6g} against {other[j]:.6g} at t = {t[j]:.6g})")
        return q, reason, ""
    note = (f"{name}: its largest differences (estimated error {q.max_abs:.3g} at t = {q.t_max_abs:.6g}) are where "
            f"{name} moves fast, and a shift in time of at most {shifted:.3g} explains them: a phase error (a "
            "transition a little earlier or later), not a wrong value")
    return q, "", note


def _shift_distance(t: np.ndarray, values: np.ndarray, tight: np.ndarray, i: int, width: float) -> float:
    """The distance from the run's value at point ``i`` to the tighter solve's curve over
    ``[t_i - width, t_i + width]`` (linear between its points): zero when a shift in time of at most
    ``width`` explains the difference."""
    if not (np.isfinite(values[i]) and width > 0):
        return float(abs(values[i] - tight[i])) if np.isfinite(values[i]) else math.inf
    forward = t[-1] >= t[0]
    a, b = t[i] - width, t[i] + width
    if forward:
        j0, j1 = np.searchsorted(t, a, side="left"), np.searchsorted(t, b, side="right")
        inside = tight[j0:j1]
        edges = np.interp([a, b], t, tight)
    else:
        rt, rtight = t[::-1], tight[::-1]
        j0, j1 = np.searchsorted(rt, a, side="left"), np.searchsorted(rt, b, side="right")
        inside = rtight[j0:j1]
        edges = np.interp([a, b], rt, rtight)
    pool = np.concatenate([inside, edges])
    pool = pool[np.isfinite(pool)]
    if pool.size == 0:
        return math.inf
    lo, hi = float(pool.min()), float(pool.max())
    v = float(values[i])
    return max(lo - v, v - hi, 0.0)


def _units_text(units: float) -> str:
    return "an infinite number of" if math.isinf(units) else f"{units:.3g}"
