"""What every diagram block is: the :class:`Block` base class, its :class:`Key` declarations and
the checks and realisations blocks share (:func:`polynomial_pair`, :func:`controller_canonical`).

The block classes themselves live in :mod:`odelab.systems.diagram.blocks` (the core blocks and
the registry :data:`~odelab.systems.diagram.blocks.BLOCKS`) and in one module per family
(discrete, switching, tables, ratelimit, transport). Each imports only this module, so the
registry can import them all without an import circle.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from odelab.exceptions import InputError
from odelab.expressions.compile import PortableState

__all__ = ["BLOCKS", "REQUIRED", "ZC_KEY", "Block", "BlockError", "Key", "controller_canonical", "polynomial_pair",
           "register"]

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


class Block(PortableState):
    """Base class: a block with named inputs (references to other blocks' outputs). It pickles with its
    compiled expressions as their texts (a built diagram travels to a Dask worker)."""

    TYPE: ClassVar[str] = ""
    KEYS: ClassVar[dict[str, Key]] = {}
    #: other names a file may give a key, as MATLAB writes them (a PID's ``Kp`` for ``P``)
    ALIASES: ClassVar[dict[str, str]] = {}
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


# One registry: TOML type name -> block class. A block class joins it with ``@register`` where it
# is defined (the core blocks in blocks.py, the families in their own modules); blocks.py imports
# every family module, so importing it fills the registry. Source types (step, ramp, ...) are the
# input signal types of experiment files, built from odelab.signals by the loader.
BLOCKS: dict[str, type[Block]] = {}


def register(cls: type[Block]) -> type[Block]:
    """Add a block class to :data:`BLOCKS` under its ``TYPE`` (a class decorator)."""
    if not isinstance(getattr(cls, "TYPE", None), str) or not cls.TYPE:
        raise TypeError(f"block class {cls.__name__} needs a TYPE (its TOML type name) to be registered")
    BLOCKS[cls.TYPE] = cls
    return cls
