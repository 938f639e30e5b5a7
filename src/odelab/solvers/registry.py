"""The registry of integration methods, by name, with what each can do.

A :class:`Method` declares its capabilities (events, dense output, complex ``y0``, a mass
matrix, DAEs, the compiled backend, the options it takes) and the driver that runs it; every
module that needs to know whether a method can do something asks the method, and every message
about what a method cannot do lists the methods that can from :data:`METHODS`
(:func:`methods_with`, :func:`listing`). A new method is one :func:`register_method` call.
"""

from __future__ import annotations

import difflib
import importlib
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from odelab import solution
from odelab.exceptions import InputError
from odelab.solvers import tableau as tb
from odelab.solvers.optionset import OPTIONS
from odelab.solvers import verner

__all__ = ["Method", "METHODS", "DRIVERS", "Driver", "get_method", "register_method", "methods_with", "listing",
           "join_names", "dense_output_text", "DEFAULT_METHOD", "DELAY_METHOD", "RESIDUAL_METHOD", "REFERENCE_METHOD",
           "SENSITIVITY_METHOD"]

@dataclass(frozen=True)
class Driver:
    """What runs the methods of one kind: ``run(fun, tspan, y0, method, options) -> Solution``.

    ``target`` is the driver function's ``module:function`` (imported when first run: the
    drivers import this registry, so it cannot import them); ``sentence`` says what it is."""

    target: str
    sentence: str

    @property
    def run(self) -> Callable:
        module, _, function = self.target.partition(":")
        return getattr(importlib.import_module(module), function)


# The drivers: what runs a method of each kind (odelab.solvers.api calls DRIVERS[method.kind].run, and only it).
DRIVERS = {
    "adaptive": Driver("odelab.solvers.api:drive_adaptive",
                       "odelab.solvers.engine.integrate_adaptive: an explicit Runge-Kutta pair, MATLAB's controller"),
    "fixed": Driver("odelab.solvers.api:drive_fixed",
                    "odelab.solvers.engine.integrate_fixed: an explicit Runge-Kutta method on a fixed step h"),
    "multistep": Driver("odelab.solvers.adams:drive_multistep",
                        "odelab.solvers.adams.integrate_ode113: Adams-Bashforth-Moulton PECE (Shampine & Gordon)"),
    "implicit": Driver("odelab.solvers.api:drive_implicit",
                       "odelab.solvers.implicit.solve_implicit: odelab's stiff solvers (one module each, its step "
                       "class registered by name)"),
    "residual": Driver("odelab.solvers.api:drive_residual",
                       "odelab.solvers.api.solve_residual: fully implicit F(t, y, y') = 0 from consistent y0 and "
                       "y'0 (odelab.solvers.implicit.ode15i)"),
    "delay": Driver("odelab.solvers.dde23:drive_delay", "odelab.solvers.dde23.solve_delay: delay equations with "
                    "constant lags"),
    "scipy": Driver("odelab.solvers.api:drive_scipy",
                    "odelab.solvers.scipy_adapter.solve_scipy: SciPy's solve_ivp solver classes, stepped"),
}

# The options of each family of methods (odelab's names; MATLAB's spellings in odelab.solvers.options).
EXPLICIT_OPTIONS = ("rtol", "atol", "max_step", "initial_step", "refine", "norm_control", "max_steps",
                    "events", "nonnegative", "mass", "mstate_dependence", "output_fcn", "output_sel", "args")
FIXED_OPTIONS = ("h", "args")
DELAY_OPTIONS = ("rtol", "atol", "max_step", "initial_step", "norm_control", "max_steps", "events", "args")
IMPLICIT_OPTIONS = ("rtol", "atol", "max_step", "initial_step", "refine", "max_steps", "events", "jacobian",
                    "jpattern", "vectorized", "mass", "args")
SCIPY_OPTIONS = ("rtol", "atol", "max_step", "initial_step", "max_steps", "args")
RESIDUAL_OPTIONS = ("rtol", "atol", "max_step", "initial_step", "refine", "max_steps", "events", "jacobian",
                    "max_order", "args")

MASS_KINDS = ("", "constant", "moving")  # none; a constant M; M, M(t) or M(t, y) (MStateDependence)


@dataclass(frozen=True)
class Method:
    """An integration method odelab can run, and what it can do.

    Attributes
    ----------
    name
        Registry name, as users type it (``"ode45"``, ``"rk4"``, ``"Radau"``).
    kind
        The driver that runs it, a key of :data:`DRIVERS`: ``"adaptive"`` (odelab's engine with
        MATLAB's controller), ``"fixed"`` (odelab's engine on a fixed step ``h``), ``"implicit"``
        (:mod:`odelab.solvers.implicit`), ``"multistep"`` (ode113, :mod:`odelab.solvers.adams`),
        ``"delay"`` (dde23), ``"residual"`` (a fully implicit ``F(t, y, y') = 0``: ode15i) or
        ``"scipy"`` (``scipy.integrate`` solver classes). Only the
        dispatch in :mod:`odelab.solvers.api` reads it; everything else asks a capability.
    order
        Order of accuracy of the propagated solution; for variable-order methods the
        highest order used (see ``orders``).
    description
        One line for ``odelab solvers``.
    tableau
        The Butcher tableau (odelab's own Runge-Kutta methods).
    power, shrink_min, refine
        MATLAB controller constants for adaptive methods: exponent 1/(q+1), smallest first
        reduction factor after a failure, default output points per step.
    stiff
        Whether the method is meant for stiff problems.
    options
        The solver options it takes (odelab's names, see :mod:`odelab.solvers.options`).
    events
        It locates [events] (MATLAB's ``Events``).
    dense
        What to say of its interpolant in a message (``""``: said with the next method's, or
        no interpolant); ``dense_output`` says whether ``deval`` works on its solutions.
    complex_y0
        It integrates a complex ``y0`` in complex arithmetic (as MATLAB's explicit solvers).
    mass
        The mass matrices of ``M y' = f`` it takes: ``""`` none, ``"constant"``, or
        ``"moving"`` (``M``, ``M(t)`` or ``M(t, y)``).
    dae
        It takes a singular mass matrix: an index-1 DAE.
    compiled, compiled_events
        The compiled (numba) backend runs it; and locates its [events].
    matlab_defaults
        MATLAB's odeset defaults apply (rtol 1e-3, atol 1e-6, ``MaxStep`` a tenth of the span,
        ``Refine``).
    delays
        It solves delay equations (and only those).
    residual
        It solves fully implicit systems ``F(t, y, y') = 0`` (and only those), from ``y0`` and
        ``y'0`` (MATLAB's ode15i).
    source
        Whose implementation it is: ``"odelab"`` or ``"SciPy"``.
    color, marker, dash
        How the report draws its lines (:func:`odelab.report.plots.method_style`): a colour, a
        matplotlib marker and line style; ``""``: a stable one chosen from its name.
    """

    name: str
    kind: str
    order: int
    description: str
    tableau: tb.ButcherTableau | None = None
    power: float = 0.0
    shrink_min: float = 0.0
    refine: int = 1
    stiff: bool = False
    orders: str = ""
    problem: str = "non-stiff"
    options: tuple[str, ...] = SCIPY_OPTIONS
    events: bool = False
    dense_output: bool = False
    dense: str = ""
    complex_y0: bool = False
    mass: str = ""
    dae: bool = False
    compiled: bool = False
    compiled_events: bool = False
    matlab_defaults: bool = False
    delays: bool = False
    residual: bool = False
    source: str = "odelab"
    color: str = ""
    marker: str = ""
    dash: str = ""

    def __post_init__(self):
        if self.kind not in DRIVERS:
            raise ValueError(f"Method {self.name!r}: kind {self.kind!r} is not a driver ({', '.join(DRIVERS)}).")
        if self.mass not in MASS_KINDS:
            raise ValueError(f"Method {self.name!r}: mass {self.mass!r} is not one of {MASS_KINDS}.")
        if self.dae and not self.mass:
            raise ValueError(f"Method {self.name!r} takes a DAE, so it takes a mass matrix: give `mass`.")
        if bool(self.mass) != ("mass" in self.options):
            raise ValueError(f"Method {self.name!r}: `mass` and the option `mass` disagree.")
        if self.events != ("events" in self.options):
            raise ValueError(f"Method {self.name!r}: `events` and the option `events` disagree.")
        if self.residual != (self.kind == "residual"):
            raise ValueError(f"Method {self.name!r}: `residual` and the driver kind {self.kind!r} disagree.")
        if self.compiled_events and not (self.compiled and self.events):
            raise ValueError(f"Method {self.name!r}: compiled events need `compiled` and `events`.")

    @property
    def adaptive(self) -> bool:
        """Whether it chooses its own steps (under tolerances) rather than taking a fixed ``h``."""
        return "h" not in self.options

    @property
    def kind_label(self) -> str:
        """What the method is for, as ``odelab solvers`` shows it: non-stiff, stiff or DAE."""
        return self.problem

    @property
    def defaults(self) -> str:
        """MATLAB's defaults for the method, one line (the defaults of :data:`odelab.solvers.optionset.OPTIONS`)."""
        if not self.adaptive:
            return "h required"
        text = f"rtol {OPTIONS['rtol'].default}, atol {OPTIONS['atol'].default}"  # the option registry's
        if self.delays:
            return text + ", max_step 0.1*span"
        if self.matlab_defaults:
            text += f", refine {self.refine}, max_step 0.1*span"
        if "max_order" in self.options:
            text += f", max_order {OPTIONS['max_order'].default}" + (", NDF (bdf off)" if "bdf" in self.options else "")
        if "jacobian" in self.options:
            text += ", Jacobian by finite differences"
        return text

    @property
    def order_label(self) -> str:
        """The order as a user reads it: ``"5(4)"`` for a pair, ``"1-5"`` for variable order."""
        if self.orders:
            return self.orders
        if self.tableau is not None and self.tableau.error_order:
            return f"{self.order}({self.tableau.error_order})"
        return str(self.order)

    @property
    def capabilities(self) -> tuple[str, ...]:
        """What it can do, in words (``odelab explain solver.method.<name>``, the docs)."""
        out = []
        if self.delays:
            out.append("delay equations")
        if self.residual:
            out.append("fully implicit F(t, y, y') = 0 (index-1 DAEs), consistent initial values by decic")
        if self.events:
            out.append("events")
        if self.dense_output:
            out.append("dense output (deval)")
        if self.complex_y0:
            out.append("complex y0")
        if self.mass == "moving":
            out.append("a mass M(t, y)")
        elif self.mass:
            out.append("a constant mass matrix" + (", singular too (index-1 DAEs)" if self.dae else ""))
        if self.compiled:
            out.append("the compiled backend" + (" (with events)" if self.compiled_events else ""))
        return tuple(out)


def _adaptive(name, tableau, shrink_min, refine, description, dense="", compiled=False, **look):
    return Method(
        name=name, kind="adaptive", order=tableau.order, description=description, tableau=tableau,
        power=1.0 / (tableau.error_order + 1), shrink_min=shrink_min, refine=refine, problem="non-stiff",
        options=EXPLICIT_OPTIONS, events=True, dense_output=True, dense=dense, complex_y0=True, mass="moving",
        compiled=compiled, compiled_events=compiled, matlab_defaults=True, **look,
    )


def _implicit(name, order, orders, problem, description, dae=False, dense_output=False, dense="", extra=(),
              nonnegative=True, compiled=False):
    own = IMPLICIT_OPTIONS + (("nonnegative",) if nonnegative else ()) + extra
    return Method(name=name, kind="implicit", order=order, orders=orders, description=description, stiff=True,
                  problem=problem, options=own, events=True, dense_output=dense_output,
                  dense=dense, mass="constant", dae=dae, compiled=compiled, matlab_defaults=True)


def _fixed(name, tableau, description, **look):
    return Method(name=name, kind="fixed", order=tableau.order, description=description, tableau=tableau,
                  problem="non-stiff (fixed h)", options=FIXED_OPTIONS, compiled=True, **look)


def _scipy(name, order, description, **kw):
    return Method(name, "scipy", order, description, options=SCIPY_OPTIONS, source="SciPy", **kw)


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        # ode23's interpolant is named with ode45's in messages (dense = "": said with the next)
        _adaptive("ode23", tb.BS23, 0.5, 1, "MATLAB's ode23: Bogacki-Shampine 3(2), adaptive", compiled=True,
                  color="#0072B2", marker="o", dash="-"),
        _adaptive("ode45", tb.DP54, 0.1, 4, "MATLAB's ode45: Dormand-Prince 5(4), adaptive",
                  dense="their ntrp23/ntrp45 interpolants", compiled=True, color="#D55E00", marker="s", dash="--"),
        _implicit("ode15s", 5, "1-5", "stiff, DAE",
                  "MATLAB's ode15s: variable-order NDF/BDF (orders 1-5), for stiff problems and index-1 DAEs",
                  dae=True, extra=("max_order", "bdf"), compiled=True),
        # odelab.solvers.implicit.ode15i: Shampine 2002, BDFs in Lagrangian form, F(t, y, y') = 0
        Method("ode15i", "residual", 5, "MATLAB's ode15i: variable-order BDF (orders 1-5) for fully implicit "
               "F(t, y, y') = 0 (ODEs and index-1 DAEs)", orders="1-5", stiff=True,
               problem="fully implicit, DAE", options=RESIDUAL_OPTIONS, events=True, dense_output=True,
               dense="its BDF polynomials", matlab_defaults=True, residual=True),
        _implicit("ode23s", 2, "2(3)", "stiff",
                  "MATLAB's ode23s: modified Rosenbrock (2,3) W-method, for stiff problems at crude tolerances",
                  nonnegative=False, compiled=True),  # MATLAB's ode23s has no NonNegative
        _implicit("ode23t", 2, "2", "stiff, DAE",
                  "MATLAB's ode23t: trapezoidal rule with its free interpolant, for moderately stiff problems "
                  "and index-1 DAEs", dae=True, dense_output=True, dense="their quadratics"),
        _implicit("ode23tb", 2, "2(3)", "stiff",
                  "MATLAB's ode23tb: TR-BDF2 (gamma = 2 - sqrt 2), for stiff problems at crude tolerances",
                  dense_output=True, dense="their quadratics"),
        # Orders 1-13 as MATLAB documents them: predictor order k <= 12, corrector k+1 (local
        # extrapolation). Shampine & Gordon's DE/STEP/INTRP in odelab.solvers.adams.
        Method("ode113", "multistep", 13, "MATLAB's ode113: variable-order Adams-Bashforth-Moulton PECE "
               "(Shampine & Gordon), for tight tolerances and expensive f", orders="1-13", refine=1,
               options=EXPLICIT_OPTIONS, events=True, dense_output=True, dense="Adams", complex_y0=True,
               mass="moving", matlab_defaults=True, color="#7570B3", marker="H"),
        _adaptive("ode78", verner.VERNER87, 0.1, 1,
                  "MATLAB's ode78: Verner's most efficient 8(7) pair, 8th-order interpolant, adaptive",
                  dense="Verner's"),
        _adaptive("ode89", verner.VERNER98, 0.1, 1,
                  "MATLAB's ode89: Verner's most robust 9(8) pair, 8th-order interpolant, adaptive",
                  dense="Verner's"),
        # odelab.solvers.dde23: delay equations with constant lags (Shampine & Thompson 2001)
        Method("dde23", "delay", 3, "MATLAB's dde23: delay equations y'(t) = f(t, y, y(t - tau)) with constant "
               "lags; Bogacki-Shampine 3(2), discontinuity tracking", orders="3(2)", problem="delay (constant lags)",
               options=DELAY_OPTIONS, events=True, dense_output=True, delays=True),
        _fixed("euler", tb.EULER, "Forward Euler, fixed step h", color="#CC79A7", marker="v", dash=":"),
        _fixed("heun", tb.HEUN, "Heun's method (improved Euler), fixed step h", color="#E69F00", marker="D"),
        _fixed("midpoint", tb.MIDPOINT, "Explicit midpoint, fixed step h", color="#56B4E9", marker="P"),
        _fixed("ralston", tb.RALSTON, "Ralston's second-order method, fixed step h", color="#8C6D31", marker="X"),
        _fixed("rk3", tb.KUTTA3, "Kutta's third-order method, fixed step h", color="#7F7F7F", marker="<"),
        _fixed("rk4", tb.RK4, "Classical fourth-order Runge-Kutta, fixed step h", color="#009E73", marker="^",
               dash="-."),
        _scipy("RK23", 3, "SciPy solve_ivp RK23 (Bogacki-Shampine, SciPy's controller)", color="#2B4C7E", marker="h"),
        _scipy("RK45", 5, "SciPy solve_ivp RK45 (Dormand-Prince, SciPy's controller)", color="#8E2C0E", marker="d"),
        _scipy("DOP853", 8, "SciPy solve_ivp DOP853 (Dormand-Prince 8(5,3))", color="#3E7D5E", marker="*"),
        _scipy("Radau", 5, "SciPy solve_ivp Radau IIA, implicit, for stiff problems", stiff=True, problem="stiff",
               color="#6A3D9A", marker=">"),
        _scipy("BDF", 5, "SciPy solve_ivp BDF (orders 1-5), implicit, for stiff problems", stiff=True,
               orders="1-5", problem="stiff", color="#B15928", marker="p"),
        # LSODA: Adams orders 1-12 while non-stiff, BDF orders 1-5 once stiff (Petzold 1983).
        _scipy("LSODA", 12, "SciPy solve_ivp LSODA (Adams/BDF switching)", stiff=True,
               orders="Adams 1-12 / BDF 1-5", problem="both (switches)", color="#1B9E77", marker="8"),
    )
}


# The methods odelab runs when none is named, each written here once and imported where it is the default.
DEFAULT_METHOD = "ode45"  # MATLAB's first choice: experiment files, simulate, linearize, diagrams, the compiled path
DELAY_METHOD = "dde23"  # delay equations: lag(...) in the equations, a diagram's transport delay
RESIDUAL_METHOD = "ode15i"  # fully implicit systems F(t, y, y') = 0
REFERENCE_METHOD = "DOP853"  # the high-accuracy reference (SciPy's 8th-order pair, at rtol 1e-12)
SENSITIVITY_METHOD = "ode78"  # [fit]: the states and their sensitivities, at the fit's tight tolerances

# each is a method of the kind it is the default for (analysis.reference steps SciPy's classes; a fit, explicit ones)
for _name, _fits in ((DEFAULT_METHOD, lambda m: m.adaptive and not m.stiff), (DELAY_METHOD, lambda m: m.delays),
                     (RESIDUAL_METHOD, lambda m: m.residual), (REFERENCE_METHOD, lambda m: m.source == "SciPy"),
                     (SENSITIVITY_METHOD, lambda m: m.adaptive and not m.stiff and not m.delays)):
    if not _fits(METHODS[_name]):
        raise ValueError(f"{_name!r} is not a method of the kind it is the default for.")


def register_method(method: Method) -> Method:
    """Add ``method`` to :data:`METHODS` (the loader, messages, ``odelab solvers``/``explain`` read it)."""
    if not isinstance(method, Method):
        raise TypeError(f"register_method takes a Method; got {method!r}.")
    clash = next((n for n in METHODS if n.lower() == method.name.lower() and n != method.name), None)
    if clash:
        raise ValueError(f"method {method.name!r} would shadow {clash!r} (names are matched without case).")
    METHODS[method.name] = method
    return method


def _suite_number(name: str) -> float:
    digits = re.match(r"ode(\d+)", name)
    return float(digits.group(1)) if digits else float("inf")


def listing(methods: Iterable[Method]) -> list[Method]:
    """``methods`` in the order messages list them: MATLAB's suite by number (non-stiff, then stiff), the rest
    in registry order."""
    order = {name: i for i, name in enumerate(METHODS)}
    return sorted(methods, key=lambda m: (m.delays, m.stiff, not m.adaptive, _suite_number(m.name),
                                          order.get(m.name, len(order))))


def methods_with(test: Callable[[Method], bool], *, delays: bool | None = False,
                 residual: bool | None = False) -> list[str]:
    """Names of the registered methods that pass ``test``, in :func:`listing` order; ``delays``: only the
    methods for delay equations (True), only those for ODEs (False, the default), or both (None);
    ``residual`` likewise for the methods of fully implicit systems F(t, y, y') = 0."""
    return [m.name for m in listing(METHODS.values())
            if test(m) and (delays is None or m.delays == delays) and (residual is None or m.residual == residual)]


def join_names(names: Iterable[str], last: str = "and") -> str:
    """``"a, b and c"``."""
    names = list(names)
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} {last} {names[-1]}"


def dense_output_text() -> str:
    """The methods with dense output, each family with its interpolant: the ``deval`` message's list."""
    parts: list[str] = []
    run: list[str] = []
    label = ""
    for m in listing(m for m in METHODS.values() if m.dense_output and not m.delays and not m.residual):
        if run and m.dense != label:
            parts.append(f"{' or '.join(run)}" + (f" ({label})" if label else ""))
            run = []
        run.append(m.name)
        label = m.dense
    if run:
        parts.append(f"{' or '.join(run)}" + (f" ({label})" if label else ""))
    return ", ".join(parts)


# What users type when they mean a suite member: MATLAB names without their letter, other
# tools' names for the same methods. Checked before the spelling-based suggestion.
_MEANT = {
    "ode15": "ode15s", "ode113s": "ode113",
    "ode11": "ode113", "ode13": "ode113", "ode8": "ode89", "ode87": "ode78", "ode98": "ode89",
    "ode23ts": "ode23t", "ode23st": "ode23s", "ode45s": "ode15s", "stiff": "ode15s", "gear": "ode15s",
    "ndf": "ode15s", "rosenbrock": "ode23s", "trbdf2": "ode23tb", "tr-bdf2": "ode23tb", "adams": "ode113",
    "trapezoidal": "ode23t", "verner": "ode78", "rk45": "RK45", "dopri5": "ode45", "dopri853": "DOP853",
}


def get_method(name: str, *, key: str = "method") -> Method:
    """Look a method up by name (case-insensitive), with a did-you-mean on failure."""
    if not isinstance(name, str):
        raise InputError(f"`{key}` must be a method name such as 'ode45'; got {name!r}.", key=key)
    by_lower = {n.lower(): m for n, m in METHODS.items()}
    method = by_lower.get(name.lower())
    if method is None:
        meant = _MEANT.get(name.lower().strip())
        if meant is None:
            close = difflib.get_close_matches(name.lower(), list(by_lower), n=1)
            meant = by_lower[close[0]].name if close else None
        hint = f" Did you mean '{meant}'?" if meant else ""
        raise InputError(
            f"`{key}` is {name!r}, which is not a method odelab knows.{hint} "
            f"Known methods: {', '.join(METHODS)}.",
            key=key,
        )
    return method



def _install_dense_methods() -> None:
    """deval's message lists the methods with dense output (odelab.solution.DENSE_METHODS)."""
    solution.DENSE_METHODS = dense_output_text


_install_dense_methods()
