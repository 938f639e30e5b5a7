"""Random sources: Simulink's Random Number, Uniform Random Number and Band-Limited White Noise.

Each is a discrete source with a ``seed`` and a ``sample_time`` (Simulink's defaults: seed 0,
Ts = 0.1 s; the white noise's seed 23341): at each hit t = k Ts + offset it outputs a new number
and holds it until the next hit, so its output is a state of the diagram (named after the block)
stored as the step function it is.

How the numbers relate to MATLAB's: Simulink draws from its own generator, whose stream odelab
does not reproduce; the numbers here have the same distribution (normal with the given mean and
variance; uniform on [minimum, maximum); normal with variance power/Ts for the white noise, as
Simulink's block scales it) and are reproducible: the number at hit k is the first draw of
NumPy's PCG64 seeded with ``SeedSequence([seed, k])``, so it depends only on the seed and the
hit's index, never on the solver's steps, restarts or the machine. Two blocks with the same seed
give the same numbers, as two Simulink blocks with the same seed do.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from odelab.systems.diagram.base import Block, BlockError, Key, _scalar, register

__all__ = ["BandLimitedWhiteNoise", "RandomNumber", "UniformRandomNumber", "draw"]


def draw(seed: int, k: int, kind: str = "normal") -> float:
    """The reproducible number of hit ``k`` for ``seed``: standard normal, or uniform on [0, 1)."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed) % 2**32, int(k) % 2**63]))
    return float(rng.standard_normal() if kind == "normal" else rng.random())


class _RandomSource(Block):
    """A discrete source: a new number at each hit, held between hits (one state, named after the block)."""

    DISCRETE = True
    LINEAR = False
    INPUTS: ClassVar[tuple[int, int | None]] = (0, 0)
    TIMED = True  # the hybrid driver passes the hit's time (hit_output_at): the number is a function of k
    nstates = 1
    KIND = "normal"

    def check(self):
        from odelab.systems.diagram.schedule import sample_time

        self.sample = sample_time(self.params["sample_time"])
        seed = _scalar(self, "seed")
        if seed != int(seed) or seed < 0:
            raise BlockError(f"`seed` must be a whole number >= 0 (Simulink's seeds are); got {seed:g}.", key="seed")
        self.seed = int(seed)
        self.check_values()

    def check_values(self):
        raise NotImplementedError

    @property
    def feedthrough(self):
        return False

    def fixed_widths(self):
        return [1]

    def setup(self, widths):
        return [1]

    def state_names(self, name):
        return [name]

    def value(self, k: int) -> float:
        raise NotImplementedError

    def initial_state(self):
        return np.array([self.value(0)])

    def outputs(self, t, x, u, cplx=False):
        return [x]

    def derivative(self, t, x, u):
        return 0.0 * x

    def hit_output_at(self, t, x, u):
        k = int(round((float(t) - self.sample.offset) / self.sample.period))
        return np.array([self.value(k)])

    def hit_output(self, x, u):  # pragma: no cover - the driver calls hit_output_at (TIMED)
        return np.asarray(x, dtype=float)

    def hit_update(self, x, u):
        return np.asarray(x, dtype=float)

    def label(self, name):
        return f"{name}\n{self.describe()}\nseed {self.seed}, Ts = {self.sample}"


_SEED = Key("number", 0.0, "the seed, a whole number >= 0 (Simulink's default 0)")
_TS = Key("numbers", 0.1, "seconds between numbers, Ts or [Ts, offset] (Simulink's default 0.1)")


@register
class RandomNumber(_RandomSource):
    """Simulink's Random Number: normally distributed numbers, one per sample time, held between samples."""

    TYPE = "random-number"
    KEYS = {"mean": Key("number", 0.0, "the mean"), "variance": Key("number", 1.0, "the variance (>= 0)"),
            "seed": _SEED, "sample_time": _TS}
    DOC = "y = mean + sqrt(variance) n_k, n_k standard normal, new every Ts"

    def check_values(self):
        self.mean, self.variance = _scalar(self, "mean"), _scalar(self, "variance")
        if self.variance < 0:
            raise BlockError(f"`variance` must be at least 0; got {self.variance:g}.", key="variance")

    def value(self, k):
        return self.mean + math.sqrt(self.variance) * draw(self.seed, k)

    def describe(self):
        return f"random N({self.mean:g}, {self.variance:g})"


@register
class UniformRandomNumber(_RandomSource):
    """Simulink's Uniform Random Number: numbers uniform on [minimum, maximum), one per sample time."""

    TYPE = "uniform-random-number"
    KEYS = {"minimum": Key("number", -1.0, "the lower end"), "maximum": Key("number", 1.0, "the upper end"),
            "seed": _SEED, "sample_time": _TS}
    DOC = "y uniform on [minimum, maximum), new every Ts"

    def check_values(self):
        self.lo, self.hi = _scalar(self, "minimum"), _scalar(self, "maximum")
        if not self.lo < self.hi:
            raise BlockError(f"`minimum` ({self.lo:g}) must be below `maximum` ({self.hi:g}).", key="minimum")

    def value(self, k):
        return self.lo + (self.hi - self.lo) * draw(self.seed, k, "uniform")

    def describe(self):
        return f"uniform [{self.lo:g}, {self.hi:g})"


@register
class BandLimitedWhiteNoise(_RandomSource):
    """Simulink's Band-Limited White Noise: normal numbers of variance power/Ts, one per sample time, so the
    held signal has the power spectral density ``power`` (Simulink's scaling)."""

    TYPE = "band-limited-white-noise"
    KEYS = {"power": Key("number", 0.1, "the noise power, the height of its PSD (Simulink's default 0.1)"),
            "seed": Key("number", 23341.0, "the seed, a whole number >= 0 (Simulink's default 23341)"),
            "sample_time": _TS}
    DOC = "y = sqrt(power/Ts) n_k, n_k standard normal, new every Ts"

    def check_values(self):
        self.power = _scalar(self, "power")
        if self.power < 0:
            raise BlockError(f"`power` must be at least 0; got {self.power:g}.", key="power")

    def value(self, k):
        return math.sqrt(self.power / self.sample.period) * draw(self.seed, k)

    def describe(self):
        return f"white noise, power {self.power:g}"
