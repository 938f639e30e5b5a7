"""Simulink's source blocks as signals: Step, Ramp, Sine, Pulse, and Terms (exponentials,
polynomials and damped sines written directly in the exact form)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from odelab.exceptions import InputError
from odelab.signals.base import (
    MAX_PIECES,
    ExactForm,
    Piece,
    Signal,
    SignalKey,
    Term,
    _g,
    _inside,
    _is_real,
    _real,
    _shaped,
    _times,
    _window,
)


@dataclass(frozen=True)
class Step(Signal):
    """A step from ``initial`` to ``final`` at t = ``time``: u(t) = final for t >= time.

    Like Simulink's Step block, the output switches *at* the step time. Simulink's block
    defaults to a step time of 1; odelab's ``Step()`` is the unit step at t = 0.
    """

    TOML: ClassVar[str] = "step"
    KEYS: ClassVar[Mapping[str, SignalKey]] = {"time": SignalKey(0.0, unit="t"), "initial": SignalKey(0.0, unit="u"),
                                               "final": SignalKey(1.0, unit="u")}

    time: float = 0.0
    initial: float = 0.0
    final: float = 1.0

    @classmethod
    def describe(cls, name: str, values: Mapping[str, Any]) -> str:
        v = values
        return f"{name} steps {_g(v.get('initial', 0))} → {_g(v.get('final', 1))} at t = {_g(v.get('time', 0))}"

    def compiled_reason(self) -> str | None:
        return None

    def numba_source(self, slot) -> str:
        time, initial, final = slot(self.time, self.initial, self.final)
        return f"({final} if _tu >= {time} else {initial})"  # np.where(t >= time, final, initial)

    def __post_init__(self):
        for name in ("time", "initial", "final"):
            object.__setattr__(self, name, _real("Step", name, getattr(self, name)))

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        return _shaped(t, np.where(t >= self.time, self.final, self.initial))

    def breakpoints(self, t0: float, tf: float) -> np.ndarray:
        return _inside([self.time] if self.final != self.initial else [], t0, tf)

    def exact_terms(self) -> ExactForm:
        return ExactForm.of(
            Piece(-math.inf, self.time, (Term(self.initial),)),
            Piece(self.time, math.inf, (Term(self.final),)),
        )


@dataclass(frozen=True)
class Ramp(Signal):
    """u(t) = initial + slope*(t - start) for t >= start, ``initial`` before (Simulink's Ramp)."""

    TOML: ClassVar[str] = "ramp"
    KEYS: ClassVar[Mapping[str, SignalKey]] = {"slope": SignalKey(1.0, unit="u/t"), "start": SignalKey(0.0, unit="t"),
                                               "initial": SignalKey(0.0, unit="u")}

    slope: float = 1.0
    start: float = 0.0
    initial: float = 0.0

    @classmethod
    def describe(cls, name: str, values: Mapping[str, Any]) -> str:
        slope, start, initial = values.get("slope", 1), values.get("start", 0), values.get("initial", 0)
        var = "t" if not start else f"(t - {_g(start)})"
        term = var if slope == 1 else f"{_g(slope)} {var}"
        text = f"{_g(initial)} + {term}" if initial else term
        return f"{name} = {text}" + (f" for t >= {_g(start)}" if start else "")

    def compiled_reason(self) -> str | None:
        return None

    def numba_source(self, slot) -> str:
        slope, start, initial = slot(self.slope, self.start, self.initial)
        return f"({initial} + {slope} * _max(_tu - {start}, 0.0))"

    def __post_init__(self):
        for name in ("slope", "start", "initial"):
            object.__setattr__(self, name, _real("Ramp", name, getattr(self, name)))

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        return _shaped(t, self.initial + self.slope * np.maximum(t - self.start, 0.0))

    def breakpoints(self, t0: float, tf: float) -> np.ndarray:
        return _inside([self.start] if self.slope else [], t0, tf)

    def exact_terms(self) -> ExactForm:
        return ExactForm.of(
            Piece(-math.inf, self.start, (Term(self.initial),)),
            Piece(self.start, math.inf, (Term(self.initial), Term(self.slope, self.start, 1))),
        )


@dataclass(frozen=True)
class Sine(Signal):
    """u(t) = bias + amplitude*sin(frequency*t + phase), frequency in rad/s (Simulink's Sine Wave)."""

    TOML: ClassVar[str] = "sine"
    KEYS: ClassVar[Mapping[str, SignalKey]] = {
        "amplitude": SignalKey(1.0, unit="u"), "frequency": SignalKey(1.0, unit="rad/s"),
        "phase": SignalKey(0.0, unit="rad"), "bias": SignalKey(0.0, unit="u")}

    amplitude: float = 1.0
    frequency: float = 1.0
    phase: float = 0.0
    bias: float = 0.0

    @classmethod
    def describe(cls, name: str, values: Mapping[str, Any]) -> str:
        v = values
        a, w, phi, bias = (v.get("amplitude", 1), v.get("frequency", 1), v.get("phase", 0), v.get("bias", 0))
        arg = f"{_g(w)} t" if w != 1 else "t"
        arg += f" + {_g(phi)}" if phi else ""
        term = ("" if a == 1 else "-" if a == -1 else f"{_g(a)} ") + f"sin({arg})"
        return f"{name} = " + (f"{_g(bias)} + {term}" if bias else term)

    def compiled_reason(self) -> str | None:
        return None

    def numba_source(self, slot) -> str:
        amplitude, frequency, phase, bias = slot(self.amplitude, self.frequency, self.phase, self.bias)
        return f"({bias} + {amplitude} * _np.sin({frequency} * _tu + {phase}))"

    def __post_init__(self):
        for name in ("amplitude", "frequency", "phase", "bias"):
            object.__setattr__(self, name, _real("Sine", name, getattr(self, name)))

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        return _shaped(t, self.bias + self.amplitude * np.sin(self.frequency * t + self.phase))

    def exact_terms(self) -> ExactForm:
        # a sin(w t + phi) = a sin(phi) cos(w t) + a cos(phi) sin(w t)
        a, w, phi = self.amplitude, self.frequency, self.phase
        terms = (
            Term(self.bias),
            Term(a * math.sin(phi), freq=w, kind="cos"),
            Term(a * math.cos(phi), freq=w, kind="sin"),
        )
        return ExactForm.of(Piece(-math.inf, math.inf, terms))


@dataclass(frozen=True)
class Pulse(Signal):
    """A square wave, as Simulink's Pulse Generator in time mode.

    u(t) = amplitude on ``delay + k*period <= t < delay + k*period + width*period``
    (k = 0, 1, ...), and 0 elsewhere, including everywhere before ``delay``. ``width`` is a
    fraction of the period, 0 < width < 1 (Simulink asks for a percentage).
    """

    TOML: ClassVar[str] = "pulse"
    KEYS: ClassVar[Mapping[str, SignalKey]] = {
        "amplitude": SignalKey(1.0, unit="u"), "period": SignalKey(1.0, unit="t"), "width": SignalKey(0.5),
        "delay": SignalKey(0.0, unit="t")}

    amplitude: float = 1.0
    period: float = 1.0
    width: float = 0.5
    delay: float = 0.0

    def compiled_reason(self) -> str | None:
        return None

    def numba_source(self, slot) -> str:
        args = slot(self.amplitude, self.period, self.width, self.delay)
        return f"_pulse(_tu, {', '.join(args)})"  # the helper of solvers/compiled/inputs.INPUT_PRELUDE

    def __post_init__(self):
        object.__setattr__(self, "amplitude", _real("Pulse", "amplitude", self.amplitude))
        object.__setattr__(self, "period", _real("Pulse", "period", self.period, positive=True))
        object.__setattr__(self, "delay", _real("Pulse", "delay", self.delay))
        width = _real("Pulse", "width", self.width)
        if not 0.0 < width < 1.0:
            raise InputError(
                f"`Pulse.width` is a fraction of the period and must be strictly between 0 and 1; "
                f"got {width!r} (use a Step or a Constant for an output that never switches).",
                key="Pulse.width",
            )
        object.__setattr__(self, "width", width)

    # Both __call__ and the edges use these two formulas, so that a time classified as "on"
    # by one is "on" for the other to the last bit.
    def _rise(self, k: np.ndarray | float) -> np.ndarray | float:
        return self.delay + k * self.period

    def _fall(self, k: np.ndarray | float) -> np.ndarray | float:
        return self._rise(k) + self.width * self.period

    def _period_index(self, t: np.ndarray) -> np.ndarray:
        """k with rise(k) <= t < rise(k + 1), exactly in floating point."""
        k = np.floor((t - self.delay) / self.period)
        k = np.where(t < self._rise(k), k - 1, k)
        k = np.where(t >= self._rise(k + 1), k + 1, k)
        return k

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        k = self._period_index(t)
        on = (k >= 0) & (t < self._fall(k))
        return _shaped(t, np.where(on, self.amplitude, 0.0))

    def _count_check(self, lo: float, hi: float) -> tuple[int, int]:
        if not math.isfinite(hi):
            raise InputError(
                "A Pulse has infinitely many pieces: ask for its pieces or breakpoints over a "
                "finite time window."
            )
        k0 = max(0, int(self._period_index(np.float64(max(lo, self.delay)))))
        k1 = max(0, int(self._period_index(np.float64(max(hi, self.delay)))))
        if 2 * (k1 - k0 + 1) > MAX_PIECES:
            raise InputError(
                f"The Pulse has about {2 * (k1 - k0 + 1)} edges between {lo} and {hi} (period "
                f"{self.period}): more than {MAX_PIECES}. Shorten the time span or lengthen "
                "the period."
            )
        return k0, k1

    def breakpoints(self, t0: float, tf: float) -> np.ndarray:
        if self.amplitude == 0:
            return np.empty(0)
        lo, hi = _window(t0, tf)
        if hi <= self.delay:
            return np.empty(0)
        k0, k1 = self._count_check(lo, hi)
        k = np.arange(k0, k1 + 1, dtype=float)
        return _inside(np.concatenate([self._rise(k), self._fall(k)]), lo, hi)

    def exact_terms(self) -> ExactForm:
        def generate(lo: float, hi: float) -> tuple[Piece, ...]:
            if hi < self.delay:
                return (Piece(-math.inf, self.delay, ()),)
            k0, k1 = self._count_check(lo, hi)
            on = (Term(self.amplitude),)
            # before rise(k0) the pulse is off: either before the delay (k0 = 0) or in the
            # off part of period k0 - 1, which ends before the window starts
            pieces = [Piece(-math.inf, self._rise(k0), ())]
            for k in range(k0, k1 + 1):  # rise(k1) <= hi < rise(k1 + 1)
                pieces.append(Piece(self._rise(k), self._fall(k), on))
                pieces.append(Piece(self._fall(k), self._rise(k + 1), ()))
            return tuple(pieces)

        return ExactForm(generate)


@dataclass(frozen=True)
class Terms(Signal):
    """A sum of :class:`Term` objects from ``start`` on, 0 before: exponentials, polynomials,
    damped sines, written directly in the exact form.

    >>> u = Terms((Term(1.0, rate=-2.0),), start=0.0)        # e^{-2t} for t >= 0
    >>> v = Terms((Term(1.0, power=2),))                       # t^2 for all t
    """

    terms: tuple[Term, ...]
    start: float = -math.inf

    def __post_init__(self):
        terms = (self.terms,) if isinstance(self.terms, Term) else tuple(self.terms)
        for i, term in enumerate(terms):
            if not isinstance(term, Term):
                raise InputError(f"`Terms.terms[{i}]` must be a Term; got {term!r}.", key="Terms.terms")
            for name in ("coef", "tau", "rate", "freq"):
                _real(f"Terms.terms[{i}]", name, getattr(term, name))
        object.__setattr__(self, "terms", terms)
        start = self.start
        if not (_is_real(start) and not math.isnan(start) and start != math.inf):
            raise InputError(
                f"`Terms.start` must be a real number or -inf; got {start!r}.", key="Terms.start"
            )
        object.__setattr__(self, "start", float(start))

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        out = np.zeros(t.shape)
        on = t >= self.start
        if np.any(on):  # only there: an exponential may overflow before the start
            out[on] = Piece(self.start, math.inf, self.terms)(t[on])
        return _shaped(t, out)

    def breakpoints(self, t0: float, tf: float) -> np.ndarray:
        return _inside([self.start] if math.isfinite(self.start) else [], t0, tf)

    def exact_terms(self) -> ExactForm:
        if not math.isfinite(self.start):
            return ExactForm.of(Piece(-math.inf, math.inf, self.terms))
        return ExactForm.of(Piece(-math.inf, self.start, ()), Piece(self.start, math.inf, self.terms))


