"""The registry of integration methods, by name."""

from __future__ import annotations

import difflib
from dataclasses import dataclass

from odelab.exceptions import InputError
from odelab.solvers import tableau as tb
from odelab.solvers import verner

__all__ = ["Method", "METHODS", "get_method"]


@dataclass(frozen=True)
class Method:
    """An integration method odelab can run.

    Attributes
    ----------
    name
        Registry name, as users type it (``"ode45"``, ``"rk4"``, ``"Radau"``).
    kind
        ``"adaptive"`` (odelab's engine with MATLAB's controller), ``"fixed"`` (odelab's
        engine on a fixed step ``h``), ``"implicit"`` (odelab's stiff solvers in
        :mod:`odelab.solvers.implicit`), ``"multistep"`` (ode113, :mod:`odelab.solvers.adams`)
        or ``"scipy"`` (``scipy.integrate`` solver classes).
    order
        Order of accuracy of the propagated solution; for variable-order methods the
        highest order used (see ``orders``).
    description
        One line for ``odelab solvers``.
    tableau
        The Butcher tableau (odelab's own methods).
    power, shrink_min, refine
        MATLAB controller constants for adaptive methods: exponent 1/(q+1), smallest first
        reduction factor after a failure, default output points per step.
    stiff
        Whether the method is meant for stiff problems.
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

    @property
    def kind_label(self) -> str:
        """What the method is for, as ``odelab solvers`` shows it: non-stiff, stiff or DAE."""
        return self.problem

    @property
    def defaults(self) -> str:
        """MATLAB's defaults for the method, one line."""
        if self.kind == "fixed":
            return "h required"
        if self.kind == "delay":
            return "rtol 1e-3, atol 1e-6, max_step 0.1*span"
        text = "rtol 1e-3, atol 1e-6"
        if self.kind in ("adaptive", "implicit", "multistep"):
            text += f", refine {self.refine}, max_step 0.1*span"
        if self.name == "ode15s":
            text += ", max_order 5, NDF (bdf off)"
        if self.kind == "implicit":
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
    def options(self) -> tuple[str, ...]:
        """Option names the method accepts."""
        if self.kind in ("adaptive", "multistep"):
            return ("rtol", "atol", "max_step", "initial_step", "refine", "norm_control", "max_steps",
                    "events", "nonnegative", "mass", "mstate_dependence", "output_fcn", "output_sel", "args")
        if self.kind == "fixed":
            return ("h", "args")
        if self.kind == "delay":
            return ("rtol", "atol", "max_step", "initial_step", "norm_control", "max_steps", "events", "args")
        if self.kind == "implicit":
            common = ("rtol", "atol", "max_step", "initial_step", "refine", "max_steps", "events", "jacobian",
                      "jpattern", "vectorized", "mass", "args")
            common += () if self.name == "ode23s" else ("nonnegative",)  # MATLAB's ode23s has no NonNegative
            return common + (("max_order", "bdf") if self.name == "ode15s" else ())
        return ("rtol", "atol", "max_step", "initial_step", "max_steps", "args")


def _adaptive(name, tableau, shrink_min, refine, description):
    return Method(
        name=name,
        kind="adaptive",
        order=tableau.order,
        description=description,
        tableau=tableau,
        power=1.0 / (tableau.error_order + 1),
        shrink_min=shrink_min,
        refine=refine,
        problem="non-stiff",
    )


def _implicit(name, order, orders, problem, description):
    return Method(name=name, kind="implicit", order=order, orders=orders, description=description, stiff=True,
                  problem=problem)


def _fixed(name, tableau, description):
    return Method(name=name, kind="fixed", order=tableau.order, description=description, tableau=tableau,
                  problem="non-stiff (fixed h)")


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        _adaptive("ode23", tb.BS23, 0.5, 1, "MATLAB's ode23: Bogacki-Shampine 3(2), adaptive"),
        _adaptive("ode45", tb.DP54, 0.1, 4, "MATLAB's ode45: Dormand-Prince 5(4), adaptive"),
        _implicit("ode15s", 5, "1-5", "stiff, DAE",
                  "MATLAB's ode15s: variable-order NDF/BDF (orders 1-5), for stiff problems and index-1 DAEs"),
        _implicit("ode23s", 2, "2(3)", "stiff",
                  "MATLAB's ode23s: modified Rosenbrock (2,3) W-method, for stiff problems at crude tolerances"),
        _implicit("ode23t", 2, "2", "stiff, DAE",
                  "MATLAB's ode23t: trapezoidal rule with its free interpolant, for moderately stiff problems "
                  "and index-1 DAEs"),
        _implicit("ode23tb", 2, "2(3)", "stiff",
                  "MATLAB's ode23tb: TR-BDF2 (gamma = 2 - sqrt 2), for stiff problems at crude tolerances"),
        # Orders 1-13 as MATLAB documents them: predictor order k <= 12, corrector k+1 (local
        # extrapolation). Shampine & Gordon's DE/STEP/INTRP in odelab.solvers.adams.
        Method("ode113", "multistep", 13, "MATLAB's ode113: variable-order Adams-Bashforth-Moulton PECE "
               "(Shampine & Gordon), for tight tolerances and expensive f", orders="1-13", refine=1),
        _adaptive("ode78", verner.VERNER87, 0.1, 1,
                  "MATLAB's ode78: Verner's most efficient 8(7) pair, 8th-order interpolant, adaptive"),
        _adaptive("ode89", verner.VERNER98, 0.1, 1,
                  "MATLAB's ode89: Verner's most robust 9(8) pair, 8th-order interpolant, adaptive"),
        # odelab.solvers.dde23: delay equations with constant lags (Shampine & Thompson 2001)
        Method("dde23", "delay", 3, "MATLAB's dde23: delay equations y'(t) = f(t, y, y(t - tau)) with constant "
               "lags; Bogacki-Shampine 3(2), discontinuity tracking", orders="3(2)", problem="delay (constant lags)"),
        _fixed("euler", tb.EULER, "Forward Euler, fixed step h"),
        _fixed("heun", tb.HEUN, "Heun's method (improved Euler), fixed step h"),
        _fixed("midpoint", tb.MIDPOINT, "Explicit midpoint, fixed step h"),
        _fixed("ralston", tb.RALSTON, "Ralston's second-order method, fixed step h"),
        _fixed("rk3", tb.KUTTA3, "Kutta's third-order method, fixed step h"),
        _fixed("rk4", tb.RK4, "Classical fourth-order Runge-Kutta, fixed step h"),
        Method("RK23", "scipy", 3, "SciPy solve_ivp RK23 (Bogacki-Shampine, SciPy's controller)"),
        Method("RK45", "scipy", 5, "SciPy solve_ivp RK45 (Dormand-Prince, SciPy's controller)"),
        Method("DOP853", "scipy", 8, "SciPy solve_ivp DOP853 (Dormand-Prince 8(5,3))"),
        Method("Radau", "scipy", 5, "SciPy solve_ivp Radau IIA, implicit, for stiff problems", stiff=True,
               problem="stiff"),
        Method("BDF", "scipy", 5, "SciPy solve_ivp BDF (orders 1-5), implicit, for stiff problems", stiff=True,
               orders="1-5", problem="stiff"),
        # LSODA: Adams orders 1-12 while non-stiff, BDF orders 1-5 once stiff (Petzold 1983).
        Method("LSODA", "scipy", 12, "SciPy solve_ivp LSODA (Adams/BDF switching)", stiff=True,
               orders="Adams 1-12 / BDF 1-5", problem="both (switches)"),
    )
}

_BY_LOWER = {name.lower(): m for name, m in METHODS.items()}

# What users type when they mean a suite member: MATLAB names without their letter, other
# tools' names for the same methods. Checked before the spelling-based suggestion.
_MEANT = {
    "ode15": "ode15s", "ode15i": "ode15s", "ode113s": "ode113",
    "ode11": "ode113", "ode13": "ode113", "ode8": "ode89", "ode87": "ode78", "ode98": "ode89",
    "ode23ts": "ode23t", "ode23st": "ode23s", "ode45s": "ode15s", "stiff": "ode15s", "gear": "ode15s",
    "ndf": "ode15s", "rosenbrock": "ode23s", "trbdf2": "ode23tb", "tr-bdf2": "ode23tb", "adams": "ode113",
    "trapezoidal": "ode23t", "verner": "ode78", "rk45": "RK45", "dopri5": "ode45", "dopri853": "DOP853",
}


def get_method(name: str, *, key: str = "method") -> Method:
    """Look a method up by name (case-insensitive), with a did-you-mean on failure."""
    if not isinstance(name, str):
        raise InputError(f"`{key}` must be a method name such as 'ode45'; got {name!r}.", key=key)
    method = _BY_LOWER.get(name.lower())
    if method is None:
        meant = _MEANT.get(name.lower().strip())
        if meant is None:
            close = difflib.get_close_matches(name.lower(), list(_BY_LOWER), n=1)
            meant = _BY_LOWER[close[0]].name if close else None
        hint = f" Did you mean '{meant}'?" if meant else ""
        raise InputError(
            f"`{key}` is {name!r}, which is not a method odelab knows.{hint} "
            f"Known methods: {', '.join(METHODS)}.",
            key=key,
        )
    return method
