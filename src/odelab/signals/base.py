"""What a signal is and how signals combine: the Signal base class with its arithmetic (sums,
scalings, numbers as Constants, callables as Functions), the exact piecewise form (Term, Piece,
ExactForm) and the registry of the signal types experiment files name."""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from numbers import Real
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from odelab.exceptions import InputError

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


