"""The right-hand side of an odelab experiment, as MATLAB's `function ydot = eq1(t, y)`."""

import math


def rhs(t, y):
    """Return dy/dt at time t for the state vector y (a 1-D array)."""
    return [math.cos(t)]
