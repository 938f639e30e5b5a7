"""Validation of solver arguments, with MATLAB's ``odeset`` names as aliases.

Each validator names the argument, the value received and the fix, as SciPy's ``_ivp``
validators do; all raise :class:`~odelab.exceptions.InputError` (a ``ValueError``).
"""

from __future__ import annotations

import difflib
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from odelab.exceptions import InputError
from odelab.solvers.registry import Method, join_names, methods_with

__all__ = ["SolverOptions", "normalize_options", "as_tspan", "as_y0", "resolve_options"]

EPS = float(np.finfo(float).eps)

# Accepted spellings, compared without case and underscores: MATLAB's odeset names
# (RelTol, AbsTol, MaxStep, InitialStep, Refine, NormControl), odelab's and SciPy's.
_ALIASES = {
    "rtol": "rtol",
    "reltol": "rtol",
    "atol": "atol",
    "abstol": "atol",
    "maxstep": "max_step",
    "initialstep": "initial_step",
    "firststep": "initial_step",
    "refine": "refine",
    "normcontrol": "norm_control",
    "h": "h",
    "step": "h",
    "maxsteps": "max_steps",
    "events": "events",
    "nonnegative": "nonnegative",
    "mass": "mass",
    "mstatedependence": "mstate_dependence",
    "outputfcn": "output_fcn",
    "outputsel": "output_sel",
    "args": "args",
    # the stiff solvers' odeset options (see odelab.solvers.implicit)
    "jacobian": "jacobian",
    "jpattern": "jpattern",
    "vectorized": "vectorized",
    "maxorder": "max_order",
    "bdf": "bdf",
}
OPTION_NAMES = ("rtol", "atol", "max_step", "initial_step", "refine", "norm_control", "h", "max_steps",
                "events", "nonnegative", "mass", "mstate_dependence", "output_fcn", "output_sel", "args",
                "jacobian", "jpattern", "vectorized", "max_order", "bdf")
# MATLAB's spellings of index options count from 1 (what a MATLAB user types); odelab's from 0.
_ONE_BASED = {"NonNegative": "nonnegative", "OutputSel": "output_sel"}


def _fmt(value) -> str:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    return repr(value)


def normalize_options(options: Mapping[str, object], method: Method) -> dict[str, object]:
    """Map user option names (any accepted spelling) to odelab's, checking the method takes them."""
    out: dict[str, object] = {}
    given: dict[str, str] = {}
    for name, value in options.items():
        canonical = _ALIASES.get(name.lower().replace("_", ""))
        if canonical is None:
            close = difflib.get_close_matches(name, [*OPTION_NAMES, "RelTol", "AbsTol", "MaxStep"], n=1)
            hint = f" Did you mean `{close[0]}`?" if close else ""
            raise InputError(
                f"unknown solver option `{name}`.{hint} Options: {', '.join(OPTION_NAMES)} "
                "(MATLAB's RelTol, AbsTol, MaxStep, InitialStep, Refine, NormControl, Events, NonNegative, "
                "Mass, MStateDependence, OutputFcn, OutputSel also work).",
                key=name,
            )
        if value is None:
            continue
        if canonical in given:
            raise InputError(
                f"`{name}` and `{given[canonical]}` set the same option; give it once.", key=name
            )
        if canonical not in method.options:
            raise InputError(_not_for_method(canonical, name, method), key=name)
        given[canonical] = name
        if name in _ONE_BASED:
            value = _from_one_based(name, value)
        out[canonical] = value
    return out


def _index_list(name: str, value) -> list[int]:
    items = [value] if isinstance(value, (int, np.integer)) and not isinstance(value, bool) else value
    try:
        out = list(items)
    except TypeError:
        out = None
    if out is None or not all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) for i in out):
        raise InputError(f"`{name}` must be a list of state indices (whole numbers); got {_fmt(value)}.", key=name)
    return [int(i) for i in out]


def _from_one_based(name: str, value) -> list[int]:
    indices = _index_list(name, value)
    if any(i < 1 for i in indices):
        raise InputError(
            f"`{name}` holds MATLAB's 1-based state indices; got {_fmt(value)}. Use "
            f"`{_ONE_BASED[name]}` for 0-based (Python) indices.",
            key=name,
        )
    return [i - 1 for i in indices]


def _state_indices(name: str, value, n: int) -> np.ndarray:
    indices = _index_list(name, value)
    for i in indices:
        if not 0 <= i < n:
            raise InputError(
                f"`{name}` index {i} is out of range: the state has {n} component{'s' if n != 1 else ''} "
                f"(indices 0..{n - 1}; MATLAB's NonNegative/OutputSel spellings count from 1).",
                key=name,
            )
    if len(set(indices)) != len(indices):
        raise InputError(f"`{name}` lists an index twice: {_fmt(value)}.", key=name)
    return np.array(sorted(indices) if name == "nonnegative" else indices, dtype=np.intp)


def _not_for_method(canonical: str, name: str, method: Method) -> str:
    if canonical == "h":
        return (
            f"`{name}` (a fixed step) is for the fixed-step methods "
            f"({', '.join(methods_with(lambda m: not m.adaptive))}); {method.name} chooses its own steps: use "
            "`rtol`/`atol`, `max_step` or `initial_step` instead."
        )
    if canonical in ("mass", "mstate_dependence"):
        # say what is wrong with the mass, not which option name the solver lacks
        takes = methods_with(lambda m: canonical in m.options)
        if canonical == "mass":
            return (f"`{name}` (M y' = f): {method.name} solves y' = f only, with no mass matrix; the solvers that "
                    f"take a mass are {', '.join(takes)}.")
        return (f"`{name}` describes a mass that depends on t or the states, but {method.name} takes a constant mass "
                f"matrix only; a mass M(t, y) is solved by {', '.join(takes)} (remove `{name}` for a constant "
                "mass).")
    if canonical == "nonnegative" and method.stiff and method.source == "odelab":
        stiff = methods_with(lambda m: m.stiff and "nonnegative" in m.options)
        return (f"`{name}` is not available for {method.name}, as in MATLAB (its NonNegative documentation excludes "
                f"{method.name}); keep the solution non-negative with {join_names(stiff, 'or')}.")
    if not method.adaptive:
        return (
            f"`{name}` does not apply to {method.name}, a fixed-step method: it takes only the "
            "step `h`. Use ode23/ode45 for error control."
        )
    return f"`{name}` does not apply to {method.name}; it accepts: {', '.join(method.options)}."


def as_tspan(tspan) -> np.ndarray:
    """Check a MATLAB-style ``tspan``: >= 2 finite, strictly monotonic entries."""
    try:
        arr = np.asarray(tspan, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"`tspan` must be a sequence of numbers [t0, tf, ...]; got {tspan!r}.", key="tspan") from None
    if arr.ndim != 1 or arr.size < 2:
        raise InputError(
            f"`tspan` must be [t0, tf] or a longer sequence of output times; got {_fmt(arr)}.", key="tspan"
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"`tspan` entries must be finite; got {_fmt(arr)}.", key="tspan")
    if arr[0] == arr[-1]:
        raise InputError(
            f"`tspan` starts and ends at the same time ({arr[0]:g}); the last entry must differ from the first.",
            key="tspan",
        )
    direction = np.sign(arr[-1] - arr[0])
    steps = direction * np.diff(arr)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0)) + 1
        raise InputError(
            f"`tspan` entries must strictly {'increase' if direction > 0 else 'decrease'}; "
            f"entry {i} ({arr[i]:g}) follows {arr[i - 1]:g}.",
            key="tspan",
        )
    return arr


def as_y0(y0, *, allow_complex: bool = False) -> np.ndarray:
    """Check the initial state: a scalar or 1-D sequence of finite numbers (complex if allowed)."""
    if np.iscomplexobj(y0) and not allow_complex:
        raise InputError(f"`y0` must be real; got {y0!r}.", key="y0")
    try:
        arr = np.array(y0, dtype=complex if np.iscomplexobj(y0) else float)
    except (TypeError, ValueError):
        raise InputError(f"`y0` must be a number or a sequence of numbers; got {y0!r}.", key="y0") from None
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim == 2 and 1 in arr.shape:  # MATLAB users write column or row vectors
        arr = arr.ravel()
    if arr.ndim != 1 or arr.size == 0:
        raise InputError(f"`y0` must be a number or a 1-D sequence; got shape {arr.shape}.", key="y0")
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"`y0` must be finite; entry {i} is {arr[i].item()!r}.", key="y0")
    return arr


def _positive(name: str, value, *, allow_array=False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InputError(f"`{name}` must be a positive number; got {value!r}.", key=name)
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"`{name}` must be a positive, finite number; got {value!r}.", key=name)
    return value


@dataclass(frozen=True)
class SolverOptions:
    """Options resolved for one solve (defaults filled in, MATLAB's adjustments applied)."""

    rtol: float = 1e-3
    atol: np.ndarray | float = 1e-6
    max_step: float = math.inf
    initial_step: float = math.nan
    refine: int = 1
    norm_control: bool = False
    h: float = math.nan
    max_steps: int = 0
    warnings: tuple[str, ...] = ()
    events: object = None
    nonnegative: np.ndarray | None = None
    mass: object = None
    mstate_dependence: str | None = None
    output_fcn: object = None
    output_sel: np.ndarray | None = None
    args: tuple = ()
    extra: Mapping[str, object] | None = None  # the stiff solvers' options (odelab.solvers.implicit)


def _as_args(value) -> tuple:
    if not isinstance(value, (tuple, list)):
        raise InputError(f"`args` must be a tuple of extra arguments for fun(t, y, *args), e.g. args=(k,); "
                         f"got {value!r}.", key="args")
    return tuple(value)


def _as_bool(name, value) -> bool:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, str) and value.lower() in ("on", "off"):
        return value.lower() == "on"
    raise InputError(f"`{name}` must be true/false (or MATLAB's 'on'/'off'); got {value!r}.", key=name)


def resolve_options(method: Method, opts: Mapping[str, object], tspan: np.ndarray, n: int) -> SolverOptions:
    """Fill in defaults and check every value, as MATLAB's ``odearguments`` does."""
    notes: list[str] = []
    span = abs(float(tspan[-1] - tspan[0]))
    if not method.adaptive:
        if "h" not in opts:
            raise InputError(
                f"{method.name} is a fixed-step method: give the step `h` (e.g. h = {span / 100:g} "
                "for 100 steps).",
                key="h",
            )
        return SolverOptions(h=_positive("h", opts["h"]), args=_as_args(opts.get("args", ())))

    rtol = _positive("rtol", opts.get("rtol", 1e-3))
    if rtol < 100 * EPS:
        rtol = 100 * EPS
        msg = f"RelTol has been increased to {rtol:g} (100*eps), the smallest value MATLAB's solvers allow."
        notes.append(msg)
        warnings.warn(msg, stacklevel=4)

    norm_control = _as_bool("norm_control", opts.get("norm_control", False))
    atol_raw = opts.get("atol", 1e-6)
    if np.iscomplexobj(atol_raw) or isinstance(atol_raw, (bool, str)):
        raise InputError(f"`atol` must be a positive number or one per state; got {atol_raw!r}.", key="atol")
    try:
        atol = np.array(atol_raw, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InputError(f"`atol` must be a positive number or one per state; got {atol_raw!r}.", key="atol") from None
    if atol.size not in (1, n):
        raise InputError(
            f"`atol` has {atol.size} values but there {'is 1 state' if n == 1 else f'are {n} states'}: "
            "give one value, or one per state.",
            key="atol",
        )
    if not np.all(np.isfinite(atol)) or np.any(atol <= 0):
        raise InputError(f"`atol` values must be positive and finite; got {_fmt(atol)}.", key="atol")
    if norm_control and atol.size != 1:
        raise InputError("`atol` must be a single number when `norm_control` is on (as in MATLAB).", key="atol")
    atol_value = float(atol[0]) if norm_control else np.broadcast_to(atol, (n,)).copy()

    if "max_step" in opts:
        max_step = min(span, _positive("max_step", opts["max_step"]))
    else:
        max_step = 0.1 * span if method.matlab_defaults else math.inf
    initial_step = _positive("initial_step", opts["initial_step"]) if "initial_step" in opts else math.nan

    refine = opts.get("refine", method.refine)
    if isinstance(refine, bool) or not isinstance(refine, (int, np.integer, float)) or refine != int(refine) or refine < 1:
        raise InputError(f"`refine` must be a whole number >= 1; got {refine!r}.", key="refine")
    max_steps = opts.get("max_steps", 0)
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 0:
        raise InputError(f"`max_steps` must be a whole number >= 1 (or 0 for no limit); got {max_steps!r}.", key="max_steps")
    nonnegative = _state_indices("nonnegative", opts["nonnegative"], n) if "nonnegative" in opts else None
    if nonnegative is not None and nonnegative.size == 0:
        nonnegative = None
    output_sel = _state_indices("output_sel", opts["output_sel"], n) if "output_sel" in opts else None
    output_fcn = opts.get("output_fcn")
    if output_fcn is not None and not callable(output_fcn):
        raise InputError(f"`output_fcn` must be a function output_fcn(t, y, flag); got {output_fcn!r}.",
                         key="output_fcn")
    dependence = opts.get("mstate_dependence")
    if dependence is not None and (not isinstance(dependence, str)
                                   or dependence.lower() not in ("none", "weak", "strong")):
        raise InputError(f"`mstate_dependence` must be 'none', 'weak' or 'strong' (MATLAB's MStateDependence); "
                         f"got {dependence!r}.", key="mstate_dependence")
    extra = None
    if "jacobian" in method.options:  # the stiff solvers' own options (Jacobian, JPattern, MaxOrder...)
        from odelab.solvers.implicit import resolve_extras

        extra = resolve_extras(method, opts, n)
    return SolverOptions(
        extra=extra,
        events=opts.get("events"),
        nonnegative=nonnegative,
        mass=opts.get("mass"),
        mstate_dependence=dependence.lower() if dependence is not None else None,
        output_fcn=output_fcn,
        output_sel=output_sel,
        args=_as_args(opts.get("args", ())),
        rtol=rtol,
        atol=atol_value,
        max_step=max_step,
        initial_step=initial_step,
        refine=int(refine),
        norm_control=norm_control,
        max_steps=int(max_steps),
        warnings=tuple(notes),
    )
