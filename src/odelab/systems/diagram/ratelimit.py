"""The rate-limiter block: Simulink's Rate Limiter, with its switching instants located.

The output y follows the input u while u's slope stays within [``falling``, ``rising``]
(mode *track*), and ramps at ``rising`` (mode *rising*, while y < u) or ``falling`` (mode
*falling*, while y > u) otherwise. y is a state of the diagram (named after the block, starting
at ``initial``, Simulink's initial condition): y' = rising, falling, or u' when tracking. The
instants the limit engages (u' crosses ``rising`` upward or ``falling`` downward while y tracks
u) and disengages (y catches u) are zero crossings, located on the solver's interpolant; a jump
of u (a step, a sample hit upstream) starts a ramp at once. A step of height H into a rate
limiter is therefore a ramp of slope ``rising`` that reaches the step's value at H / rising
after the step, to round-off.

u' is the derivative of the input along the trajectory, exact: a complex step of the diagram's
evaluation in the direction (1, x', w') where w' are the sources' slopes (exact for every signal
with an exact form: steps, ramps, sines, pulses, linear tables and their sums; a central
difference for the others). While y tracks u, y is put back to u exactly at every restart, so
no integration error accumulates.

Simulink's own block compares each major step's input with the previous output (its output
depends on the step sizes and it has no zero-crossing detection); odelab's is the continuous
limit of that rule, so it does not depend on the solver's steps.
"""

from __future__ import annotations

import math

import numpy as np

from odelab.systems.diagram.base import ZC_KEY, Block, BlockError, Key, _real, _scalar, register

__all__ = ["RateLimiter", "signal_slope"]

RISING, TRACK, FALLING = 2, 1, 0


@register
class RateLimiter(Block):
    """Simulink's Rate Limiter: y follows u with its slope limited to [falling, rising]
    (Simulink's defaults 1 and -1); y starts at ``initial`` (0). The instants the limit engages
    and disengages are located (see the module)."""

    TYPE = "rate-limiter"
    LINEAR = False
    ZC = True
    STATEFUL_MODE = True
    #: the block needs the slope of its input along the trajectory (``slope`` of zc_*, derivative)
    NEEDS_SLOPE = True
    KEYS = {"rising": Key("number", 1.0, "the largest rising slope of the output, units of y per second (> 0)"),
            "falling": Key("number", -1.0, "the largest falling slope, units of y per second (< 0)"),
            "initial": Key("number", 0.0, "the output at the start (Simulink's initial condition)"),
            "zero_crossing": ZC_KEY}
    DOC = "y = u with its slope limited to [falling, rising]"
    nstates = 1

    def check(self):
        self.rising, self.falling = _scalar(self, "rising"), _scalar(self, "falling")
        self.y0 = _scalar(self, "initial")
        if not self.rising > 0:
            raise BlockError(f"`rising` is {self.rising:g}; the rising slew rate must be positive (units per "
                             "second, e.g. rising = 2).", key="rising")
        if not self.falling < 0:
            raise BlockError(f"`falling` is {self.falling:g}; the falling slew rate must be negative (units per "
                             f"second, e.g. falling = {-self.rising:g}, Simulink's sign).", key="falling")

    @property
    def feedthrough(self):
        return False

    def fixed_widths(self):
        return [1]

    def setup(self, widths):
        if widths[0] != 1:
            raise BlockError(f"a rate limiter takes a scalar input; this one has width {widths[0]}.", key="input")
        return [1]

    def initial_state(self):
        return np.array([self.y0])

    def outputs(self, t, x, u, cplx=False):
        return [x]

    def derivative(self, t, x, u, slope=None):
        """y': the limit in a limited mode, u' (``slope``) when tracking; without the driver's
        mode, the limit toward u (0 where y equals u)."""
        one = 0.0 * x + 1.0
        if self.mode is not None:
            m = int(np.asarray(self.mode).reshape(-1)[0])
            if m == RISING:
                return self.rising * one
            if m == FALLING:
                return self.falling * one
            return (0.0 if slope is None else slope) * one
        e = _real(u[0] - x)
        return np.where(e > 0, self.rising, np.where(e < 0, self.falling, 0.0)) * one

    # -- zero crossings: [u - y, u' - rising, u' - falling] ---------------------------------------

    def zc_values(self, x, u, slope=0.0):
        y = float(np.asarray(x).reshape(-1)[0])
        v = float(np.asarray(u[0]).reshape(-1)[0])
        return np.array([v - y, slope - self.rising, slope - self.falling])

    def zc_mode(self, signs, x, u, slope=0.0):
        # The gap u - y is read exactly (not its sign with the driver's convention for a zero):
        # the driver puts y = u when it tracks or has just caught u, so 0 means "y is on u".
        e = float(np.asarray(u[0]).reshape(-1)[0]) - float(np.asarray(x).reshape(-1)[0])
        if e > 0:
            return np.array([RISING])
        if e < 0:
            return np.array([FALLING])
        return np.array([RISING if signs[1] > 0 else FALLING if signs[2] < 0 else TRACK])

    def zc_directions(self, mode):
        m = int(np.asarray(mode).reshape(-1)[0])
        if m == RISING:  # y catches u from below: u - y falls to 0
            return np.array([-1.0, np.nan, np.nan])
        if m == FALLING:
            return np.array([1.0, np.nan, np.nan])
        return np.array([np.nan, 1.0, -1.0])

    def caught(self, x, u, fired: bool) -> bool:
        """Whether y should be put on u at a restart where u is continuous: it tracks, or its
        crossing (y reaching u) has just fired or been passed."""
        if self.mode is None:
            return False
        m = int(np.asarray(self.mode).reshape(-1)[0])
        e = float(np.asarray(u[0]).reshape(-1)[0]) - float(np.asarray(x).reshape(-1)[0])
        return m == TRACK or fired or (m == RISING and e <= 0) or (m == FALLING and e >= 0)

    def describe(self):
        return f"rate limiter [{self.falling:g}, {self.rising:g}]/s"

    def label(self, name):
        return f"{name}\nrate limit\n[{self.falling:g}, {self.rising:g}] /s"


# -- the sources' slopes --------------------------------------------------------------------------

_H = 1e-30  # the complex step


def _term_slope(term, t: float) -> float:
    """d/dt of one exact-form term at t, by a complex step (exact)."""
    s = (t - term.tau) + 1j * _H
    out = complex(term.coef)
    if term.power:
        out = out * s**term.power
    if term.rate:
        out = out * np.exp(term.rate * s)
    if term.kind == "sin":
        out = out * np.sin(term.freq * s)
    elif term.freq:
        out = out * np.cos(term.freq * s)
    return float(np.imag(out)) / _H


def signal_slope(signal, t: float, lo: float = -math.inf, hi: float = math.inf) -> float:
    """The slope of an input signal at t, taken inside the window [lo, hi] (a piece of the
    hybrid driver: at an end, the slope on the piece's side). Exact for signals with an exact
    form; a central difference (one-sided at the window's ends) otherwise."""
    t = float(min(max(t, lo), hi))
    form = signal.exact_terms() if hasattr(signal, "exact_terms") else None
    if form is not None:
        pieces = form.raw(float(np.nextafter(t, -math.inf)), t)  # with the piece that ends at t
        at_end = t >= hi and lo < hi
        piece = None
        for p in pieces:
            if (p.start < t <= p.stop) if at_end else (p.start <= t < p.stop):
                piece = p
                break
        if piece is None and pieces:
            piece = pieces[-1]
        return sum(_term_slope(term, t) for term in piece.terms) if piece is not None else 0.0
    h = 6e-6 * max(1.0, abs(t))
    a, b = max(t - h, lo), min(t + h, hi)
    if b <= a:
        return 0.0
    return float((np.asarray(signal(b), dtype=float) - np.asarray(signal(a), dtype=float)) / (b - a))
