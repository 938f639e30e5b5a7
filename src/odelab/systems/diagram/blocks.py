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

from typing import ClassVar

import numpy as np

from odelab.exceptions import InputError
from odelab.expressions import compile_vector
from odelab.systems.diagram.base import (BLOCKS, REQUIRED, ZC_KEY, Block, BlockError, Key, _broadcast_width, _column,
                                         _real, _scalar, controller_canonical, polynomial_pair, register)

__all__ = ["BLOCKS", "REQUIRED", "ZC_KEY", "Block", "BlockError", "Key", "controller_canonical", "polynomial_pair", "Source", "Clock", "Gain", "Sum", "Product", "Integrator",
           "StateSpaceBlock", "TransferFcn", "Saturation", "DeadZone", "Fcn", "Mux", "Demux", "block_class", "register"]

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


@register
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


@register
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


@register
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


@register
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


@register
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


@register
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


@register
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


@register
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


@register
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


@register
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


@register
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



@register
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


def block_class(type_name: str) -> type[Block]:
    return BLOCKS[type_name]


# The block families in their own modules register themselves (each imports only base.py);
# importing them here is what fills BLOCKS.
from odelab.systems.diagram import (derivative, discrete, noise, ratelimit, stop, switching, tables,  # noqa: E402,F401
                                   transport)
