"""Input signals u(t), as Simulink's source blocks.

Every signal is a frozen dataclass and a vectorised callable: ``u(t)`` takes a float or an
array of times and returns a float or an array of the same shape. Signals combine with
``+``, ``-``, and ``*`` / ``/`` by numbers (:class:`Sum`, :class:`Scaled`, :class:`Constant`).

:class:`Terms` writes exponentials, polynomials and damped sines directly as terms of the
exact form below.

Two more methods serve the rest of odelab:

``breakpoints(t0, tf)``
    The times strictly between t0 and tf (either order), sorted increasingly, where the
    signal or its first derivative jumps. :func:`odelab.systems.simulate.simulate` restarts
    the solver at each one, so a step is not smeared over a long step of the integrator.
``exact_terms()``
    The signal written exactly as a piecewise sum of :class:`Term` objects,

        c * (t - tau)**k * exp(lam*(t - tau)) * cos(w*(t - tau))    (or sin),

    as an :class:`ExactForm`, or ``None`` when there is no such form (:class:`Function`,
    and sums or scalings of one). A :class:`Table` has one: linear interpolation is exactly
    piecewise linear.
    :func:`odelab.analysis.lti.lti_response` turns each piece into an exosystem and computes
    the response of a linear system exactly.

Convention at a jump: every signal here is *right-continuous*, u(T) is the value after the
jump (Simulink's Step block outputs the final value at the step time). Code that needs the
value before a jump at T evaluates just below T (``numpy.nextafter(T, -inf)``).
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from numbers import Real
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from odelab.exceptions import InputError
from odelab.fileio import DECIMAL_COMMA_FIX, decimal_comma_line

__all__ = [
    "SIGNALS",
    "SignalContext",
    "SignalKey",
    "plain_description",
    "register_signal",
    "Signal",
    "Step",
    "Ramp",
    "Sine",
    "Pulse",
    "Table",
    "interpolate_1d",
    "interpolate_2d",
    "spline_pieces",
    "Function",
    "Sum",
    "Scaled",
    "Constant",
    "Expression",
    "Terms",
    "Term",
    "Piece",
    "ExactForm",
    "as_signal",
    "as_signals",
    "input_jumps",
]

# A Pulse over a window with more edges than this is refused: its breakpoints and pieces
# would not fit in memory, and restarting a solver that often is never what was meant.
MAX_PIECES = 1_000_000


# -- helpers -----------------------------------------------------------------------------


def _is_real(value: Any) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool)


def _real(owner: str, name: str, value: Any, *, positive: bool = False) -> float:
    """``value`` as a finite float, or an InputError naming ``owner.name``."""
    if not _is_real(value) or not math.isfinite(float(value)):
        raise InputError(
            f"`{owner}.{name}` must be a finite real number; got {value!r}.", key=f"{owner}.{name}"
        )
    value = float(value)
    if positive and value <= 0:
        raise InputError(f"`{owner}.{name}` must be positive; got {value!r}.", key=f"{owner}.{name}")
    return value


def _times(t: Any) -> np.ndarray:
    return np.asarray(t, dtype=float)


def _shaped(t: np.ndarray, values: np.ndarray) -> float | np.ndarray:
    """Return a float for a scalar time, an array of t's shape otherwise."""
    if t.ndim == 0:
        return float(values)
    return np.broadcast_to(values, t.shape).astype(float, copy=True)


def _window(t0: float, tf: float) -> tuple[float, float]:
    t0, tf = float(t0), float(tf)
    if math.isnan(t0) or math.isnan(tf):
        raise InputError(f"A time window must not contain NaN; got ({t0}, {tf}).")
    return (t0, tf) if t0 <= tf else (tf, t0)


def _inside(times: Iterable[float], t0: float, tf: float) -> np.ndarray:
    """The distinct ``times`` strictly inside the open interval between t0 and tf, sorted."""
    lo, hi = _window(t0, tf)
    times = np.asarray(list(times) if not isinstance(times, np.ndarray) else times, dtype=float)
    return np.unique(times[(times > lo) & (times < hi)])


# -- exact forms ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Term:
    """One term ``coef * s**power * exp(rate*s) * cos(freq*s)`` (or ``sin``), s = t - tau.

    In the notation of the module docstring: c = ``coef``, k = ``power``, lam = ``rate``,
    w = ``freq`` (rad/s). ``kind`` is ``"cos"`` or ``"sin"``.
    """

    coef: float
    tau: float = 0.0
    power: int = 0
    rate: float = 0.0
    freq: float = 0.0
    kind: str = "cos"

    def __post_init__(self):
        if self.kind not in ("cos", "sin"):
            raise InputError(f"`Term.kind` must be 'cos' or 'sin'; got {self.kind!r}.")
        if not isinstance(self.power, int) or self.power < 0:
            raise InputError(f"`Term.power` must be a non-negative integer; got {self.power!r}.")

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        s = t - self.tau
        out = np.full(s.shape, self.coef)
        if self.power:
            out = out * s**self.power
        if self.rate:
            out = out * np.exp(self.rate * s)
        if self.kind == "sin":
            out = out * np.sin(self.freq * s)
        elif self.freq:
            out = out * np.cos(self.freq * s)
        return _shaped(t, out)

    def scaled(self, gain: float) -> Term:
        return Term(gain * self.coef, self.tau, self.power, self.rate, self.freq, self.kind)


@dataclass(frozen=True)
class Piece:
    """A signal on ``start <= t < stop`` (``start`` may be -inf, ``stop`` inf): a sum of terms."""

    start: float
    stop: float
    terms: tuple[Term, ...] = ()

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        out = np.zeros(t.shape)
        for term in self.terms:
            out = out + term(t)
        return _shaped(t, out)


def _covering(pieces: Sequence[Piece], lo: float, hi: float) -> tuple[Piece, ...]:
    """The pieces that meet [lo, hi], including one that starts exactly at hi."""
    return tuple(p for p in pieces if p.stop > lo and p.start <= hi)


class ExactForm:
    """A signal's exact piecewise form, generated on demand over a time window.

    A generator is needed rather than a list because a :class:`Pulse` has infinitely many
    pieces; over a finite window every signal has finitely many.

    Parameters
    ----------
    generate
        ``generate(lo, hi)`` returns contiguous, sorted pieces covering ``[lo, hi]``; only
        their values on ``[lo, hi]`` count (a piece reaching outside it may be wrong there,
        e.g. the first piece of a Pulse over a late window).
    """

    __slots__ = ("_generate",)

    def __init__(self, generate: Callable[[float, float], Sequence[Piece]]):
        self._generate = generate

    @classmethod
    def of(cls, *pieces: Piece) -> ExactForm:
        """A form with a fixed, finite list of pieces."""
        return cls(lambda lo, hi: pieces)

    def raw(self, lo: float, hi: float) -> tuple[Piece, ...]:
        """The unclipped pieces that meet [lo, hi] (lo <= hi), in time order."""
        return _covering(self._generate(lo, hi), lo, hi)

    def pieces(self, t0: float = -math.inf, tf: float = math.inf) -> tuple[Piece, ...]:
        """Pieces partitioning the window between t0 and tf, clipped to it, in time order.

        Each piece holds on ``start <= t < stop``; the last one also at its ``stop``. The
        ``tau`` of the terms are not shifted by the clipping, so the values are unchanged.
        Pieces of zero length are dropped (unless the window is a single point).
        """
        lo, hi = _window(t0, tf)
        raw = self.raw(lo, hi)
        clipped = [Piece(max(p.start, lo), min(p.stop, hi), p.terms) for p in raw]
        if lo < hi:
            clipped = [p for p in clipped if p.stop > p.start]
        else:
            clipped = [p for p in raw if p.start <= lo < p.stop][:1] or clipped[:1]
            clipped = [Piece(lo, hi, p.terms) for p in clipped]
        return tuple(clipped)

    def __call__(self, t: Any) -> float | np.ndarray:
        """Evaluate the form (right-continuous at piece boundaries)."""
        t = _times(t)
        out = np.zeros(t.shape)
        if t.size == 0:
            return _shaped(t, out)
        raw = self.raw(float(np.min(t)), float(np.max(t)))
        starts = np.array([p.start for p in raw])
        which = np.searchsorted(starts, t, side="right") - 1
        for i, piece in enumerate(raw):
            mask = which == i
            if np.any(mask):
                out[mask] = piece(t[mask])
        return _shaped(t, out)

    def scaled(self, gain: float) -> ExactForm:
        def generate(lo: float, hi: float) -> tuple[Piece, ...]:
            return tuple(
                Piece(p.start, p.stop, tuple(term.scaled(gain) for term in p.terms))
                for p in self._generate(lo, hi)
            )

        return ExactForm(generate)

    @staticmethod
    def sum(forms: Sequence[ExactForm]) -> ExactForm:
        """The form of a sum: the union of the boundaries, the terms of every form."""

        def generate(lo: float, hi: float) -> tuple[Piece, ...]:
            parts = [form.raw(lo, hi) for form in forms]
            starts = sorted({p.start for part in parts for p in part})
            stops = [*starts[1:], min(part[-1].stop for part in parts if part)] if starts else []
            out = []
            cursor = [0] * len(parts)  # starts increase: each part is scanned once overall
            for a, b in zip(starts, stops):
                terms: list[Term] = []
                for k, part in enumerate(parts):
                    i = cursor[k]
                    while i < len(part) and part[i].stop <= a:
                        i += 1
                    cursor[k] = i
                    if i < len(part) and part[i].start <= a:
                        terms.extend(part[i].terms)
                out.append(Piece(a, b, tuple(terms)))
            return tuple(out)

        return ExactForm(generate)


# -- the registry of signal types that experiment files name ----------------------------------


@dataclass(frozen=True)
class SignalKey:
    """One key of a signal type in an experiment file (``[inputs.f]`` or a source block).

    ``default`` None makes the key required. ``kind`` says how the file gives it: ``"number"``
    (a number or an expression of the parameters, evaluated when the file is loaded),
    ``"text"`` (a string such as a file name), ``"expression"`` (an expression of t and the
    parameters) or ``"numbers"`` (a list of numbers: a table's samples). ``unit`` is "t" for a time,
    "u" for the signal's own unit, or a fixed unit.
    """

    default: Any = None
    kind: str = "number"
    unit: str = ""


@dataclass(frozen=True)
class SignalContext:
    """What building a signal from an experiment file needs from the experiment layer.

    ``key`` is the table's key path (``inputs.f``, ``blocks.force``), ``what`` the noun for
    messages ("input", "source block"), ``params`` the file's parameter values,
    ``resolve_file(name, key)`` a user file's path (relative to the experiment file, confined),
    ``max_rows`` the budget of a table's rows (None: no limit).
    """

    key: str
    what: str
    params: Mapping[str, float]
    resolve_file: Callable[[str, str], Path]
    max_rows: int | None = None


#: The signal types of experiment files, by TOML name, in the order messages list them.
SIGNALS: dict[str, type[Signal]] = {}


def register_signal(cls: type[Signal]) -> type[Signal]:
    """Class decorator: make ``cls`` the signal type ``cls.TOML`` of experiment files.

    The class declares its keys (``KEYS``, name -> :class:`SignalKey`), builds itself from
    them (:meth:`Signal.from_toml`), describes itself for the report (:meth:`Signal.describe`),
    gives its compiled source (:meth:`Signal.numba_source`) and its exact form
    (:meth:`Signal.exact_terms`). The schema, the builder, ``odelab explain``, the report and
    the compiled backend read the registry: nothing else names the type.
    """
    name = getattr(cls, "TOML", None)
    if not isinstance(name, str) or not re.fullmatch(r"[a-z][a-z0-9_-]*", name):
        raise ValueError(f"a registered signal needs TOML = a lower-case name; {cls.__name__} has {name!r}")
    if name in SIGNALS and SIGNALS[name] is not cls:
        raise ValueError(f"the signal type {name!r} is registered already ({SIGNALS[name].__name__})")
    SIGNALS[name] = cls
    return cls


def plain_description(name: str, kind: str | None, values: Mapping[str, Any]) -> str:
    """``f: pulse (amplitude 1, period 2, ...)``: a signal listed by its keys, where it has no formula."""
    args = ", ".join(f"{k} {_g(x)}" for k, x in values.items() if k != "type")
    return f"{name}: {kind or 'signal'}" + (f" ({args})" if args else "")


def _g(value: Any) -> str:
    """A number as the report writes it in a formula (``0.2``, ``1e-05``); anything else as text."""
    return f"{value:g}" if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value)


# -- signals -----------------------------------------------------------------------------


class Signal:
    """Base class of the input signals: arithmetic, breakpoints and exact forms.

    Subclasses implement ``__call__``, ``breakpoints`` and ``exact_terms``. A signal type that
    experiment files name also sets ``TOML`` and ``KEYS`` and is :func:`register_signal`-ed.
    """

    TOML: ClassVar[str | None] = None  # its name in experiment files ([inputs.f] type = "step")
    KEYS: ClassVar[Mapping[str, SignalKey]] = {}  # its keys there, with their defaults

    @classmethod
    def from_toml(cls, values: Mapping[str, Any], ctx: SignalContext) -> Signal:
        """The signal from its keys (defaults filled in, numbers evaluated); InputError names the key."""
        return cls(**{k: float(values[k]) for k in cls.KEYS})

    @classmethod
    def describe(cls, name: str, values: Mapping[str, Any]) -> str:
        """The input ``name`` as the report writes it, from its stored keys: ``f: pulse (amplitude 1, ...)``."""
        return plain_description(name, cls.TOML, values)

    def compiled_reason(self) -> str | None:
        """Why the compiled backend cannot generate this signal (None when :meth:`numba_source` can)."""
        return f"a {type(self).__name__} input is not generated by the compiled engine"

    def numba_source(self, slot: Callable[..., list[str]]) -> str:
        """The expression of u at ``_tu`` in the compiled module (numba), operation for operation
        the numpy of ``__call__``. ``slot(*numbers)`` stores numbers as run-time data and returns
        the names that read them (``_p[7]``): never paste a number into the source."""
        raise NotImplementedError(self.compiled_reason())

    def __call__(self, t: Any) -> float | np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def breakpoints(self, t0: float, tf: float) -> np.ndarray:
        """Times strictly between t0 and tf (sorted increasingly) where u or u' jumps."""
        return np.empty(0)

    def exact_terms(self) -> ExactForm | None:
        """The exact piecewise form, or None if there is none."""
        return None

    # arithmetic: numbers become Constants; a Sum stays flat
    def __add__(self, other: Any) -> Signal:
        if isinstance(other, Signal) or _is_real(other):
            return Sum((self, other))
        return NotImplemented

    def __radd__(self, other: Any) -> Signal:
        if _is_real(other):
            return Sum((other, self))
        return NotImplemented

    def __neg__(self) -> Signal:
        return Scaled(-1.0, self)

    def __sub__(self, other: Any) -> Signal:
        if isinstance(other, Signal):
            return Sum((self, -other))
        if _is_real(other):
            return Sum((self, -float(other)))
        return NotImplemented

    def __rsub__(self, other: Any) -> Signal:
        if _is_real(other):
            return Sum((other, -self))
        return NotImplemented

    def __mul__(self, gain: Any) -> Signal:
        if _is_real(gain):
            return Scaled(gain, self)
        return NotImplemented

    __rmul__ = __mul__

    def __truediv__(self, gain: Any) -> Signal:
        if _is_real(gain):
            if gain == 0:
                raise ZeroDivisionError("a signal cannot be divided by 0")
            return Scaled(1.0 / float(gain), self)
        return NotImplemented


@dataclass(frozen=True)
class Constant(Signal):
    """u(t) = value."""

    TOML: ClassVar[str] = "constant"
    KEYS: ClassVar[Mapping[str, SignalKey]] = {"value": SignalKey(None, unit="u")}

    value: float = 0.0

    @classmethod
    def describe(cls, name: str, values: Mapping[str, Any]) -> str:
        return f"{name} = {_g(values.get('value'))}"

    def compiled_reason(self) -> str | None:
        return None

    def numba_source(self, slot) -> str:
        (value,) = slot(self.value)
        return value

    def __post_init__(self):
        object.__setattr__(self, "value", _real("Constant", "value", self.value))

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        return _shaped(t, np.float64(self.value))

    def exact_terms(self) -> ExactForm:
        return ExactForm.of(Piece(-math.inf, math.inf, (Term(self.value),)))


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


def _quoted_line(line: str, rows_so_far: list) -> str:
    """A bad line of a table file, quoted (shortened) only when earlier lines were samples: a file
    that is not a table at all (a path pointed at /etc/passwd) has none of its content quoted."""
    if not rows_so_far:
        return ("text, and so did the line before it: the file is not a table of samples (two numeric "
                "columns t, u); check `file`")
    return repr(line if len(line) <= 60 else line[:57] + "...")

# -- table interpolation (the [inputs] table type and the diagrams' lookup-table block) -----------

#: Simulink's interpolation and extrapolation methods of lookup tables, in odelab's spelling
INTERPOLATIONS = ("linear", "flat", "nearest", "cubic-spline")
EXTRAPOLATIONS = ("clip", "linear")


def spline_pieces(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The coefficients (4, n - 1) of MATLAB's ``spline`` through (x, y) (not-a-knot ends; two
    points give the line, three the parabola): piece i is sum c[k, i] (t - x[i])**(3 - k)."""
    from scipy.interpolate import CubicSpline

    return np.asarray(CubicSpline(x, y, bc_type="not-a-knot").c, dtype=float)


def _re(v):
    return v.real if np.iscomplexobj(v) else v


def interpolate_1d(v, x: np.ndarray, y: np.ndarray, interpolation: str = "linear", extrapolation: str = "clip",
                   *, segment=None, spline: np.ndarray | None = None):
    """Table lookup y(v) through the points (x, y), x increasing, as Simulink's 1-D Lookup Table.

    ``interpolation``: ``"linear"``; ``"flat"`` (the value at the breakpoint at or below v);
    ``"nearest"`` (the nearest breakpoint's value, half-way goes up); ``"cubic-spline"``
    (MATLAB's ``spline``, coefficients ``spline`` from :func:`spline_pieces`).
    ``extrapolation``: ``"clip"`` (the end values) or ``"linear"`` (the end segment's line; a
    spline's end tangent). ``segment``, if given, is the interval index to use (the number of
    breakpoints at or below v, or for ``"nearest"`` of midpoints), so a caller can hold it;
    otherwise it is read off v. v may be complex (complex-step derivatives): the decisions are
    taken on its real part.
    """
    n = x.size
    r = _re(v)
    edges = 0.5 * (x[1:] + x[:-1]) if interpolation == "nearest" else x
    m = np.searchsorted(edges, r, side="right") if segment is None else np.broadcast_to(segment, np.shape(v))
    zero = 0.0 * v
    slope = np.diff(y) / np.diff(x)
    if interpolation == "nearest":
        out = y[np.clip(m, 0, n - 1)] + zero
    elif interpolation == "flat":
        out = y[np.clip(m - 1, 0, n - 1)] + zero
    elif interpolation == "cubic-spline":
        c = spline_pieces(x, y) if spline is None else spline
        j = np.clip(m - 1, 0, n - 2)
        dx = v - x[j]
        out = ((c[0, j] * dx + c[1, j]) * dx + c[2, j]) * dx + c[3, j]
    else:
        j = np.clip(m - 1, 0, n - 2)
        out = y[j] + slope[j] * (v - x[j])
    if segment is not None and interpolation != "nearest":  # the held interval decides, not v
        below, above = m == 0, m == n
    else:
        below, above = r < x[0], r > x[-1]
    if extrapolation == "clip":
        out = np.where(below, y[0] + zero, np.where(above, y[-1] + zero, out))
    elif interpolation == "cubic-spline":
        c = spline_pieces(x, y) if spline is None else spline
        h = x[-1] - x[-2]
        d_end = (3 * c[0, -1] * h + 2 * c[1, -1]) * h + c[2, -1]
        out = np.where(below, y[0] + c[2, 0] * (v - x[0]), np.where(above, y[-1] + d_end * (v - x[-1]), out))
    else:
        out = np.where(below, y[0] + slope[0] * (v - x[0]), np.where(above, y[-1] + slope[-1] * (v - x[-1]), out))
    return out


def interpolate_2d(v1, v2, x1: np.ndarray, x2: np.ndarray, table: np.ndarray, interpolation: str = "linear",
                   extrapolation: str = "clip"):
    """2-D table lookup (rows for x1, columns for x2), as Simulink's 2-D Lookup Table:
    bilinear (``"linear"``), ``"flat"`` or ``"nearest"``; ``"clip"`` or ``"linear"`` outside."""
    r1, r2 = _re(v1), _re(v2)
    zero = 0.0 * v1 + 0.0 * v2
    if interpolation in ("flat", "nearest"):
        idx = []
        for r, x in ((r1, x1), (r2, x2)):
            if interpolation == "nearest":
                k = np.searchsorted(0.5 * (x[1:] + x[:-1]), r, side="right")
            else:
                k = np.searchsorted(x, r, side="right") - 1
            idx.append(np.clip(k, 0, x.size - 1))
        return table[idx[0], idx[1]] + zero
    parts = []
    for v, r, x in ((v1, r1, x1), (v2, r2, x2)):
        i = np.clip(np.searchsorted(x, r, side="right") - 1, 0, x.size - 2)
        if extrapolation == "clip":
            v = np.where(r < x[0], x[0] + 0.0 * v, np.where(r > x[-1], x[-1] + 0.0 * v, v))
        parts.append((i, (v - x[i]) / (x[i + 1] - x[i])))
    (i, a), (j, b) = parts
    return ((1 - a) * (1 - b) * table[i, j] + a * (1 - b) * table[i + 1, j] + (1 - a) * b * table[i, j + 1]
            + a * b * table[i + 1, j + 1]) + zero


@dataclass(frozen=True, eq=False)
class Table(Signal):
    """Interpolation of samples (t_i, u_i): linear between them and held constant outside
    [t_0, t_last] by default (Simulink's 1-D Lookup Table / From Workspace).

    ``interpolation`` is ``"linear"``, ``"flat"`` (each sample held until the next),
    ``"nearest"`` or ``"cubic-spline"`` (MATLAB's ``spline``); ``extrapolation`` is ``"clip"``
    (the end values) or ``"linear"`` (the end segments continued), as
    :func:`interpolate_1d`. ``t`` must be strictly increasing (a jump is a Step added to the
    table, or ``"flat"``).
    """

    TOML: ClassVar[str] = "table"
    KEYS: ClassVar[Mapping[str, SignalKey]] = {
        "file": SignalKey("", kind="text"), "t": SignalKey((), kind="numbers", unit="t"),
        "values": SignalKey((), kind="numbers", unit="u"), "interpolation": SignalKey("linear", kind="text"),
        "extrapolation": SignalKey("clip", kind="text")}

    t: Any
    values: Any
    label: str = ""
    interpolation: str = "linear"
    extrapolation: str = "clip"

    @classmethod
    def from_toml(cls, values: Mapping[str, Any], ctx: SignalContext) -> Table:
        """From a CSV file (``file``) or from the samples themselves (``t`` and ``values``, as MATLAB's
        ``interp1(tdata, udata, t)`` gives them)."""
        import difflib

        key = ctx.key
        for k, allowed_values in (("interpolation", INTERPOLATIONS), ("extrapolation", EXTRAPOLATIONS)):
            if values[k] not in allowed_values:
                close = difflib.get_close_matches(str(values[k]), allowed_values, n=1)
                hint = f" Did you mean {close[0]!r}?" if close else ""
                raise InputError(f"`{key}.{k}` is {values[k]!r}; use one of "
                                 f"{', '.join(repr(a) for a in allowed_values)} (Simulink's names).{hint}",
                                 key=f"{key}.{k}")
        inline = bool(values.get("t")) or bool(values.get("values"))
        if values["file"] and inline:
            raise InputError(f"`{key}` has both `file` and `t`/`values`; keep one: the samples come from the file or "
                             "from the experiment file.", key=f"{key}.file")
        if inline:
            t, u = list(values.get("t") or ()), list(values.get("values") or ())
            if ctx.max_rows and len(t) > ctx.max_rows:
                raise InputError(f"`{key}.t` has {len(t):,} samples; the budget is {ctx.max_rows:,} rows per input "
                                 "table (raise it with `odelab run --limit table_rows=N` if you mean it).",
                                 key=f"{key}.t")
            try:
                return cls(t, u, interpolation=values["interpolation"], extrapolation=values["extrapolation"])
            except InputError as exc:
                raise InputError(f"`{key}`: {exc.message[:1].lower() + exc.message[1:]}", key=key) from None
        if not values["file"]:
            raise InputError(f"`{key}` needs its samples: `file` (a CSV of t and u) or `t` and `values` (lists of "
                             "numbers).", key=f"{key}.file")
        csv_path = ctx.resolve_file(values["file"], f"{key}.file")
        if not csv_path.is_file():
            raise InputError(f"`{key}.file`: {values['file']!r} does not exist (looked for {csv_path}).",
                             key=f"{key}.file")
        try:
            return cls.from_csv(csv_path, max_rows=ctx.max_rows, interpolation=values["interpolation"],
                                extrapolation=values["extrapolation"])
        except InputError as exc:  # named from the experiment file, which is what the user runs
            text = exc.message[:1].lower() + exc.message[1:]
            if ctx.max_rows and text.startswith("the table file has more than"):
                text += (f" The budget is {ctx.max_rows:,} rows per input table (each row is a breakpoint at which "
                         f"the solver restarts); raise it with `odelab run --limit table_rows=N` if you mean it.")
            raise InputError(f"`{key}.file` {values['file']!r}: {text}", key=f"{key}.file") from None

    @classmethod
    def describe(cls, name: str, values: Mapping[str, Any]) -> str:
        if values.get("file"):
            return f"{name}: table {values.get('file')}"
        return f"{name}: table of {len(values.get('t') or ())} samples"

    def compiled_reason(self) -> str | None:
        return None

    def numba_source(self, slot) -> str:
        t, u = slot(*self.t.tolist()), slot(*self.values.tolist())  # each stored as one slice (.span)
        return f"_np.interp(_tu, {t.span}, {u.span})"

    def __post_init__(self):
        try:
            t = np.array(self.t, dtype=float)
            u = np.array(self.values, dtype=float)
        except (TypeError, ValueError):
            raise InputError(
                "`Table.t` and `Table.values` must be 1-D arrays of real numbers; got "
                f"{self.t!r} and {self.values!r}.",
                key="Table",
            ) from None
        if t.ndim != 1 or u.ndim != 1:
            raise InputError(
                f"`Table.t` and `Table.values` must be 1-D; got shapes {t.shape} and {u.shape}.",
                key="Table",
            )
        if t.size != u.size:
            raise InputError(
                f"`Table.t` has {t.size} samples but `Table.values` has {u.size}: give one value "
                "per time.",
                key="Table",
            )
        if t.size == 0:
            raise InputError("A Table needs at least one sample; got none.", key="Table")
        for name, arr in (("t", t), ("values", u)):
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise InputError(
                    f"`Table.{name}` must be finite; sample {bad[0]} is {float(arr[bad[0]])!r}.",
                    key=f"Table.{name}",
                )
        steps = np.diff(t)
        bad = np.flatnonzero(steps <= 0)
        if bad.size:
            i = int(bad[0])
            raise InputError(
                f"`Table.t` must be strictly increasing; sample {i + 1} (t = {float(t[i + 1])!r}) does "
                f"not come after sample {i} (t = {float(t[i])!r}). Sort the samples, and model a jump "
                "with a Step added to the table.",
                key="Table.t",
            )
        if self.interpolation not in INTERPOLATIONS:
            raise InputError(f"`Table.interpolation` is {self.interpolation!r}; use one of "
                             f"{', '.join(repr(m) for m in INTERPOLATIONS)}.", key="Table.interpolation")
        if self.extrapolation not in EXTRAPOLATIONS:
            raise InputError(f"`Table.extrapolation` is {self.extrapolation!r}; use one of "
                             f"{', '.join(repr(m) for m in EXTRAPOLATIONS)}.", key="Table.extrapolation")
        if t.size < 2 and (self.interpolation != "linear" or self.extrapolation != "clip"):
            raise InputError(f"A Table with interpolation {self.interpolation!r} or extrapolation "
                             f"{self.extrapolation!r} needs at least two samples.", key="Table")
        t.setflags(write=False)
        u.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "values", u)
        spline = spline_pieces(t, u) if self.interpolation == "cubic-spline" else None
        object.__setattr__(self, "_spline", spline)

    @classmethod
    def from_csv(cls, path: str | Path, *, label: str | None = None, max_rows: int | None = None,
                 interpolation: str = "linear", extrapolation: str = "clip") -> Table:
        # (messages quote a line only once the file has shown itself a table: a path pointed at
        # /etc/shadow must not print a line of it)
        """Read two columns (t, u) from a CSV file, with an optional header line.

        Commas, semicolons, tabs or spaces separate the columns; blank lines and lines that
        start with ``#`` are skipped. The label is the header of the second column, if any.
        """
        path = Path(path)
        try:
            raw = path.read_bytes()
        except OSError as exc:
            raise InputError(f"Cannot read the table file: {exc.strerror}.", source=str(path)) from None
        if raw.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in raw[:200]:
            raise InputError("The table file is UTF-16 or binary, not text; save it as CSV UTF-8 (in Excel: "
                             "Save as, CSV UTF-8).", source=str(path))
        try:
            text = raw.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise InputError(f"The table file is not UTF-8 text (byte {exc.start}); save it as CSV UTF-8 (in "
                             "Excel: Save as, CSV UTF-8).", source=str(path)) from None
        times: list[float] = []
        vals: list[float] = []
        header: list[str] | None = None
        for number, line in enumerate(text.splitlines(), start=1):
            stripped = line.strip()
            if not stripped or stripped.startswith("#"):
                continue
            if decimal_comma_line(stripped):
                raise InputError(f"line {number} writes its numbers with decimal commas "
                                 f"({_quoted_line(stripped, [None])}): {DECIMAL_COMMA_FIX}.", source=str(path))
            cells = _split_row(stripped)
            try:
                numbers = [float(cell) for cell in cells]
            except ValueError:
                if not times and header is None:
                    header = cells
                    continue
                raise InputError(
                    f"line {number}: expected two numbers (t, u); got {_quoted_line(stripped, times)}.",
                    source=str(path),
                ) from None
            if len(numbers) != 2:
                raise InputError(
                    f"line {number}: expected two columns (t, u); got {len(numbers)}"
                    f"{': ' + _quoted_line(stripped, times) if times else ''}.",
                    source=str(path),
                )
            times.append(numbers[0])
            vals.append(numbers[1])
            if max_rows and len(times) > max_rows:  # stop reading: the caller's budget says why
                raise InputError(f"The table file has more than {max_rows:,} rows.", source=str(path))
        if not times:
            raise InputError("The table file has no samples (two columns t, u).", source=str(path))
        if label is None:
            label = header[1] if header and len(header) == 2 else path.stem
        try:
            return cls(times, vals, label, interpolation, extrapolation)
        except InputError as exc:
            raise exc.located(source=str(path))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Table):
            return NotImplemented
        return (
            np.array_equal(self.t, other.t)
            and np.array_equal(self.values, other.values)
            and self.label == other.label
            and (self.interpolation, self.extrapolation) == (other.interpolation, other.extrapolation)
        )

    def __hash__(self) -> int:
        return hash((self.t.tobytes(), self.values.tobytes(), self.label, self.interpolation, self.extrapolation))

    def __repr__(self) -> str:
        label = f", label={self.label!r}" if self.label else ""
        return f"Table({self.t.size} samples, t from {float(self.t[0])!r} to {float(self.t[-1])!r}{label})"

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        if self.interpolation == "linear" and self.extrapolation == "clip":
            return _shaped(t, np.interp(t, self.t, self.values))
        return _shaped(t, interpolate_1d(t, self.t, self.values, self.interpolation, self.extrapolation,
                                         spline=self._spline))

    def _slopes(self) -> np.ndarray:
        """Slope on (-inf, t_0), each segment, and (t_last, inf): size n + 1."""
        inner = np.diff(self.values) / np.diff(self.t)
        if self.extrapolation == "linear" and inner.size:
            return np.concatenate([inner[:1], inner, inner[-1:]])
        return np.concatenate([[0.0], inner, [0.0]])

    def breakpoints(self, t0: float, tf: float) -> np.ndarray:
        t, u = self.t, self.values
        if self.interpolation == "flat":  # jumps where the held value changes
            times = t[1:][np.diff(u) != 0]
            if self.extrapolation == "linear":
                times = np.concatenate([t[:1], times, t[-1:]])
        elif self.interpolation == "nearest":
            times = (0.5 * (t[1:] + t[:-1]))[np.diff(u) != 0]
            if self.extrapolation == "linear":
                times = np.concatenate([t[:1], times, t[-1:]])
        elif self.interpolation == "cubic-spline":
            times = t  # the third derivative jumps at the knots, the first at the ends (clip)
        else:
            slopes = self._slopes()
            # the slope changes at sample i when the segments on either side differ
            times = t[slopes[1:] != slopes[:-1]]
        return _inside(np.unique(times), t0, tf)

    def exact_terms(self) -> ExactForm | None:
        if self.interpolation != "linear":
            return None  # held, nearest and spline tables are simulated (restarted at their breakpoints)
        t, u, slopes = self.t, self.values, self._slopes()

        def generate(lo: float, hi: float) -> tuple[Piece, ...]:
            # only the samples around the window: a long table gives few pieces
            i0 = max(int(np.searchsorted(t, lo, side="right")) - 1, 0)
            i1 = min(int(np.searchsorted(t, hi, side="right")), t.size - 1)
            first = (Term(float(u[i0])),) if not slopes[0] else (Term(float(u[0])), Term(float(slopes[0]),
                                                                                             float(t[0]), 1))
            pieces = [Piece(-math.inf, float(t[i0]), first if i0 == 0 else (Term(float(u[i0])),))]
            for i in range(i0, i1):
                terms = (Term(float(u[i])), Term(float(slopes[i + 1]), float(t[i]), 1))
                pieces.append(Piece(float(t[i]), float(t[i + 1]), terms))
            # constant (or the last segment continued) after the last sample; when t[i1] > hi
            # this piece lies past the window
            last = (Term(float(u[i1])),) if not slopes[-1] or i1 != t.size - 1 else (
                Term(float(u[i1])), Term(float(slopes[-1]), float(t[i1]), 1))
            pieces.append(Piece(float(t[i1]), math.inf, last))
            return tuple(pieces)

        return ExactForm(generate)


def _split_row(line: str) -> list[str]:
    for sep in (",", ";", "\t"):
        if sep in line:
            return [cell.strip() for cell in next(csv.reader([line], delimiter=sep))]
    return line.split()


@dataclass(frozen=True)
class Function(Signal):
    """Any callable of t, e.g. a compiled expression of an experiment file.

    ``fun`` should accept an array of times and return an array of the same shape; a
    function that only takes floats (``math.sin``) is evaluated point by point instead.
    odelab knows nothing about its discontinuities: no breakpoints, no exact form.
    """

    fun: Callable[[Any], Any]
    label: str = ""

    def __post_init__(self):
        if not callable(self.fun):
            raise InputError(f"`Function.fun` must be callable; got {self.fun!r}.", key="Function.fun")

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        try:
            out = np.asarray(self.fun(t), dtype=float)
        except (TypeError, ValueError):
            out = None
        if out is None or (out.shape != t.shape and out.ndim != 0):
            out = np.array([float(self.fun(float(ti))) for ti in t.ravel()]).reshape(t.shape)
        return _shaped(t, out)

    def __repr__(self) -> str:
        if self.label:
            return f"Function({self.label!r})"
        return f"Function({getattr(self.fun, '__name__', type(self.fun).__name__)})"

    def compiled_reason(self) -> str | None:
        return "a Python function of t (an experiment file's `expression` input is compiled; a callable is not)"


@dataclass(frozen=True, repr=False)
class Expression(Function):
    """u = an expression of t and the parameters, as an experiment file writes it (``type = "expression"``).

    ``text``, ``key`` and ``params`` are the checked expression, its key path and the
    parameter values it was compiled with: the compiled backend generates it from them.
    """

    TOML: ClassVar[str] = "expression"
    KEYS: ClassVar[Mapping[str, SignalKey]] = {"expression": SignalKey(None, kind="expression", unit="u")}

    text: str = ""
    key: str = ""
    params: Mapping[str, float] | None = None

    @classmethod
    def from_toml(cls, values: Mapping[str, Any], ctx: SignalContext) -> Expression:
        from odelab import expressions

        params = dict(ctx.params)
        text = str(values["expression"])
        compiled = expressions.compile_expression(values["expression"], names=["t", *params],
                                                  key=f"{ctx.key}.expression")

        def expression_signal(t, _e=compiled, _p=params):
            return _e(t=t, **_p)

        return cls(expression_signal, label=text, text=text, key=f"{ctx.key}.expression", params=params)

    @classmethod
    def describe(cls, name: str, values: Mapping[str, Any]) -> str:
        return f"{name} = {values.get('expression')}"

    def compiled_reason(self) -> str | None:
        return None

    def numba_source(self, slot) -> str:
        from odelab.expressions import parse_expression
        from odelab.solvers.compiled.codegen import expression_source

        params = dict(self.params or {})
        parsed = parse_expression(self.text, key=self.key, names=["t", *params])  # a parameter `e` shadows e
        used = [name for name in params if name in set(parsed.names)]
        rename = {"t": "_tu", **dict(zip(used, slot(*(params[name] for name in used))))}
        return f"({expression_source(parsed, rename)})"


@dataclass(frozen=True)
class Scaled(Signal):
    """u(t) = gain * signal(t)."""

    gain: float
    signal: Signal

    def compiled_reason(self) -> str | None:
        return self.signal.compiled_reason()

    def numba_source(self, slot) -> str:
        (gain,) = slot(self.gain)
        return f"({gain} * {self.signal.numba_source(slot)})"

    def __post_init__(self):
        object.__setattr__(self, "gain", _real("Scaled", "gain", self.gain))
        object.__setattr__(self, "signal", as_signal(self.signal, name="Scaled.signal"))

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        return _shaped(t, self.gain * np.asarray(self.signal(t)))

    def breakpoints(self, t0: float, tf: float) -> np.ndarray:
        return self.signal.breakpoints(t0, tf) if self.gain else np.empty(0)

    def exact_terms(self) -> ExactForm | None:
        form = self.signal.exact_terms()
        return None if form is None else form.scaled(self.gain)


@dataclass(frozen=True)
class Sum(Signal):
    """u(t) = sum of the ``terms`` (signals; numbers become Constants). Nested sums are flattened."""

    terms: tuple[Signal, ...]

    def __post_init__(self):
        if isinstance(self.terms, (Signal, str)) or not isinstance(self.terms, Iterable):
            raise InputError(
                f"`Sum.terms` must be a sequence of signals; got {self.terms!r}.", key="Sum.terms"
            )
        flat: list[Signal] = []
        for i, item in enumerate(self.terms):
            item = as_signal(item, name=f"Sum.terms[{i}]")
            flat.extend(item.terms if isinstance(item, Sum) else (item,))
        object.__setattr__(self, "terms", tuple(flat))

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        out = np.zeros(t.shape)
        for term in self.terms:
            out = out + term(t)
        return _shaped(t, out)

    def breakpoints(self, t0: float, tf: float) -> np.ndarray:
        parts = [term.breakpoints(t0, tf) for term in self.terms]
        return np.unique(np.concatenate(parts)) if parts else np.empty(0)

    def compiled_reason(self) -> str | None:
        return next((r for r in (term.compiled_reason() for term in self.terms) if r), None)

    def numba_source(self, slot) -> str:
        text = "0.0"  # Sum.__call__: out = zeros; out = out + term(t), term by term
        for term in self.terms:
            text = f"({text} + {term.numba_source(slot)})"
        return text

    def exact_terms(self) -> ExactForm | None:
        forms = [term.exact_terms() for term in self.terms]
        if any(form is None for form in forms):
            return None
        if not forms:
            return Constant(0.0).exact_terms()
        return ExactForm.sum(forms)


# -- coercion ------------------------------------------------------------------------------


# the types of experiment files, in the order their messages list them
for _cls in (Step, Ramp, Sine, Pulse, Table, Expression, Constant):
    register_signal(_cls)
del _cls


def as_signal(value: Any, *, name: str = "u") -> Signal:
    """A Signal as is, a number as a :class:`Constant`, a callable as a :class:`Function`."""
    if isinstance(value, Signal):
        return value
    if _is_real(value):
        return Constant(float(value))
    if callable(value):
        return Function(value)
    raise InputError(
        f"`{name}` must be a signal (Step, Ramp, Sine, ...), a number or a function of t; "
        f"got {value!r}.",
        key=name,
    )


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
