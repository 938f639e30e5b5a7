"""Blocks whose output's formula switches: abs, sign, switch, relay and min-max.

Each declares its switching functions for :mod:`~odelab.systems.diagram.zerocross` (the
instants its formula changes are located, then the run restarts in the new mode, as
Simulink's zero-crossing detection does). Between switches a block's mode is held by the
driver, so the right-hand side is smooth inside every step; evaluated without the driver (the
output after the run, a linearisation) a block reads its mode off its inputs.
"""

from __future__ import annotations

import difflib

import numpy as np

from odelab.systems.diagram.base import ZC_KEY, Block, BlockError, Key, _broadcast_width, _column, _real, _scalar, register

__all__ = ["Abs", "Sign", "Switch", "Relay", "MinMax"]


def _flat(v) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(-1)


@register
class Abs(Block):
    """y = |u| (Simulink's Abs); switches where u crosses 0 (modes 1: u >= 0, 0: u < 0)."""

    TYPE = "abs"
    LINEAR = False
    ZC = True
    KEYS = {"zero_crossing": ZC_KEY}
    DOC = "y = |u|"

    def setup(self, widths):
        return [widths[0]]

    def outputs(self, t, x, u, cplx=False):
        v = u[0]
        m = _column(self.mode, v) if self.mode is not None else (_real(v) >= 0)
        return [np.where(m == 1, v, -v)]

    def zc_values(self, x, u):
        return _flat(u[0])

    def zc_mode(self, signs, x, u):
        return np.where(signs >= 0, 1, 0)

    def zc_directions(self, mode):
        return np.where(np.asarray(mode) == 1, -1.0, 1.0)

    def label(self, name):
        return f"{name}\n|u|"


@register
class Sign(Block):
    """y = sign(u): 1, 0 or -1 (Simulink's Sign); switches where u crosses 0."""

    TYPE = "sign"
    LINEAR = False
    ZC = True
    KEYS = {"zero_crossing": ZC_KEY}
    DOC = "y = sign(u)"

    def setup(self, widths):
        return [widths[0]]

    def outputs(self, t, x, u, cplx=False):
        v = u[0]
        if self.mode is not None:
            return [np.broadcast_to(_column(self.mode, v), np.shape(v)).astype(float) + 0.0 * v]
        return [np.sign(_real(v)) + 0.0 * v]

    def zc_values(self, x, u):
        return _flat(u[0])

    def zc_mode(self, signs, x, u):
        return np.sign(signs)

    def zc_directions(self, mode):
        mode = np.asarray(mode)
        return np.where(mode > 0, -1.0, np.where(mode < 0, 1.0, 0.0))

    def label(self, name):
        return f"{name}\nsign(u)"


_CRITERIA = ("u2 >= threshold", "u2 > threshold", "u2 ~= 0")


@register
class Switch(Block):
    """y = u1 where the criterion on u2 holds, else u3 (Simulink's Switch; inputs in that order)."""

    TYPE = "switch"
    INPUTS = (3, 3)
    LINEAR = False
    ZC = True
    KEYS = {"threshold": Key("number", 0.0, "the threshold u2 is compared with"),
            "criteria": Key("text", "u2 >= threshold", "\"u2 >= threshold\", \"u2 > threshold\" or \"u2 ~= 0\""),
            "zero_crossing": ZC_KEY}
    DOC = "y = u1 if u2 passes the criterion, else u3"
    SHAPE = "box"

    def check(self):
        crit = self.params["criteria"]
        if crit not in _CRITERIA:
            close = difflib.get_close_matches(str(crit), _CRITERIA, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise BlockError(f"`criteria` is {crit!r}; use one of {', '.join(repr(c) for c in _CRITERIA)} "
                             f"(Simulink's names).{hint}", key="criteria")
        self.criteria = crit
        self.threshold = 0.0 if crit == "u2 ~= 0" else _scalar(self, "threshold")

    def setup(self, widths):
        out = _broadcast_width(self, [widths[0], widths[2]])
        if widths[1] not in (1, out):
            raise BlockError(f"the control input u2 has width {widths[1]}; give a scalar or one of width {out}.",
                             key="inputs")
        return [out]

    def _passes(self, v):
        r = _real(v)
        if self.criteria == "u2 >= threshold":
            return r >= self.threshold
        if self.criteria == "u2 > threshold":
            return r > self.threshold
        return r != 0

    def outputs(self, t, x, u, cplx=False):
        u1, u2, u3 = u
        m = (_column(self.mode, u2) == 1) if self.mode is not None else self._passes(u2)
        return [np.where(m, u1, u3)]

    def zc_values(self, x, u):
        return _flat(u[1]) - self.threshold

    def zc_mode(self, signs, x, u):
        if self.criteria == "u2 >= threshold":
            return np.where(signs >= 0, 1, 0)
        if self.criteria == "u2 > threshold":
            return np.where(signs > 0, 1, 0)
        return np.where(signs != 0, 1, 0)

    def zc_directions(self, mode):
        mode = np.asarray(mode)
        if self.criteria == "u2 ~= 0":
            return np.zeros(mode.shape)
        return np.where(mode == 1, -1.0, 1.0)

    def label(self, name):
        return f"{name}\nswitch: {self.criteria.replace('threshold', f'{self.threshold:g}')}"


@register
class Relay(Block):
    """Simulink's Relay: output ``on_value`` once u reaches ``on_point``, ``off_value`` once it
    falls to ``off_point``, unchanged in between (hysteresis when on_point > off_point). It starts
    off unless u(t0) >= on_point. Its output is held as a state (named after the block); the
    switching instants are located (or, with ``zero_crossing = false``, taken at the end of the
    step in which they occurred)."""

    TYPE = "relay"
    LINEAR = False
    ZC = True
    STATEFUL_MODE = True
    _EPS = float(np.finfo(float).eps)
    KEYS = {"on_point": Key("number", _EPS, "switch on when u >= on_point (Simulink's default eps)"),
            "off_point": Key("number", _EPS, "switch off when u <= off_point"),
            "on_value": Key("number", 1.0, "the output when on"),
            "off_value": Key("number", 0.0, "the output when off"),
            "zero_crossing": ZC_KEY}
    DOC = "on/off with hysteresis"
    nstates = 1

    def check(self):
        self.on_point, self.off_point = _scalar(self, "on_point"), _scalar(self, "off_point")
        self.on_value, self.off_value = _scalar(self, "on_value"), _scalar(self, "off_value")
        if self.on_point < self.off_point:
            raise BlockError(f"`on_point` ({self.on_point:g}) is below `off_point` ({self.off_point:g}); the relay "
                             "switches on at on_point >= off_point (equal: no hysteresis).", key="on_point")

    @property
    def feedthrough(self):
        return False

    def fixed_widths(self):
        return [1]

    def setup(self, widths):
        if widths[0] != 1:
            raise BlockError(f"a relay takes a scalar input; this one has width {widths[0]}.", key="input")
        return [1]

    def initial_state(self):
        return np.array([self.off_value])

    def outputs(self, t, x, u, cplx=False):
        return [x]

    def derivative(self, t, x, u):
        return 0.0 * x

    def zc_values(self, x, u):
        v = float(np.asarray(u[0]).reshape(-1)[0])
        return np.array([v - self.on_point, v - self.off_point])

    def zc_mode(self, signs, x, u):
        on = self.mode if self.mode is not None else np.array([0])
        if signs[0] >= 0:
            return np.array([1])
        if signs[1] <= 0:
            return np.array([0])
        return np.asarray(on)

    def zc_directions(self, mode):
        on = int(np.asarray(mode).reshape(-1)[0]) == 1
        return np.array([np.nan, -1.0]) if on else np.array([1.0, np.nan])

    def zc_reset(self, x, mode):
        return np.array([self.on_value if int(np.asarray(mode).reshape(-1)[0]) == 1 else self.off_value])

    def label(self, name):
        return f"{name}\nrelay on {self.on_point:g} / off {self.off_point:g}"


@register
class MinMax(Block):
    """y = the smallest (``function = "min"``) or largest (``"max"``) of the inputs, elementwise;
    one vector input gives its smallest or largest element (Simulink's MinMax). Switches where
    the chosen input changes."""

    TYPE = "min-max"
    INPUTS = (1, None)
    LINEAR = False
    ZC = True
    KEYS = {"function": Key("text", "min", "\"min\" or \"max\""), "zero_crossing": ZC_KEY}
    DOC = "y = min or max of the inputs"

    def check(self):
        if self.params["function"] not in ("min", "max"):
            raise BlockError(f"`function` is {self.params['function']!r}; use \"min\" or \"max\".", key="function")
        self.sign = 1.0 if self.params["function"] == "max" else -1.0

    def setup(self, widths):
        if len(widths) == 1:
            self.n, self.reduce = widths[0], True
            return [1]
        self.n, self.reduce = len(widths), False
        self.width = _broadcast_width(self, widths)
        return [self.width]

    def _stack(self, u):
        if self.reduce:
            return u[0][:, None] if np.ndim(u[0]) == 1 else u[0][:, None, ...]
        shape = (self.width,) + np.broadcast_shapes(*(np.shape(v)[1:] for v in u))
        return np.stack([np.broadcast_to(v, shape) for v in u])  # (n, w, ...)

    def outputs(self, t, x, u, cplx=False):
        s = self._stack(u)
        if self.mode is not None:
            idx = np.asarray(self.mode, dtype=int).reshape((1, -1) + (1,) * (s.ndim - 2))
            idx = np.broadcast_to(idx, (1,) + s.shape[1:])
        else:
            idx = np.argmax(self.sign * _real(s), axis=0)[None]
        return [np.take_along_axis(s, idx, axis=0)[0]]

    # switching functions: for each element and each pair i < j of inputs, sign * (u_i - u_j)
    def _pairs(self):
        return [(i, j) for i in range(self.n) for j in range(i + 1, self.n)]

    def zc_values(self, x, u):
        s = np.asarray(_real(self._stack(u)), dtype=float).reshape(self.n, -1)  # (n, w)
        return np.concatenate([self.sign * (s[i] - s[j]) for i, j in self._pairs()])

    def zc_mode(self, signs, x, u):
        s = np.asarray(_real(self._stack(u)), dtype=float).reshape(self.n, -1)
        w = s.shape[1]
        signs = np.asarray(signs).reshape(-1, w)
        wins = np.ones((self.n, w), dtype=bool)  # i beats (or ties) every other input
        for k, (i, j) in enumerate(self._pairs()):
            wins[i] &= signs[k] >= 0
            wins[j] &= signs[k] <= 0
        fallback = np.argmax(self.sign * s, axis=0)
        return np.where(wins.any(axis=0), np.argmax(wins, axis=0), fallback)

    def zc_directions(self, mode):
        mode = np.asarray(mode).reshape(-1)
        rows = []
        for i, j in self._pairs():
            rows.append(np.where(mode == i, -1.0, np.where(mode == j, 1.0, np.nan)))
        return np.concatenate(rows) if rows else np.zeros(0)

    def label(self, name):
        return f"{name}\n{self.params['function']}"
