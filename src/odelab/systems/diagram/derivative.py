"""Simulink's Derivative block, as the first-order approximation s/(c s + 1).

Simulink's block outputs du/dt as the difference quotient over the solver's last step (its value
depends on the steps taken, and is 0 at the first). odelab's ``derivative`` is the transfer
function s/(c s + 1) instead, the approximation Simulink itself uses to linearise the block
(its "Coefficient c in the transfer function approximation"): a first-order lag of c seconds on
the exact derivative, independent of the solver's steps. c is 1 ms unless given (``coefficient``);
a smaller c follows du/dt more closely and makes the system stiffer (its pole is at -1/c).
"""

from __future__ import annotations

import numpy as np

from odelab.systems.diagram.base import Block, BlockError, Key, _scalar, register

__all__ = ["Derivative"]


@register
class Derivative(Block):
    """du/dt approximated by s/(c s + 1): Simulink's Derivative block, with the lag c of its linearisation."""

    TYPE = "derivative"
    KEYS = {"coefficient": Key("number", 1e-3, "c in s/(c s + 1), seconds (> 0): the lag behind du/dt"),
            "initial": Key("number", 0.0, "the input's value at the start, so the output starts at 0")}
    DOC = "y = s/(c s + 1) u: du/dt with a lag of c seconds"

    def check(self):
        c = _scalar(self, "coefficient")
        if not c > 0:
            raise BlockError(f"`coefficient` must be a positive time in seconds; got {c:g}.", key="coefficient")
        self.c = c
        # z' = (u - z)/c, y = (u - z)/c: the state z follows u (its size, not 1/c^2 times smaller, so the solver's
        # absolute tolerance on it costs y only atol/c); z(t0) = u(t0) starts y at 0
        self.A, self.B, self.C, self.D = (np.array([[v]]) for v in (-1 / c, 1 / c, -1 / c, 1 / c))
        self.nstates = 1
        self.x0 = np.array([_scalar(self, "initial")])

    def state_names(self, name):
        return [f"{name}.x1"]

    def initial_state(self):
        return self.x0.copy()

    def setup(self, widths):
        if widths[0] != 1:
            raise BlockError(f"the input has width {widths[0]}; a derivative block takes one signal (split a vector "
                             "with a demux).", key="input")
        return [1]

    def outputs(self, t, x, u, cplx=False):
        return [self.C[0, 0] * x + self.D[0, 0] * u[0]]

    def derivative(self, t, x, u):
        return self.A[0, 0] * x + self.B[0, 0] * u[0]

    def generate_outputs(self, g, name, ins):
        x = g.state(name, 0)
        return [g.var(f"({g.number(self.C[0, 0])} * {x} + {g.number(self.D[0, 0])} * {ins[0]})")]

    def generate_derivative(self, g, name, ins):
        x = g.state(name, 0)
        g.derivative(name, 0, f"({g.number(self.A[0, 0])} * {x} + {g.number(self.B[0, 0])} * {ins[0]})")

    def describe(self):
        return f"derivative s/({self.c:g} s + 1)"

    def label(self, name):
        return f"{name}\ndu/dt\ns/({self.c:g}s + 1)"
