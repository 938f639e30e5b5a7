"""Simulink's Transport Delay block: ``y(t) = u(t - delay)``, ``initial`` before the delay has elapsed.

The block only declares itself here (keys, widths, drawing); a diagram holding one runs as delay
equations through dde23 and is linearised through its Pade approximation, both in
:mod:`odelab.systems.diagram.delay`.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from odelab.exceptions import InputError
from odelab.systems.diagram.base import Block, BlockError, Key, _scalar, register

__all__ = ["TransportDelay"]


@register
class TransportDelay(Block):
    """Simulink's Transport Delay: y(t) = u(t - delay), ``initial`` before the delay has elapsed."""

    TYPE = "transport-delay"
    KEYS: ClassVar[dict[str, Key]] = {
        "delay": Key("number", doc="the delay T in seconds (> 0)"),
        "initial": Key("numbers", 0.0, "the output until t0 + delay, a number or a list"),
        "pade_order": Key("count", 2, "order of the Pade approximation used when the diagram is linearised"),
    }
    DOC = "y(t) = u(t - delay), initial before t0 + delay (solved by dde23)"
    LINEAR = False  # an infinite-dimensional system: linearised through its Pade approximation
    SHAPE = "box"

    def check(self):
        self.T = _scalar(self, "delay")
        if not self.T > 0:
            raise BlockError(f"`delay` must be positive (seconds); got {self.params['delay']!r}. A delay of 0 is "
                             "the wire itself: remove the block.", key="delay")
        y0 = np.atleast_1d(np.asarray(self.params["initial"], dtype=float))
        if y0.ndim != 1 or not np.all(np.isfinite(y0)):
            raise BlockError(f"`initial` must be a finite number or list; got {self.params['initial']!r}.",
                             key="initial")
        self.y0 = y0
        order = self.params["pade_order"]
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 0 <= int(order) <= 10:
            raise BlockError(f"`pade_order` must be a whole number from 0 to 10; got {order!r}.", key="pade_order")
        self.order = int(order)

    @property
    def feedthrough(self):
        return False

    def fixed_widths(self):
        return [self.y0.size]

    def setup(self, widths):
        if widths[0] not in (1, self.y0.size) and self.y0.size != 1:
            raise BlockError(f"the input has width {widths[0]} but `initial` has {self.y0.size} entries; give one "
                             "initial output per element (or one for all).", key="initial")
        return [self.y0.size]

    def outputs(self, t, x, u, cplx=False):
        raise InputError("a transport-delay block is evaluated by dde23 (odelab.systems.diagram.delay), which "
                         "knows the past; this diagram was evaluated without it.", key="delay")

    def describe(self):
        return f"delay {getattr(self, 'texts', {}).get('delay', f'{self.T:g}')}"

    def node(self, name):
        text = getattr(self, "texts", {}).get("delay", f"{self.T:g}")
        return f"{name}\ne^(-{text} s)", "box", {}
