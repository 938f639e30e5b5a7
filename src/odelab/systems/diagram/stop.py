"""Simulink's Stop Simulation block: the run ends when its input is nonzero.

As in Simulink, the input is looked at after each step the solver accepts, and the run ends at
the end of the step in which it became nonzero (a terminal event; the results up to there are
stored with the block's name in the message). The block has no output.
"""

from __future__ import annotations

import numpy as np

from odelab.systems.diagram.base import Block, register

__all__ = ["Stop"]


@register
class Stop(Block):
    """Ends the run at the end of the step after which its input is nonzero (Simulink's Stop Simulation)."""

    TYPE = "stop"
    LINEAR = False
    STOPS = True  # the hybrid driver watches its input after every step
    DOC = "ends the run when u != 0"
    SHAPE = "octagon"

    def ports(self):
        return ()

    def setup(self, widths):
        return []

    def outputs(self, t, x, u, cplx=False):
        return []

    def stopped(self, u) -> bool:
        """Whether the input (at one point) asks the run to stop."""
        return bool(np.any(np.asarray(u[0], dtype=float) != 0))

    def label(self, name):
        return f"{name}\nSTOP"
