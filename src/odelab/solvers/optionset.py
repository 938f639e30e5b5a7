"""The registry of solver options (MATLAB's ``odeset``): each declared once, with its spellings.

A :class:`SolverOption` names the option as odelab spells it, MATLAB's ``odeset`` names and any
other accepted spelling (compared without case and underscores), how an experiment file gives it
(its TOML type, or none for options only Python callers pass), its default as a reader sees it,
a sentence for ``odelab explain``/the docs, its check, and which methods take it besides those
whose :attr:`~odelab.solvers.registry.Method.options` list it. :mod:`odelab.solvers.options`
parses and checks with it, the experiment schema builds ``[solver]`` from it, ``odelab explain``
and the "does not apply" messages read it. A new option is one :func:`register_option` call.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.exceptions import InputError

__all__ = ["SolverOption", "OptionContext", "OPTIONS", "register_option", "canonical", "TOML_TYPES", "DEFAULT_RTOL",
           "DEFAULT_ATOL"]

EPS = float(np.finfo(float).eps)

# How an experiment file gives an option ([solver] key types; odelab.experiment.schema maps them)
TOML_TYPES = ("number", "numbers", "integer", "switch", "state names", "matrix", "choice", "text")


@dataclass
class OptionContext:
    """What an option's check may need: the method, the number of states, the span, the options resolved so
    far, and the notes to give the user (MATLAB's adjustments, e.g. RelTol raised to 100 eps)."""

    method: Any
    n: int
    span: float
    resolved: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class SolverOption:
    """One solver option.

    Attributes
    ----------
    name
        odelab's name (``"rtol"``), the keyword of :func:`odelab.solve` and the ``[solver]`` key.
    doc
        One sentence for ``odelab explain solver.<name>`` and the docs.
    matlab
        MATLAB's ``odeset`` names (``("RelTol",)``); accepted too, and listed by messages.
    aliases
        Other accepted spellings (SciPy's ``first_step``).
    default
        The default as a reader sees it (``"1e-3"``), or None.
    toml
        How an experiment file gives it, one of :data:`TOML_TYPES`, or None (Python callers only).
    choices
        The valid strings of a ``"choice"``.
    check
        ``check(value, ctx) -> value``: the checked (converted) value, or raise
        :class:`~odelab.exceptions.InputError` naming the option, the value and the fix. None: the
        driver that takes it checks it (the stiff solvers' options, in odelab.solvers.implicit).
    takes
        ``takes(method) -> bool``: methods that take the option besides those that list it; None: only
        those.
    one_based
        MATLAB spellings of an index option count from 1 (what a MATLAB user types).
    """

    name: str
    doc: str
    matlab: tuple[str, ...] = ()
    aliases: tuple[str, ...] = ()
    default: str | None = None
    toml: str | None = None
    choices: tuple[str, ...] = ()
    check: Callable[[Any, OptionContext], Any] | None = None
    takes: Callable[[Any], bool] | None = None
    one_based: bool = False

    def __post_init__(self):
        if self.toml is not None and self.toml not in TOML_TYPES:
            raise ValueError(f"SolverOption {self.name!r}: toml {self.toml!r} is not one of {TOML_TYPES}.")
        if (self.toml == "choice") != bool(self.choices):
            raise ValueError(f"SolverOption {self.name!r}: a \"choice\" lists its `choices` (and only a choice).")

    @property
    def spellings(self) -> tuple[str, ...]:
        """Every accepted spelling, odelab's first."""
        return (self.name, *self.matlab, *self.aliases)


OPTIONS: dict[str, SolverOption] = {}


def _key(name: str) -> str:
    return name.lower().replace("_", "")


def register_option(option: SolverOption) -> SolverOption:
    """Add ``option`` to :data:`OPTIONS`; its spellings may not clash with another option's."""
    for other in OPTIONS.values():
        if other.name != option.name and {_key(s) for s in other.spellings} & {_key(s) for s in option.spellings}:
            raise ValueError(f"option {option.name!r}: a spelling clashes with option {other.name!r}.")
    OPTIONS[option.name] = option
    return option


def canonical(name: str) -> str | None:
    """odelab's name of an option given in any accepted spelling (``"RelTol"`` -> ``"rtol"``), or None."""
    wanted = _key(name)
    for option in OPTIONS.values():
        if any(_key(s) == wanted for s in option.spellings):
            return option.name
    return None


def fmt(value) -> str:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    return repr(value)


# --- the checks (each names the option, the value and the fix) ---------------------------------------------

def positive(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InputError(f"`{name}` must be a positive number; got {value!r}.", key=name)
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"`{name}` must be a positive, finite number; got {value!r}.", key=name)
    return value


def as_bool(name: str, value) -> bool:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, str) and value.lower() in ("on", "off"):
        return value.lower() == "on"
    raise InputError(f"`{name}` must be true/false (or MATLAB's 'on'/'off'); got {value!r}.", key=name)


def index_list(name: str, value) -> list[int]:
    items = [value] if isinstance(value, (int, np.integer)) and not isinstance(value, bool) else value
    try:
        out = list(items)
    except TypeError:
        out = None
    if out is None or not all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) for i in out):
        raise InputError(f"`{name}` must be a list of state indices (whole numbers); got {fmt(value)}.", key=name)
    return [int(i) for i in out]


def state_indices(name: str, value, n: int) -> np.ndarray:
    indices = index_list(name, value)
    for i in indices:
        if not 0 <= i < n:
            raise InputError(
                f"`{name}` index {i} is out of range: the state has {n} component{'s' if n != 1 else ''} "
                f"(indices 0..{n - 1}; MATLAB's NonNegative/OutputSel spellings count from 1).",
                key=name,
            )
    if len(set(indices)) != len(indices):
        raise InputError(f"`{name}` lists an index twice: {fmt(value)}.", key=name)
    return np.array(sorted(indices) if name == "nonnegative" else indices, dtype=np.intp)


def _rtol(value, ctx: OptionContext) -> float:
    rtol = positive("rtol", value)
    if rtol < 100 * EPS:
        rtol = 100 * EPS
        msg = f"RelTol has been increased to {rtol:g} (100*eps), the smallest value MATLAB's solvers allow."
        ctx.notes.append(msg)
        warnings.warn(msg, stacklevel=5)
    return rtol


def _atol(value, ctx: OptionContext):
    n = ctx.n
    if np.iscomplexobj(value) or isinstance(value, (bool, str)):
        raise InputError(f"`atol` must be a positive number or one per state; got {value!r}.", key="atol")
    try:
        atol = np.array(value, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InputError(f"`atol` must be a positive number or one per state; got {value!r}.", key="atol") from None
    if atol.size not in (1, n):
        raise InputError(
            f"`atol` has {atol.size} values but there {'is 1 state' if n == 1 else f'are {n} states'}: "
            "give one value, or one per state.",
            key="atol",
        )
    if not np.all(np.isfinite(atol)) or np.any(atol <= 0):
        raise InputError(f"`atol` values must be positive and finite; got {fmt(atol)}.", key="atol")
    norm_control = ctx.resolved.get("norm_control", False)
    if norm_control and atol.size != 1:
        raise InputError("`atol` must be a single number when `norm_control` is on (as in MATLAB).", key="atol")
    return float(atol[0]) if norm_control else np.broadcast_to(atol, (n,)).copy()


def _refine(value, ctx: OptionContext) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer, float)) or value != int(value) or value < 1:
        raise InputError(f"`refine` must be a whole number >= 1; got {value!r}.", key="refine")
    return int(value)


def _max_steps(value, ctx: OptionContext) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InputError(f"`max_steps` must be a whole number >= 1 (or 0 for no limit); got {value!r}.",
                         key="max_steps")
    return int(value)


def _nonnegative(value, ctx: OptionContext):
    indices = state_indices("nonnegative", value, ctx.n)
    return indices if indices.size else None


def _output_fcn(value, ctx: OptionContext):
    if not callable(value):
        raise InputError(f"`output_fcn` must be a function output_fcn(t, y, flag); got {value!r}.", key="output_fcn")
    return value


def _dependence(value, ctx: OptionContext) -> str:
    if not isinstance(value, str) or value.lower() not in ("none", "weak", "strong"):
        raise InputError(f"`mstate_dependence` must be 'none', 'weak' or 'strong' (MATLAB's MStateDependence); "
                         f"got {value!r}.", key="mstate_dependence")
    return value.lower()


def _args(value, ctx: OptionContext) -> tuple:
    if not isinstance(value, (tuple, list)):
        raise InputError(f"`args` must be a tuple of extra arguments for fun(t, y, *args), e.g. args=(k,); "
                         f"got {value!r}.", key="args")
    return tuple(value)


_RTOL, _ATOL = "1e-3", "1e-6"  # MATLAB's RelTol and AbsTol defaults: the one place they are written

for _option in (
    SolverOption("rtol", f"Relative tolerance (MATLAB's RelTol; default {_RTOL} for MATLAB's methods).",
                 ("RelTol",), default=_RTOL, toml="number", check=_rtol),
    SolverOption("atol", f"Absolute tolerance, a number or one per state (MATLAB's AbsTol; default {_ATOL}).",
                 ("AbsTol",), default=_ATOL, toml="numbers", check=_atol),
    SolverOption("max_step", "The largest step (MATLAB's MaxStep; default a tenth of the span).", ("MaxStep",),
                 default="a tenth of the span", toml="number",
                 check=lambda v, ctx: min(ctx.span, positive("max_step", v))),
    SolverOption("initial_step", "The first step to try (MATLAB's InitialStep).", ("InitialStep",),
                 aliases=("first_step",), toml="number", check=lambda v, ctx: positive("initial_step", v)),
    SolverOption("refine", "Output points per step (MATLAB's Refine; ode45's default 4).", ("Refine",),
                 toml="integer", check=_refine),
    SolverOption("norm_control", "Control the error in norm rather than per component (MATLAB's NormControl).",
                 ("NormControl",), default="false", toml="switch",
                 check=lambda v, ctx: as_bool("norm_control", v)),
    SolverOption("h", "The step of a fixed-step method (euler, heun, midpoint, rk3, rk4), in the units of t.",
                 aliases=("step",), toml="number", check=lambda v, ctx: positive("h", v)),
    SolverOption("max_steps", "The largest number of steps before the case stops as failed; the run's own budget "
                 "(--max-steps) caps it.", ("MaxSteps",), default="0 (no limit)", toml="integer", check=_max_steps),
    SolverOption("max_order", "ode15s's and ode15i's highest order, 1 to 5 (MATLAB's MaxOrder).", ("MaxOrder",), default="5",
                 toml="integer"),
    SolverOption("bdf", "ode15s with backward differentiation formulas instead of NDFs (MATLAB's BDF).", ("BDF",),
                 default="false", toml="switch"),
    SolverOption("vectorized", "The equations accept many states at once (MATLAB's Vectorized), for the stiff "
                 "solvers' Jacobian.", ("Vectorized",), default="false", toml="switch"),
    SolverOption("nonnegative", "States kept nonnegative (MATLAB's NonNegative), by name.", ("NonNegative",),
                 toml="state names", check=_nonnegative, one_based=True),
    SolverOption("mass", "A mass matrix M in M y' = f, of expressions of t, the states and parameters (MATLAB's "
                 "Mass); singular with ode15s or ode23t for an index-1 DAE.", ("Mass",), toml="matrix",
                 check=lambda v, ctx: v),
    SolverOption("mstate_dependence", "How the mass matrix depends on the state (MATLAB's MStateDependence).",
                 ("MStateDependence",), toml="choice", choices=("none", "weak", "strong"), check=_dependence),
    SolverOption("events", "Event functions ev(t, y) -> (value, isterminal, direction) (MATLAB's Events); an "
                 "experiment file writes [events] instead.", ("Events",), check=lambda v, ctx: v),
    SolverOption("output_fcn", "A function output_fcn(t, y, flag) called after each step (MATLAB's OutputFcn).",
                 ("OutputFcn",), check=_output_fcn),
    SolverOption("output_sel", "The components passed to output_fcn, 0-based (MATLAB's OutputSel: 1-based).",
                 ("OutputSel",), check=lambda v, ctx: state_indices("output_sel", v, ctx.n), one_based=True),
    SolverOption("args", "Extra arguments for fun(t, y, *args), the events and the mass.", default="()",
                 check=_args),
    SolverOption("jacobian", "df/dy: a constant matrix or a function J(t, y) (MATLAB's Jacobian); an experiment "
                 "file's system gets its exact Jacobian when odelab knows it.", ("Jacobian",)),
    SolverOption("jpattern", "The sparsity pattern of df/dy (MATLAB's JPattern).", ("JPattern",)),
):
    register_option(_option)


#: MATLAB's default tolerances as numbers, read from their entries above.
DEFAULT_RTOL = float(OPTIONS["rtol"].default)
DEFAULT_ATOL = float(OPTIONS["atol"].default)
