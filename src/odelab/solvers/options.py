"""Validation of solver arguments, with MATLAB's ``odeset`` names as aliases.

Each validator names the argument, the value received and the fix, as SciPy's ``_ivp``
validators do; all raise :class:`~odelab.exceptions.InputError` (a ``ValueError``).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace

import numpy as np

from odelab.exceptions import InputError
from odelab.solvers.optionset import DEFAULT_ATOL, DEFAULT_RTOL, OPTIONS, OptionContext, canonical, fmt, index_list
from odelab.solvers.registry import Method, get_method, join_names, methods_with

__all__ = ["SolverOptions", "normalize_options", "as_tspan", "as_y0", "resolve_options", "resolved_for",
           "given_options", "method_options", "takers"]

EPS = float(np.finfo(float).eps)


def method_options(method: Method) -> tuple[str, ...]:
    """The options ``method`` takes: those its registry entry lists, then registered options that take it."""
    extra = tuple(o.name for o in OPTIONS.values()
                  if o.takes is not None and o.name not in method.options and o.takes(method))
    return tuple(method.options) + extra


def takers(name: str) -> list[str]:
    """The methods that take option ``name``, in the order messages list them."""
    return methods_with(lambda m: name in method_options(m))


def normalize_options(options: Mapping[str, object], method: Method) -> dict[str, object]:
    """Map user option names (any accepted spelling) to odelab's, checking the method takes them."""
    out: dict[str, object] = {}
    given: dict[str, str] = {}
    accepted = method_options(method)
    for name, value in options.items():
        name_canonical = canonical(name)
        if name_canonical is None:
            close = difflib.get_close_matches(name, [*OPTIONS, "RelTol", "AbsTol", "MaxStep"], n=1)
            hint = f" Did you mean `{close[0]}`?" if close else ""
            matlab = [m for o in OPTIONS.values() for m in o.matlab if m != "MaxSteps"]
            raise InputError(
                f"unknown solver option `{name}`.{hint} Options: {', '.join(OPTIONS)} "
                f"(MATLAB's {', '.join(matlab)} also work).",
                key=name,
            )
        if value is None:
            continue
        if name_canonical in given:
            raise InputError(
                f"`{name}` and `{given[name_canonical]}` set the same option; give it once.", key=name
            )
        if name_canonical not in accepted:
            raise InputError(_not_for_method(name_canonical, name, method), key=name)
        given[name_canonical] = name
        if OPTIONS[name_canonical].one_based and name != name_canonical and name in OPTIONS[name_canonical].matlab:
            value = _from_one_based(name, name_canonical, value)
        out[name_canonical] = value
    return out


def _from_one_based(name: str, canonical_name: str, value) -> list[int]:
    indices = index_list(name, value)
    if any(i < 1 for i in indices):
        raise InputError(
            f"`{name}` holds MATLAB's 1-based state indices; got {fmt(value)}. Use "
            f"`{canonical_name}` for 0-based (Python) indices.",
            key=name,
        )
    return [i - 1 for i in indices]


def _not_for_method(canonical: str, name: str, method: Method) -> str:
    if canonical == "h":
        return (
            f"`{name}` (a fixed step) is for the fixed-step methods "
            f"({', '.join(methods_with(lambda m: not m.adaptive))}); {method.name} chooses its own steps: use "
            "`rtol`/`atol`, `max_step` or `initial_step` instead."
        )
    if canonical in ("mass", "mstate_dependence"):
        # say what is wrong with the mass, not which option name the solver lacks
        takes = takers(canonical)
        if canonical == "mass":
            return (f"`{name}` (M y' = f): {method.name} solves y' = f only, with no mass matrix; the solvers that "
                    f"take a mass are {', '.join(takes)}.")
        return (f"`{name}` describes a mass that depends on t or the states, but {method.name} takes a constant mass "
                f"matrix only; a mass M(t, y) is solved by {', '.join(takes)} (remove `{name}` for a constant "
                "mass).")
    if canonical == "nonnegative" and method.stiff and method.source == "odelab":
        stiff = methods_with(lambda m: m.stiff and "nonnegative" in method_options(m))
        return (f"`{name}` is not available for {method.name}, as in MATLAB (its NonNegative documentation excludes "
                f"{method.name}); keep the solution non-negative with {join_names(stiff, 'or')}.")
    if not method.adaptive:
        return (
            f"`{name}` does not apply to {method.name}, a fixed-step method: it takes only the "
            "step `h`. Use ode23/ode45 for error control."
        )
    return f"`{name}` does not apply to {method.name}; it accepts: {', '.join(method_options(method))}."


def as_tspan(tspan) -> np.ndarray:
    """Check a MATLAB-style ``tspan``: >= 2 finite, strictly monotonic entries."""
    try:
        arr = np.asarray(tspan, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"`tspan` must be a sequence of numbers [t0, tf, ...]; got {tspan!r}.", key="tspan") from None
    if arr.ndim != 1 or arr.size < 2:
        raise InputError(
            f"`tspan` must be [t0, tf] or a longer sequence of output times; got {fmt(arr)}.", key="tspan"
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"`tspan` entries must be finite; got {fmt(arr)}.", key="tspan")
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


@dataclass(frozen=True)
class SolverOptions:
    """Options resolved for one solve (defaults filled in, MATLAB's adjustments applied), by
    :func:`resolve_options`: once per call of the keyword API, once per case when an experiment file is loaded
    (``Problem.solver_options``), and carried to the driver unchanged (:func:`odelab.solvers.api.solve`'s
    ``resolved``). ``method``, ``span`` and ``n`` say what they were resolved for, ``given`` the options as
    given (odelab's names) that a solve of another span starts from; :meth:`updated` changes some of them
    (a step budget checked alone, tighter tolerances resolved again)."""

    rtol: float = DEFAULT_RTOL
    atol: np.ndarray | float = DEFAULT_ATOL
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
    more: Mapping[str, object] = field(default_factory=dict)  # registered options without a field, checked
    method: str = ""
    span: float = math.nan
    n: int = 0
    given: Mapping[str, object] = field(default_factory=dict)  # normalised (odelab's names), as given

    def fits(self, method: Method, tspan: np.ndarray, n: int) -> bool:
        """Whether these options were resolved for ``method`` over ``tspan``'s span and ``n`` states."""
        return self.method == method.name and self.n == n and self.span == abs(float(tspan[-1] - tspan[0]))

    def updated(self, **changes) -> SolverOptions:
        """These options with ``changes`` (odelab's names, as given; None removes one): a step budget
        (``max_steps``) or ``refine`` is checked alone, any other change resolves them again from ``given``."""
        method = get_method(self.method)
        given = {k: v for k, v in {**self.given, **changes}.items() if v is not None}
        if changes and set(changes) <= {"max_steps", "refine"} and math.isnan(self.h):
            ctx = OptionContext(method, self.n, self.span)
            defaults = {"max_steps": 0, "refine": method.refine}  # as resolve_options fills them in
            return replace(self, **{name: _check(name, given.get(name, defaults[name]), ctx) for name in changes},
                           given=given)
        return resolve_options(method, given, np.array([0.0, self.span]), self.n)


def resolved_for(method: Method, options: Mapping[str, object] | SolverOptions, tspan: np.ndarray,
                 n: int) -> SolverOptions:
    """``options`` resolved for ``method`` over ``tspan`` with ``n`` states: options resolved for them already
    (a loaded case's) as they are, others (any accepted spelling) normalised and resolved once."""
    if isinstance(options, SolverOptions):
        if options.fits(method, tspan, n):
            return options
        options = options.given if options.method == method.name else normalize_options(options.given, method)
        return resolve_options(method, options, tspan, n)
    return resolve_options(method, normalize_options(options, method), tspan, n)


def given_options(options: Mapping[str, object] | SolverOptions) -> dict[str, object]:
    """The options as given: a resolved :class:`SolverOptions`' ``given`` (odelab's names), a dict as it is."""
    return dict(options.given) if isinstance(options, SolverOptions) else dict(options)


# The options with a field of their own, checked in this order (norm_control before atol, which reads it).
_CHECK_ORDER = ("rtol", "norm_control", "atol", "max_step", "initial_step", "refine", "max_steps", "nonnegative",
                "output_sel", "output_fcn", "mstate_dependence", "events", "mass", "args")


def _check(name: str, value, ctx: OptionContext):
    value = OPTIONS[name].check(value, ctx)
    ctx.resolved[name] = value
    return value


def _more(method: Method, opts: Mapping[str, object], ctx: OptionContext) -> dict[str, object]:
    """Registered options without a field of their own, checked: the drivers that take them read ``more``."""
    own = {f.name for f in fields(SolverOptions)}
    return {name: _check(name, opts[name], ctx) for name in method_options(method)
            if name not in own and name in opts and OPTIONS.get(name) is not None and OPTIONS[name].check}


def resolve_options(method: Method, opts: Mapping[str, object], tspan: np.ndarray, n: int) -> SolverOptions:
    """Fill in defaults and check every value, as MATLAB's ``odearguments`` does (each option's check is
    declared with it, in :mod:`odelab.solvers.optionset`)."""
    span = abs(float(tspan[-1] - tspan[0]))
    ctx = OptionContext(method, n, span)
    if not method.adaptive:
        if "h" not in opts:
            raise InputError(
                f"{method.name} is a fixed-step method: give the step `h` (e.g. h = {span / 100:g} "
                "for 100 steps).",
                key="h",
            )
        return SolverOptions(h=_check("h", opts["h"], ctx), args=_check("args", opts.get("args", ()), ctx),
                             more=_more(method, opts, ctx), method=method.name, span=span, n=n, given=dict(opts))
    defaults = {"rtol": DEFAULT_RTOL, "norm_control": False, "atol": DEFAULT_ATOL, "refine": method.refine, "max_steps": 0,
                "args": ()}
    for name in _CHECK_ORDER:
        value = opts.get(name, defaults.get(name))
        if value is not None:
            _check(name, value, ctx)
    got = ctx.resolved
    if "max_step" not in got:
        got["max_step"] = 0.1 * span if method.matlab_defaults else math.inf
    extra = None
    if "jacobian" in method.options:  # the stiff solvers' own options (Jacobian, JPattern, MaxOrder...)
        from odelab.solvers.implicit import resolve_extras

        extra = resolve_extras(method, opts, n)
    more = _more(method, opts, ctx)
    return SolverOptions(
        extra=extra, more=more, events=got.get("events"), nonnegative=got.get("nonnegative"), mass=got.get("mass"),
        mstate_dependence=got.get("mstate_dependence"), output_fcn=got.get("output_fcn"),
        output_sel=got.get("output_sel"), args=got["args"], rtol=got["rtol"], atol=got["atol"],
        max_step=got["max_step"], initial_step=got.get("initial_step", math.nan), refine=got["refine"],
        norm_control=got["norm_control"], max_steps=got["max_steps"], warnings=tuple(ctx.notes), method=method.name,
        span=span, n=n, given=dict(opts),
    )
