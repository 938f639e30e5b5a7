"""The blocks of a diagram: one small class per block type, with a common port interface.

Each block declares what it is once (as bdsim's blocks do): its TOML ``type`` name, its keys
with their kinds and defaults, how many inputs it takes, whether it is linear, and how it
computes its outputs and (if it holds state) its state derivative. Nothing else in odelab
lists block types: the experiment loader, the messages, the drawing and the report read
:data:`BLOCKS`. A source block wraps an :mod:`odelab.signals` signal (every input signal type
of experiment files is a source, and ``clock`` is t).

Signals between blocks are arrays whose axis 0 is the signal's width (a scalar signal has
width 1), so the same code evaluates one point (shape (w,)) or many at once (shape (w, N)),
and accepts complex values for complex-step linearisation: every decision (saturation,
limits, dead zone) is taken on real parts, so the derivative through it is exact.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from odelab.exceptions import InputError

__all__ = ["BLOCKS", "Block", "BlockError", "Key", "Source", "Clock", "Gain", "Sum", "Product", "Integrator",
           "StateSpaceBlock", "TransferFcn", "Saturation", "DeadZone", "Fcn", "Mux", "Demux", "block_class"]

REQUIRED = object()


class BlockError(InputError):
    """A block's parameters or wiring are wrong; ``key`` is the block's key (e.g. ``signs``)."""


@dataclass(frozen=True)
class Key:
    """One key a block type takes: its kind, default and meaning (for messages and the README).

    ``kind`` is ``number``, ``numbers`` (a number or a list), ``matrix``, ``text`` (a string
    taken as is), ``expression`` (expression-language text) or ``count`` (a whole number).
    """

    kind: str
    default: Any = REQUIRED
    doc: str = ""


def _real(v):
    return v.real if np.iscomplexobj(v) else v


#: the key every block with switching functions takes
ZC_KEY = Key("bool", True, "locate the instants the output's formula changes (Simulink's zero-crossing "
                           "detection); false steps over them")


def _column(mode, v):
    """A per-element mode shaped to broadcast against a signal ``v`` of shape (w,) or (w, N)."""
    return np.reshape(mode, (-1,) + (1,) * (np.ndim(v) - 1))


class Block:
    """Base class: a block with named inputs (references to other blocks' outputs)."""

    TYPE: ClassVar[str] = ""
    KEYS: ClassVar[dict[str, Key]] = {}
    INPUTS: ClassVar[tuple[int, int | None]] = (1, 1)  # least and most number of inputs
    LINEAR: ClassVar[bool] = True
    SOURCE: ClassVar[bool] = False
    DOC: ClassVar[str] = ""
    SHAPE: ClassVar[str] = "box"  # Graphviz node shape of the drawing
    #: the block has switching functions (zero crossings, :mod:`~odelab.systems.diagram.zerocross`)
    ZC: ClassVar[bool] = False
    #: the block's states are discrete (updated at its sample hits, held between them)
    DISCRETE: ClassVar[bool] = False
    #: the block needs the hybrid driver even with zero-crossing detection off (a relay's memory)
    STATEFUL_MODE: ClassVar[bool] = False

    #: the block's mode, held during a step by the hybrid driver; None: decided from the inputs
    mode = None

    def __init__(self, *, input: str | None = None, inputs: Sequence[str] | None = None, **values: Any):
        if input is not None and inputs is not None:
            raise BlockError("give either `input` or `inputs`, not both.", key="inputs")
        refs = () if input is None and inputs is None else ((input,) if input is not None else tuple(inputs))
        for i, ref in enumerate(refs):
            if not isinstance(ref, str) or not ref:
                raise BlockError(f"input {i + 1} must be the name of a block; got {ref!r}.", key="inputs")
        self.inputs: tuple[str, ...] = refs
        for name in values:
            if name not in self.KEYS:
                known = ", ".join(["input", "inputs", *self.KEYS]) if not self.SOURCE else ", ".join(self.KEYS)
                raise BlockError(f"`{name}` does not apply to a {self.TYPE} block; it takes {known}.", key=name)
        self.params: dict[str, Any] = {}
        for name, key in self.KEYS.items():
            value = values.get(name, key.default)
            if value is REQUIRED:
                raise BlockError(f"`{name}` is required for a {self.TYPE} block ({key.doc}).", key=name)
            self.params[name] = value
        lo, hi = self.INPUTS
        n = len(self.inputs)
        if self.SOURCE and n:
            raise BlockError(f"a {self.TYPE} block is a source: it takes no `input`.", key="input")
        if not self.SOURCE and not (lo <= n and (hi is None or n <= hi)):
            want = str(lo) if lo == hi else (f"at least {lo}" if hi is None else f"{lo} to {hi}")
            what = "`input = \"name\"`" if hi == 1 else "`inputs = [...]`"
            raise BlockError(f"a {self.TYPE} block takes {want} input{'s' if want != '1' else ''}; got {n}: "
                             f"give {what}.", key="inputs" if n > 1 or hi != 1 else "input")
        self.check()

    # -- what subclasses declare or override -----------------------------------------------------

    def check(self) -> None:
        """Check the parameters (after defaults are filled in)."""

    def ports(self) -> tuple[str, ...]:
        """Names of the output ports; a block with one output has the single port ``""``."""
        return ("",)

    def fixed_widths(self) -> list[int] | None:
        """Output widths known from the parameters alone (blocks without direct feedthrough)."""
        return None

    def setup(self, widths: list[int]) -> list[int]:
        """Check the input widths; return the output width of each port."""
        return [max(widths)] if widths else [1]

    @property
    def feedthrough(self) -> bool:
        """Whether the outputs depend on the inputs at the same instant (direct feedthrough)."""
        return not self.SOURCE

    @property
    def linear(self) -> bool:
        return self.LINEAR

    nstates: int = 0

    def state_names(self, name: str) -> list[str]:
        return [name] if self.nstates == 1 else [f"{name}.x{i + 1}" for i in range(self.nstates)]

    def initial_state(self) -> np.ndarray:
        return np.zeros(self.nstates)

    def outputs(self, t, x, u: list, cplx: bool = False) -> list:
        raise NotImplementedError

    def derivative(self, t, x, u: list):
        return np.zeros((0,) + np.shape(t))

    def describe(self) -> str:
        """A short label for drawings and reports, e.g. ``gain 1/m``."""
        return self.TYPE

    def label(self, name: str) -> str:
        """The text of the block's node in the drawing (lines separated by newlines)."""
        return f"{name}\n{self.describe()}"

    def node(self, name: str) -> tuple[str, str, dict]:
        """How the drawing shows the block: (label, Graphviz shape, other node attributes)."""
        return self.label(name), self.SHAPE, {}

    def input_mark(self, i: int) -> str | None:
        """The mark drawn at the head of the arrow into input ``i`` (a sum's sign), or None."""
        return None

    # -- the compiled backend (:mod:`~odelab.systems.diagram.codegen`) -------------------------

    @property
    def generated(self) -> bool:
        """Whether the compiled backend writes this block out (it overrides generate_outputs)."""
        return type(self).generate_outputs is not Block.generate_outputs

    def generate_outputs(self, g, name: str, ins: list[str]) -> list[str]:
        """Write the block's outputs as numba lines with ``g`` (a codegen Writer), in the same
        order of operations as :meth:`outputs`; return one variable per port."""
        raise NotImplementedError

    def generate_derivative(self, g, name: str, ins: list[str]) -> None:
        """Write the block's state derivatives (``g.derivative``), as :meth:`derivative`."""

    # -- zero crossings (blocks with ZC = True) ---------------------------------------------------

    @property
    def zero_crossing(self) -> bool:
        """Whether this block's switching instants are located (its ``zero_crossing`` key)."""
        return bool(self.ZC and self.params.get("zero_crossing", True))

    def zc_values(self, x, u) -> np.ndarray:
        """The block's switching functions at one point (a fixed number of them)."""
        raise NotImplementedError

    def zc_mode(self, signs: np.ndarray, x, u):
        """The mode the signs of the switching functions (each +1 or -1) select."""
        raise NotImplementedError

    def zc_directions(self, mode) -> np.ndarray:
        """Per switching function: the direction of a crossing that leaves ``mode`` (+1 rising,
        -1 falling, 0 either) or NaN where the function cannot leave it (not watched)."""
        raise NotImplementedError

    def zc_reset(self, x, mode):
        """The block's state on entering ``mode`` (e.g. an integrator put exactly at its limit)."""
        return x

    def __repr__(self) -> str:
        inputs = f", inputs={list(self.inputs)}" if self.inputs else ""
        params = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"{type(self).__name__}({params}{inputs})"


def _scalar(block: Block, name: str) -> float:
    value = block.params[name]
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise BlockError(f"`{name}` must be a number; got {value!r}.", key=name) from None
    if not np.isfinite(out):
        raise BlockError(f"`{name}` must be finite; got {value!r}.", key=name)
    return out


def _broadcast_width(block: Block, widths: list[int]) -> int:
    wide = {w for w in widths if w != 1}
    if len(wide) > 1:
        raise BlockError(f"the inputs of a {block.TYPE} block have different widths ({', '.join(map(str, widths))}); "
                         "scalar inputs combine with vectors, vectors must match.", key="inputs")
    return wide.pop() if wide else 1


# --- sources ------------------------------------------------------------------------------


class Source(Block):
    """A signal source: any input signal of experiment files (step, ramp, sine, pulse, table...).

    ``signal`` is an :mod:`odelab.signals` signal; ``kind`` the TOML type it came from.
    """

    SOURCE = True
    TYPE = "source"
    KEYS: ClassVar[dict[str, Key]] = {}

    def __init__(self, signal, *, kind: str = "signal", label: str = ""):
        super().__init__()
        self.signal = signal
        self.kind = kind
        self.label = label

    def outputs(self, t, x, u, cplx=False):
        return [np.reshape(np.asarray(self.signal(t), dtype=float), (1,) + np.shape(t))]

    def describe(self) -> str:
        return self.label or self.kind

    def node(self, name):
        return f"{name}\n{self.describe()}", "box", {}

    def __repr__(self) -> str:
        return f"Source({self.signal!r})"


class Clock(Block):
    """Simulink's Clock: the simulation time t (a source)."""

    SOURCE = True
    TYPE = "clock"
    DOC = "the simulation time t"

    def node(self, name):
        return f"{name}\n{self.describe()}", "box", {}

    def outputs(self, t, x, u, cplx=False):
        return [np.reshape(np.asarray(t, dtype=float), (1,) + np.shape(t))]


# --- static blocks ------------------------------------------------------------------------------


class Gain(Block):
    """y = K u: a scalar gain (elementwise) or a matrix gain K @ u."""

    TYPE = "gain"
    KEYS = {"gain": Key("matrix", doc="a number, or a matrix [[...]] for K @ u")}
    DOC = "y = gain * u"

    def check(self):
        K = np.asarray(self.params["gain"], dtype=float)
        if K.ndim > 2 or not np.all(np.isfinite(K)):
            raise BlockError(f"`gain` must be a finite number or matrix; got {self.params['gain']!r}.", key="gain")
        self.K = K

    def setup(self, widths):
        if self.K.ndim == 2:
            if widths[0] != self.K.shape[1]:
                raise BlockError(f"`gain` is {self.K.shape[0]}x{self.K.shape[1]} but its input has width "
                                 f"{widths[0]}; K needs {widths[0]} columns.", key="gain")
            return [self.K.shape[0]]
        if self.K.ndim == 1 and widths[0] not in (1, self.K.size):
            raise BlockError(f"`gain` has {self.K.size} entries but its input has width {widths[0]}.", key="gain")
        return [max(widths[0], self.K.size)]

    def outputs(self, t, x, u, cplx=False):
        v = u[0]
        if self.K.ndim == 2:
            return [np.tensordot(self.K, v, axes=(1, 0))]
        K = self.K if self.K.ndim == 0 else self.K.reshape((-1,) + (1,) * (v.ndim - 1))
        return [K * v]

    def describe(self):
        text = self.params.get("_text", self.params["gain"])
        return f"gain {text}" if self.K.ndim == 0 else "gain K"

    @property
    def generated(self):
        return self.K.ndim == 0

    def generate_outputs(self, g, name, ins):
        return [g.var(f"{g.number(self.K)} * {ins[0]}")]

    def node(self, name):
        k = getattr(self, "texts", {}).get("gain", self.params["gain"])
        label = f"{k}" if not isinstance(k, list) else "K"
        return label, "triangle", {"orientation": 270, "margin": 0, "xlabel": name}


class Sum(Block):
    """y = ±u1 ± u2 ...: Simulink's Sum with its list of signs (``"+--"``; ``|`` is a spacer)."""

    TYPE = "sum"
    INPUTS = (1, None)
    KEYS = {"signs": Key("text", None, "one + or - per input, e.g. \"+--\"")}
    DOC = "y = sum of the inputs with signs"

    def check(self):
        signs = self.params["signs"]
        if signs is None:
            signs = "+" * len(self.inputs)
        if not isinstance(signs, str) or set(signs) - set("+-|"):
            raise BlockError(f"`signs` must be a string of + and - (one per input), e.g. \"+-\"; got {signs!r}.",
                             key="signs")
        self.signs = [1.0 if c == "+" else -1.0 for c in signs if c != "|"]
        if len(self.signs) != len(self.inputs):
            raise BlockError(f"`signs` is {signs!r} ({len(self.signs)} sign{'s' if len(self.signs) != 1 else ''}) "
                             f"but there {'is' if len(self.inputs) == 1 else 'are'} {len(self.inputs)} input"
                             f"{'s' if len(self.inputs) != 1 else ''} ({', '.join(self.inputs)}); give one sign "
                             "per input.", key="signs")

    def setup(self, widths):
        return [_broadcast_width(self, widths)]

    def outputs(self, t, x, u, cplx=False):
        out = self.signs[0] * u[0]
        for s, v in zip(self.signs[1:], u[1:]):
            out = out + v if s > 0 else out - v
        return [out]

    def describe(self):
        return "sum " + "".join("+" if s > 0 else "-" for s in self.signs)

    def generate_outputs(self, g, name, ins):
        return [g.accumulate(f"{g.number(self.signs[0])} * {ins[0]}",
                             (("+" if s > 0 else "-", v) for s, v in zip(self.signs[1:], ins[1:])))]

    def node(self, name):
        return "Σ", "circle", {"width": 0.45, "fixedsize": True, "xlabel": name}

    def input_mark(self, i):
        return "+" if self.signs[i] > 0 else "−"


class Product(Block):
    """y = u1 * u2 ... (``ops = "*/"`` divides by the inputs marked /), elementwise."""

    TYPE = "product"
    INPUTS = (1, None)
    LINEAR = False
    KEYS = {"ops": Key("text", None, "one * or / per input, e.g. \"*/\"")}
    DOC = "y = product of the inputs"

    def check(self):
        ops = self.params["ops"] or "*" * len(self.inputs)
        if not isinstance(ops, str) or set(ops) - set("*/") or len(ops) != len(self.inputs):
            raise BlockError(f"`ops` must be one * or / per input ({len(self.inputs)}), e.g. \"*/\"; got {ops!r}.",
                             key="ops")
        self.ops = ops

    def setup(self, widths):
        return [_broadcast_width(self, widths)]

    def outputs(self, t, x, u, cplx=False):
        out = u[0] if self.ops[0] == "*" else 1.0 / u[0]
        for op, v in zip(self.ops[1:], u[1:]):
            out = out * v if op == "*" else out / v
        return [out]

    def describe(self):
        return "product " + self.ops

    SHAPE = "circle"

    def input_mark(self, i):
        return "÷" if self.ops[i] == "/" else None

    def generate_outputs(self, g, name, ins):
        return [g.accumulate(ins[0] if self.ops[0] == "*" else f"(1.0 / {ins[0]})", zip(self.ops[1:], ins[1:]))]


class _Limits(Block):
    """Shared by saturation and dead zone: two thresholds, three modes per element (0 below
    ``lower``, 1 between, 2 above ``upper``); the switching functions are u - upper and u - lower."""

    LINEAR = False
    ZC = True

    def check(self):
        self.lo, self.hi = _scalar(self, "lower"), _scalar(self, "upper")
        if not self.lo < self.hi:
            raise BlockError(f"`lower` ({self.lo:g}) must be below `upper` ({self.hi:g}).", key="lower")

    def setup(self, widths):
        return [widths[0]]

    def _modes(self, v):
        """The mode of each element of v: held by the driver, else read off v."""
        if self.mode is not None:
            return _column(self.mode, v)
        r = _real(v)
        return np.where(r > self.hi, 2, np.where(r < self.lo, 0, 1))

    def zc_values(self, x, u):
        v = np.asarray(u[0], dtype=float).reshape(-1)
        return np.concatenate([v - self.hi, v - self.lo])

    def zc_mode(self, signs, x, u):
        w = signs.size // 2
        return np.where(signs[:w] > 0, 2, np.where(signs[w:] < 0, 0, 1))

    def zc_directions(self, mode):
        mode = np.asarray(mode)
        up = np.where(mode == 1, 1.0, np.where(mode == 2, -1.0, np.nan))  # u - upper
        down = np.where(mode == 1, -1.0, np.where(mode == 0, 1.0, np.nan))  # u - lower
        return np.concatenate([up, down])


class Saturation(_Limits):
    """y = min(max(u, lower), upper), as Simulink's Saturation (defaults -0.5 and 0.5)."""

    TYPE = "saturation"
    KEYS = {"lower": Key("number", -0.5, "the lower limit"), "upper": Key("number", 0.5, "the upper limit"),
            "zero_crossing": ZC_KEY}
    DOC = "y = u limited to [lower, upper]"

    def outputs(self, t, x, u, cplx=False):
        v = u[0]
        m = self._modes(v)
        return [np.where(m == 2, self.hi, np.where(m == 0, self.lo, v))]

    def describe(self):
        return f"saturation [{self.lo:g}, {self.hi:g}]"

    def generate_outputs(self, g, name, ins):  # detection off: the mode read off u, as outputs()
        lo, hi, v = g.number(self.lo), g.number(self.hi), ins[0]
        return [g.var(f"({hi} if {v} > {hi} else ({lo} if {v} < {lo} else {v}))")]

    def label(self, name):
        return f"{name}\nsat [{self.lo:g}, {self.hi:g}]"


class DeadZone(_Limits):
    """y = 0 inside [lower, upper], u - upper above, u - lower below (Simulink's Dead Zone)."""

    TYPE = "dead-zone"
    KEYS = {"lower": Key("number", -0.5, "start of the dead zone"), "upper": Key("number", 0.5, "end of the dead zone"),
            "zero_crossing": ZC_KEY}
    DOC = "y = 0 inside [lower, upper], shifted u outside"

    def outputs(self, t, x, u, cplx=False):
        v = u[0]
        m = self._modes(v)
        return [np.where(m == 2, v - self.hi, np.where(m == 0, v - self.lo, 0.0 * v))]

    def describe(self):
        return f"dead zone [{self.lo:g}, {self.hi:g}]"

    def generate_outputs(self, g, name, ins):
        lo, hi, v = g.number(self.lo), g.number(self.hi), ins[0]
        return [g.var(f"(({v} - {hi}) if {v} > {hi} else (({v} - {lo}) if {v} < {lo} else 0.0 * {v}))")]

    def label(self, name):
        return f"{name}\ndead zone [{self.lo:g}, {self.hi:g}]"


class Fcn(Block):
    """y = f(u, t): an expression of ``u`` (one input; ``u1, u2...`` its elements) or of
    ``u1, u2...`` (several inputs), ``t`` and the parameters, as Simulink's Fcn block."""

    TYPE = "fcn"
    INPUTS = (1, None)
    LINEAR = False
    KEYS = {"expression": Key("expression", doc="e.g. \"sin(u)\" or \"u1*u2\"")}
    DOC = "y = expression of u (or u1, u2...) and t"

    def __init__(self, *, parameters: dict[str, float] | None = None, **kw):
        self.constants = dict(parameters or {})
        super().__init__(**kw)

    def setup(self, widths):
        from odelab.expressions import compile_vector

        total = sum(widths)
        names = ["u"] if total == 1 else []
        names += [f"u{i + 1}" for i in range(total)]
        args = ["t", *names]
        text = self.params["expression"]
        self._args = args
        # Unknown names and syntax errors are ExpressionErrors keyed `expression` (with a caret).
        self._f = compile_vector([text], args=args, constants=self.constants, keys=["expression"])
        self._fc = compile_vector([text], args=args, constants=self.constants, keys=["expression"],
                                  complex_step=True)
        return [1]

    def outputs(self, t, x, u, cplx=False):
        flat = [row for v in u for row in v]
        args = [t] + ([flat[0]] if len(flat) == 1 else []) + flat
        out = (self._fc if cplx else self._f)(*args)
        return [np.reshape(out, (1,) + np.shape(np.broadcast(*args)))]

    def describe(self):
        return f"f(u) = {self.params['expression']}"

    def label(self, name):
        return f"{name}\n{self.params['expression']}"


class Mux(Block):
    """y = [u1; u2; ...]: several signals into one vector."""

    TYPE = "mux"
    INPUTS = (1, None)
    DOC = "y = [u1; u2; ...]"

    def setup(self, widths):
        return [sum(widths)]

    def outputs(self, t, x, u, cplx=False):
        shape = np.broadcast_shapes(*(np.shape(v)[1:] for v in u))
        return [np.concatenate([np.broadcast_to(v, (v.shape[0],) + shape) for v in u], axis=0)]


class Demux(Block):
    """Splits a vector into its elements, addressed as ``name.1``, ``name.2``..."""

    TYPE = "demux"
    KEYS = {"outputs": Key("count", doc="how many elements, e.g. 2")}
    DOC = "splits a vector: name.1, name.2, ..."

    def check(self):
        n = self.params["outputs"]
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise BlockError(f"`outputs` must be a whole number of elements, at least 1; got {n!r}.", key="outputs")
        self.n = n

    def ports(self):
        return tuple(str(i + 1) for i in range(self.n))

    def setup(self, widths):
        if widths[0] != self.n:
            raise BlockError(f"`outputs` is {self.n} but the input has width {widths[0]}; they must agree.",
                             key="outputs")
        return [1] * self.n

    def outputs(self, t, x, u, cplx=False):
        return [u[0][i:i + 1] for i in range(self.n)]


# --- blocks with state --------------------------------------------------------------------------


class Integrator(Block):
    """x' = u, y = x; with ``lower``/``upper`` the state stays within them, as Simulink's
    saturating integrator (the derivative is zero at a limit while u pushes outward).

    With zero-crossing detection (a limited integrator's default) the instant the state reaches
    a limit, and the instant u turns back, are located: the modes are 0 (held at ``lower``),
    1 (free) and 2 (held at ``upper``), per element."""

    TYPE = "integrator"
    KEYS = {"initial": Key("numbers", 0.0, "the initial state, a number or a list"),
            "lower": Key("number", None, "lower limit of the state"),
            "upper": Key("number", None, "upper limit of the state"),
            "zero_crossing": ZC_KEY}
    DOC = "x' = u, y = x (optionally limited)"
    SHAPE = "box"

    def check(self):
        x0 = np.atleast_1d(np.asarray(self.params["initial"], dtype=float))
        if x0.ndim != 1 or not np.all(np.isfinite(x0)):
            raise BlockError(f"`initial` must be a finite number or list; got {self.params['initial']!r}.",
                             key="initial")
        self.x0 = x0
        self.nstates = x0.size
        self.lo = -np.inf if self.params["lower"] is None else _scalar(self, "lower")
        self.hi = np.inf if self.params["upper"] is None else _scalar(self, "upper")
        if not self.lo < self.hi:
            raise BlockError(f"`lower` ({self.lo:g}) must be below `upper` ({self.hi:g}).", key="lower")
        if np.any(x0 < self.lo) or np.any(x0 > self.hi):
            raise BlockError(f"`initial` ({self.params['initial']!r}) is outside the limits [{self.lo:g}, "
                             f"{self.hi:g}].", key="initial")

    @property
    def limited(self) -> bool:
        return bool(np.isfinite(self.lo) or np.isfinite(self.hi))

    @property
    def ZC(self):  # noqa: N802 - only a limited integrator switches
        return self.limited

    @property
    def linear(self):
        return not self.limited

    @property
    def feedthrough(self):
        return False

    def fixed_widths(self):
        return [self.nstates]

    def setup(self, widths):
        if widths[0] not in (1, self.nstates):
            raise BlockError(f"the input has width {widths[0]} but `initial` has {self.nstates} entries; give one "
                             "initial value per element.", key="initial")
        return [self.nstates]

    def initial_state(self):
        return self.x0.copy()

    def outputs(self, t, x, u, cplx=False):
        if not self.limited:
            return [x]
        r = _real(x)
        clamped = np.where(r > self.hi, self.hi, np.where(r < self.lo, self.lo, x))
        if self.mode is None:
            return [clamped]
        m = _column(self.mode, x)
        return [np.where(m == 2, self.hi, np.where(m == 0, self.lo, clamped))]

    def _input(self, u):
        return u[0] if u[0].shape[0] == self.nstates else np.broadcast_to(u[0], (self.nstates,) + u[0].shape[1:])

    def derivative(self, t, x, u):
        v = self._input(u)
        if not self.limited:
            return v
        if self.mode is not None:
            m = _column(self.mode, v)
            return np.where(m == 1, v, 0.0 * v)
        r, s = _real(x), _real(v)
        held = ((r >= self.hi) & (s > 0)) | ((r <= self.lo) & (s < 0))
        return np.where(held, 0.0 * v, v)

    def zc_values(self, x, u):
        v = np.asarray(self._input(u), dtype=float).reshape(-1)
        x = np.asarray(x, dtype=float).reshape(-1)
        return np.concatenate([x - self.hi, x - self.lo, v])

    def zc_mode(self, signs, x, u):
        n = self.nstates
        at_hi, at_lo, push = signs[:n] > 0, signs[n:2 * n] < 0, signs[2 * n:]
        return np.where(at_hi & (push > 0), 2, np.where(at_lo & (push < 0), 0, 1))

    def zc_directions(self, mode):
        mode = np.asarray(mode)
        free = mode == 1
        return np.concatenate([np.where(free, 1.0, np.nan), np.where(free, -1.0, np.nan),
                               np.where(mode == 2, -1.0, np.where(mode == 0, 1.0, np.nan))])

    def zc_reset(self, x, mode):
        mode = np.asarray(mode)
        return np.where(mode == 2, self.hi, np.where(mode == 0, self.lo, x))

    def describe(self):
        limits = f" [{self.lo:g}, {self.hi:g}]" if self.limited else ""
        return f"integrator 1/s{limits}"

    def generate_outputs(self, g, name, ins):
        x = g.state(name, 0)
        if self.limited:
            lo, hi = g.number(self.lo), g.number(self.hi)
            return [g.var(f"({hi} if {x} > {hi} else ({lo} if {x} < {lo} else {x}))")]
        return [g.var(x)]

    def generate_derivative(self, g, name, ins):
        x, v = g.state(name, 0), ins[0]
        if self.limited:
            lo, hi = g.number(self.lo), g.number(self.hi)
            held = f"(({x} >= {hi}) and ({v} > 0)) or (({x} <= {lo}) and ({v} < 0))"
            g.derivative(name, 0, f"(0.0 * {v}) if {held} else {v}")
        else:
            g.derivative(name, 0, v)

    def label(self, name):
        return f"{name}\n1/s" + (f"\n[{self.lo:g}, {self.hi:g}]" if self.limited else "")


class _Linear(Block):
    """Shared by the state-space and transfer-function blocks: x' = Ax + Bu, y = Cx + Du."""

    def _set(self, A, B, C, D):
        self.A, self.B, self.C, self.D = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (A, B, C, D))
        self.nstates = self.A.shape[0] if self.A.size else 0

    @property
    def feedthrough(self):
        return bool(np.any(self.D != 0))

    def fixed_widths(self):
        return None if self.feedthrough else [1] * len(self.ports())

    def setup(self, widths):
        m = self.D.shape[1]
        if sum(widths) != m:
            raise BlockError(f"the block has {m} input{'s' if m != 1 else ''} (columns of B and D) but its inputs "
                             f"have total width {sum(widths)}; connect {m} signal{'s' if m != 1 else ''} (or a mux "
                             f"of width {m}).", key="inputs")
        return [1] * len(self.ports())

    def initial_state(self):
        return np.zeros(self.nstates)

    def _u(self, u):
        return u[0] if len(u) == 1 else np.concatenate(
            [np.broadcast_to(v, (v.shape[0],) + np.broadcast_shapes(*(np.shape(w)[1:] for w in u))) for v in u])

    def outputs(self, t, x, u, cplx=False):
        y = np.tensordot(self.C, x, axes=(1, 0)) if self.nstates else 0.0
        if self.feedthrough:
            y = y + np.tensordot(self.D, self._u(u), axes=(1, 0))
        y = np.broadcast_to(y, (self.C.shape[0],) + np.shape(t)) if np.ndim(y) < 1 else y
        return [y[i:i + 1] for i in range(y.shape[0])]

    def derivative(self, t, x, u):
        return np.tensordot(self.A, x, axes=(1, 0)) + np.tensordot(self.B, self._u(u), axes=(1, 0))

    def generate_outputs(self, g, name, ins):  # y = C x (+ D u), one scalar port per output
        xs = [g.state(name, i) for i in range(self.nstates)]
        out = []
        for i in range(len(self.ports())):
            text = g.linear_part(self.C, i, xs) if self.nstates else "0.0"
            if self.feedthrough:
                text = f"({text} + {g.linear_part(self.D, i, ins)})"
            out.append(g.var(text))
        return out

    def generate_derivative(self, g, name, ins):
        xs = [g.state(name, i) for i in range(self.nstates)]
        for i in range(self.nstates):
            g.derivative(name, i, f"({g.linear_part(self.A, i, xs)} + {g.linear_part(self.B, i, ins)})")


class StateSpaceBlock(_Linear):
    """Simulink's State-Space block: x' = Ax + Bu, y = Cx + Du; outputs addressed ``name.y``."""

    TYPE = "state-space"
    INPUTS = (1, None)
    KEYS = {"A": Key("matrix", doc="n x n"), "B": Key("matrix", doc="n x m"), "C": Key("matrix", doc="p x n"),
            "D": Key("matrix", None, "p x m, default zeros"), "initial": Key("numbers", None, "x(0), default zeros"),
            "outputs": Key("names", None, "names of the outputs, default y1, y2..."),
            "states": Key("names", None, "names of the states, default x1, x2...")}
    DOC = "x' = Ax + Bu, y = Cx + Du"

    def check(self):
        from odelab.systems.statespace import StateSpace

        p = self.params
        try:
            ss = StateSpace(p["A"], p["B"], p["C"], p["D"], outputs=p["outputs"], states=p["states"])
        except InputError as exc:
            raise BlockError(exc.message, key=exc.key) from None
        self._set(ss.A, ss.B, ss.C, ss.D)
        self.output_names = tuple(ss.outputs)
        self.inner_states = tuple(ss.states)
        x0 = np.zeros(self.nstates) if p["initial"] is None else np.atleast_1d(np.asarray(p["initial"], dtype=float))
        if x0.shape != (self.nstates,):
            raise BlockError(f"`initial` has {x0.size} values but A has {self.nstates} states.", key="initial")
        self.x0 = x0

    def ports(self):
        return self.output_names

    def state_names(self, name):
        return [f"{name}.{s}" for s in self.inner_states]

    def initial_state(self):
        return self.x0.copy()

    def describe(self):
        return "state-space"

    def label(self, name):
        return f"{name}\nx' = Ax + Bu\ny = Cx + Du"



def polynomial_pair(params) -> tuple[np.ndarray, np.ndarray]:
    """A transfer function's ``num`` and ``den`` keys checked (finite coefficients, a nonzero
    denominator) with their leading zeros trimmed (a zero numerator is ``[0]``); the causality
    check, whose words differ between s and z, is the block's."""
    num = np.atleast_1d(np.asarray(params["num"], dtype=float))
    den = np.atleast_1d(np.asarray(params["den"], dtype=float))
    for key, c in (("num", num), ("den", den)):
        if c.ndim != 1 or not c.size or not np.all(np.isfinite(c)):
            raise BlockError(f"`{key}` must be a list of finite coefficients; got {params[key]!r}.", key=key)
    den = np.trim_zeros(den, "f")
    if not den.size:
        raise BlockError("`den` is all zeros; the denominator needs a nonzero coefficient.", key="den")
    num = np.trim_zeros(num, "f") if np.any(num) else np.zeros(1)
    return num, den


class TransferFcn(_Linear):
    """Simulink's Transfer Fcn: num(s)/den(s), coefficients in descending powers, as MATLAB's
    ``tf``; realised in MATLAB's controller canonical form (``tf2ss``)."""

    TYPE = "transfer-fcn"
    KEYS = {"num": Key("numbers", doc="numerator coefficients, descending powers"),
            "den": Key("numbers", doc="denominator coefficients, descending powers")}
    DOC = "y = num(s)/den(s) u"

    def check(self):
        num, den = polynomial_pair(self.params)
        if num.size > den.size:
            raise BlockError(f"the transfer function is improper (num has degree {num.size - 1}, den degree "
                             f"{den.size - 1}); a transfer-fcn block needs deg num <= deg den.", key="num")
        self.num, self.den = num, den
        A, B, C, D = controller_canonical(num, den)
        self._set(A, B, C, D)

    def ports(self):
        return ("",)

    def describe(self):
        return "transfer fcn"

    def label(self, name):
        num = " ".join(f"{c:g}" for c in self.num)
        den = " ".join(f"{c:g}" for c in self.den)
        return f"{name}\n[{num}] / [{den}]"


def controller_canonical(num: np.ndarray, den: np.ndarray):
    """MATLAB's ``tf2ss`` realisation of num/den (controller canonical form; its A's first
    row is -den[1:]/den[0]). num and den are coefficient arrays in descending powers."""
    num = np.asarray(num, dtype=float) / den[0]
    den = np.asarray(den, dtype=float) / den[0]
    n = den.size - 1
    num = np.concatenate([np.zeros(den.size - num.size), num])
    D = np.array([[num[0]]])
    if n == 0:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), D
    A = np.zeros((n, n))
    A[0, :] = -den[1:]
    A[1:, :-1] = np.eye(n - 1)
    B = np.zeros((n, 1))
    B[0, 0] = 1.0
    C = (num[1:] - num[0] * den[1:]).reshape(1, n)
    return A, B, C, D


# One registry: TOML type name -> block class. Source types (step, ramp, ...) are the input
# signal types of experiment files and are built from odelab.signals by the loader.
BLOCKS: dict[str, type[Block]] = {cls.TYPE: cls for cls in (
    Clock, Gain, Sum, Product, Integrator, StateSpaceBlock, TransferFcn, Saturation, DeadZone, Fcn, Mux, Demux)}


def register(cls: type[Block]) -> type[Block]:
    """Add a block class to :data:`BLOCKS` under its TYPE (the other block modules use it)."""
    BLOCKS[cls.TYPE] = cls
    return cls


def block_class(type_name: str) -> type[Block]:
    return BLOCKS[type_name]


# The blocks defined in their own modules join the registry here (after everything they import).
from odelab.systems.diagram import discrete as _discrete  # noqa: E402
from odelab.systems.diagram import switching as _switching  # noqa: E402
from odelab.systems.diagram import tables as _tables  # noqa: E402
from odelab.systems.diagram import ratelimit as _ratelimit  # noqa: E402
from odelab.systems.diagram import delay as _delay  # noqa: E402

for _cls in (_discrete.PID, _switching.Abs, _switching.Sign, _switching.Switch, _switching.Relay, _switching.MinMax,
             _discrete.ZeroOrderHold, _discrete.UnitDelay, _discrete.DiscreteTransferFcn, _discrete.DiscreteStateSpace,
             _discrete.DiscretePID, _tables.LookupTable, _ratelimit.RateLimiter, _delay.TransportDelay):
    register(_cls)
