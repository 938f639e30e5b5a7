"""Discrete blocks: zero-order-hold, unit-delay, discrete-transfer-fcn, discrete-state-space,
discrete-pid, each with a ``sample_time`` (seconds; ``[Ts, offset]``), as Simulink's.

Every one is a discrete linear system x[k+1] = A x[k] + B u[k], y[k] = C x[k] + D u[k]
updated at its sample hits (:mod:`~odelab.systems.diagram.schedule`) and held between them.
Its states in the diagram are its internal states (``name.x1``, ...) followed by its held
outputs (named after the block, or ``name.<output>``), all with zero derivative: the hybrid
driver (:mod:`~odelab.systems.diagram.hybrid`) changes them only at the hits, first every
hit block's outputs in evaluation order (y = C x + D u with the inputs at the hit), then their
states. So a sampled signal is stored, plotted and post-processed as the step function it is.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from odelab.exceptions import InputError
from odelab.systems.diagram.base import REQUIRED, Block, BlockError, Key, _scalar, controller_canonical, polynomial_pair, register

__all__ = ["ZeroOrderHold", "UnitDelay", "DiscreteTransferFcn", "DiscreteStateSpace", "DiscretePID"]

_TS = Key("numbers", REQUIRED, "seconds between samples, Ts or [Ts, offset]")


class _Discrete(Block):
    """x[k+1] = A x[k] + B u[k], y[k] = C x[k] + D u[k] at the hits; states [x; y held]."""

    DISCRETE = True
    LINEAR = False  # not a continuous-time LTI block: the diagram is sampled-data
    INPUTS: ClassVar[tuple[int, int | None]] = (1, 1)

    def _set(self, A, B, C, D, x0=None):
        self.A, self.B, self.C, self.D = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (A, B, C, D))
        self.nd = self.A.shape[0] if self.A.size else 0
        self.p = self.D.shape[0]
        self.nstates = self.nd + self.p
        self.xd0 = np.zeros(self.nd) if x0 is None else np.asarray(x0, dtype=float).reshape(self.nd)

    def check(self):
        from odelab.systems.diagram.schedule import sample_time

        self.sample = sample_time(self.params["sample_time"])
        self.check_discrete()

    def check_discrete(self):
        raise NotImplementedError

    @property
    def feedthrough(self):
        return bool(np.any(self.D != 0))

    def fixed_widths(self):
        return None if self.feedthrough else [1] * len(self.ports())

    def setup(self, widths):
        m = self.D.shape[1]
        if sum(widths) != m:
            raise BlockError(f"the block has {m} input{'s' if m != 1 else ''} but its inputs have total width "
                             f"{sum(widths)}.", key="inputs" if len(self.inputs) > 1 else "input")
        return [1] * len(self.ports())

    def held_names(self, name):
        return [name] if self.p == 1 else [f"{name}.{p}" for p in self.ports()]

    def state_names(self, name):
        return [f"{name}.x{i + 1}" for i in range(self.nd)] + self.held_names(name)

    def initial_state(self):
        y0 = self.C @ self.xd0 if self.nd else np.zeros(self.p)
        return np.concatenate([self.xd0, y0])

    def _u(self, u):
        return np.concatenate([np.asarray(v, dtype=float).reshape(-1) for v in u])

    def outputs(self, t, x, u, cplx=False):
        held = x[self.nd:]
        if len(self.ports()) == 1:
            return [held]
        return [held[i:i + 1] for i in range(self.p)]

    def derivative(self, t, x, u):
        return 0.0 * x

    def hit_output(self, x, u):
        """The block's state with its held outputs replaced by y = C x + D u (at a hit)."""
        x = np.array(x, dtype=float)
        y = (self.C @ x[:self.nd] if self.nd else np.zeros(self.p)) + (self.D @ self._u(u) if self.feedthrough else 0.0)
        x[self.nd:] = y
        return x

    def hit_update(self, x, u):
        """The block's state with x replaced by A x + B u (after every hit block's outputs)."""
        x = np.array(x, dtype=float)
        if self.nd:
            x[:self.nd] = self.A @ x[:self.nd] + self.B @ self._u(u)
        return x

    def describe(self):
        return f"{self.TYPE}, Ts = {self.sample}"


@register
class ZeroOrderHold(_Discrete):
    """Simulink's Zero-Order Hold: samples its input at each hit and holds it (any width)."""

    TYPE = "zero-order-hold"
    KEYS = {"sample_time": _TS}
    DOC = "y = u sampled every Ts and held"

    def check_discrete(self):
        self._set(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[1.0]])

    @property
    def feedthrough(self):
        return True

    def setup(self, widths):
        w = widths[0]
        self._set(np.zeros((0, 0)), np.zeros((0, w)), np.zeros((w, 0)), np.eye(w))
        return [w]

    def outputs(self, t, x, u, cplx=False):
        return [x]

    def hit_output(self, x, u):
        return np.asarray(u[0], dtype=float).reshape(-1).copy()

    def label(self, name):
        return f"{name}\nZOH, Ts = {self.sample}"


@register
class UnitDelay(_Discrete):
    """Simulink's Unit Delay 1/z: y[k] = u[k-1], y[0] = ``initial`` (a number or a list)."""

    TYPE = "unit-delay"
    KEYS = {"initial": Key("numbers", 0.0, "the output before the first sample, a number or a list"),
            "sample_time": _TS}
    DOC = "y[k] = u[k-1]"

    def check_discrete(self):
        x0 = np.atleast_1d(np.asarray(self.params["initial"], dtype=float))
        if x0.ndim != 1 or not np.all(np.isfinite(x0)):
            raise BlockError(f"`initial` must be a finite number or list; got {self.params['initial']!r}.",
                             key="initial")
        w = x0.size
        self._set(np.zeros((w, w)), np.eye(w), np.eye(w), np.zeros((w, w)), x0)

    @property
    def feedthrough(self):
        return False

    def fixed_widths(self):
        return [self.p]

    def setup(self, widths):
        if widths[0] != self.p:
            raise BlockError(f"the input has width {widths[0]} but `initial` has {self.p} entries; give one "
                             "initial value per element.", key="initial")
        return [self.p]

    def state_names(self, name):
        return [f"{name}.x{i + 1}" for i in range(self.nd)] if self.p > 1 else [f"{name}.next", name]

    def outputs(self, t, x, u, cplx=False):
        return [x[self.nd:]]

    def label(self, name):
        return f"{name}\n1/z, Ts = {self.sample}"


@register
class DiscreteTransferFcn(_Discrete):
    """Simulink's Discrete Transfer Fcn, MATLAB's ``tf(num, den, Ts)``: coefficients in
    descending powers of z; realised in controller canonical form (as ``tf2ss``)."""

    TYPE = "discrete-transfer-fcn"
    KEYS = {"num": Key("numbers", doc="numerator coefficients, descending powers of z"),
            "den": Key("numbers", doc="denominator coefficients, descending powers of z"),
            "sample_time": _TS}
    DOC = "y = num(z)/den(z) u"

    def check_discrete(self):
        num, den = polynomial_pair(self.params)
        if num.size > den.size:
            raise BlockError(f"the transfer function is not causal (num has degree {num.size - 1} in z, den degree "
                             f"{den.size - 1}); a discrete-transfer-fcn needs deg num <= deg den.", key="num")
        self.num, self.den = num, den
        self._set(*controller_canonical(num, den))

    def label(self, name):
        num = " ".join(f"{c:g}" for c in self.num)
        den = " ".join(f"{c:g}" for c in self.den)
        return f"{name}\n[{num}] / [{den}] (z)\nTs = {self.sample}"


@register
class DiscreteStateSpace(_Discrete):
    """Simulink's Discrete State-Space: x[k+1] = A x[k] + B u[k], y[k] = C x[k] + D u[k];
    outputs addressed ``name.y1``... (or the names given)."""

    TYPE = "discrete-state-space"
    INPUTS = (1, None)
    KEYS = {"A": Key("matrix", doc="n x n"), "B": Key("matrix", doc="n x m"), "C": Key("matrix", doc="p x n"),
            "D": Key("matrix", None, "p x m, default zeros"), "initial": Key("numbers", None, "x[0], default zeros"),
            "outputs": Key("names", None, "names of the outputs, default y1, y2..."), "sample_time": _TS}
    DOC = "x[k+1] = Ax + Bu, y = Cx + Du"

    def check_discrete(self):
        from odelab.systems.statespace import StateSpace

        p = self.params
        try:
            ss = StateSpace(p["A"], p["B"], p["C"], p["D"], outputs=p["outputs"])
        except InputError as exc:
            raise BlockError(exc.message, key=exc.key) from None
        n = ss.A.shape[0]
        x0 = None if p["initial"] is None else np.atleast_1d(np.asarray(p["initial"], dtype=float))
        if x0 is not None and x0.shape != (n,):
            raise BlockError(f"`initial` has {x0.size} values but A has {n} states.", key="initial")
        self.output_names = tuple(ss.outputs)
        self._set(ss.A, ss.B, ss.C, ss.D, x0)

    def ports(self):
        return self.output_names

    def held_names(self, name):
        return [f"{name}.{o}" for o in self.output_names]

    def label(self, name):
        return f"{name}\nx[k+1] = Ax + Bu\ny = Cx + Du, Ts = {self.sample}"


@register
class DiscretePID(_Discrete):
    """Simulink's Discrete PID Controller, parallel form, Forward Euler integrator and filter
    (its defaults): u = P e + I Ts/(z - 1) e + D N / (1 + N Ts/(z - 1)) e.

    States: the integral of e (``name.integral``) and the derivative filter's (``name.filter``),
    then the held output (``name``)."""

    TYPE = "discrete-pid"
    KEYS = {"P": Key("number", 1.0, "proportional gain"), "I": Key("number", 1.0, "integral gain"),
            "D": Key("number", 0.0, "derivative gain"), "N": Key("number", 100.0, "derivative filter coefficient"),
            "sample_time": _TS}
    DOC = "u = P e + I Ts/(z-1) e + D N/(1 + N Ts/(z-1)) e"

    def check_discrete(self):
        P, I, D, N = (_scalar(self, k) for k in "PIDN")
        Ts = self.sample.period
        if N < 0:
            raise BlockError(f"`N` is {N:g}; the filter coefficient must be positive.", key="N")
        self.gains = (P, I, D, N)
        # x_I[k+1] = x_I + Ts e;  f[k+1] = f + Ts N (D e - f);  u = P e + I x_I + N (D e - f)
        self._set([[1.0, 0.0], [0.0, 1.0 - Ts * N]], [[Ts], [Ts * N * D]], [[I, -N]], [[P + N * D]])

    def state_names(self, name):
        return [f"{name}.integral", f"{name}.filter", name]

    def label(self, name):
        P, I, D, N = self.gains
        return f"{name}\nPID(z) P {P:g}, I {I:g}, D {D:g}, N {N:g}\nTs = {self.sample}"


@register
class PID(Block):
    """Simulink's continuous PID Controller, parallel form: u = P e + I/s e + D N s/(s + N) e.

    States: the integral of e (``name.integral``) and the derivative filter's (``name.filter``)."""

    TYPE = "pid"
    KEYS = {"P": Key("number", 1.0, "proportional gain"), "I": Key("number", 1.0, "integral gain"),
            "D": Key("number", 0.0, "derivative gain"), "N": Key("number", 100.0, "derivative filter coefficient")}
    ALIASES = {"Kp": "P", "Ki": "I", "Kd": "D"}  # MATLAB's pid(Kp, Ki, Kd)
    DOC = "u = P e + I/s e + D N s/(s + N) e"
    nstates = 2

    def check(self):
        P, I, D, N = (_scalar(self, k) for k in "PIDN")
        if N <= 0:
            raise BlockError(f"`N` is {N:g}; the filter coefficient must be positive.", key="N")
        self.gains = (P, I, D, N)

    @property
    def feedthrough(self):
        P, I, D, N = self.gains
        return P + N * D != 0

    def fixed_widths(self):
        return None if self.feedthrough else [1]

    def setup(self, widths):
        if widths[0] != 1:
            raise BlockError(f"a pid block takes a scalar error signal; this one has width {widths[0]}.", key="input")
        return [1]

    def state_names(self, name):
        return [f"{name}.integral", f"{name}.filter"]

    # x_I' = e;  f' = N (D e - f);  u = P e + I x_I + N (D e - f)
    def outputs(self, t, x, u, cplx=False):
        P, I, D, N = self.gains
        y = I * x[0:1] - N * x[1:2]
        if self.feedthrough:
            y = y + (P + N * D) * u[0]
        return [y]

    def derivative(self, t, x, u):
        P, I, D, N = self.gains
        e = u[0]
        return np.concatenate([e, N * (D * e - x[1:2])])

    def generate_outputs(self, g, name, ins):  # as outputs(): I x_I - N f, then + (P + N D) e
        P, I, D, N = self.gains
        text = f"(({g.number(I)} * {g.state(name, 0)}) - ({g.number(N)} * {g.state(name, 1)}))"
        if self.feedthrough:
            text = f"({text} + ({g.number(P + N * D)} * {ins[0]}))"
        return [g.var(text)]

    def generate_derivative(self, g, name, ins):  # as derivative(): e, N (D e - f)
        P, I, D, N = self.gains
        e = ins[0]
        g.derivative(name, 0, e)
        g.derivative(name, 1, f"({g.number(N)} * (({g.number(D)} * {e}) - {g.state(name, 1)}))")

    def label(self, name):
        P, I, D, N = self.gains
        return f"{name}\nPID(s) P {P:g}, I {I:g}, D {D:g}, N {N:g}"
