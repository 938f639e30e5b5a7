"""The registry of integration methods, by name."""

from __future__ import annotations

import difflib
from dataclasses import dataclass

from odelab.exceptions import InputError
from odelab.solvers import tableau as tb

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
        engine on a fixed step ``h``) or ``"scipy"`` (``scipy.integrate`` solver classes).
    order
        Order of accuracy of the propagated solution (for SciPy's multistep methods, the
        largest order they use).
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

    @property
    def options(self) -> tuple[str, ...]:
        """Option names the method accepts."""
        if self.kind == "adaptive":
            return ("rtol", "atol", "max_step", "initial_step", "refine", "norm_control", "max_steps",
                    "events", "nonnegative", "mass", "mstate_dependence", "output_fcn", "output_sel", "args")
        if self.kind == "fixed":
            return ("h", "args")
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
    )


def _fixed(name, tableau, description):
    return Method(name=name, kind="fixed", order=tableau.order, description=description, tableau=tableau)


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        _adaptive("ode23", tb.BS23, 0.5, 1, "MATLAB's ode23: Bogacki-Shampine 3(2), adaptive"),
        _adaptive("ode45", tb.DP54, 0.1, 4, "MATLAB's ode45: Dormand-Prince 5(4), adaptive"),
        _fixed("euler", tb.EULER, "Forward Euler, fixed step h"),
        _fixed("heun", tb.HEUN, "Heun's method (improved Euler), fixed step h"),
        _fixed("midpoint", tb.MIDPOINT, "Explicit midpoint, fixed step h"),
        _fixed("ralston", tb.RALSTON, "Ralston's second-order method, fixed step h"),
        _fixed("rk3", tb.KUTTA3, "Kutta's third-order method, fixed step h"),
        _fixed("rk4", tb.RK4, "Classical fourth-order Runge-Kutta, fixed step h"),
        Method("RK23", "scipy", 3, "SciPy solve_ivp RK23 (Bogacki-Shampine, SciPy's controller)"),
        Method("RK45", "scipy", 5, "SciPy solve_ivp RK45 (Dormand-Prince, SciPy's controller)"),
        Method("DOP853", "scipy", 8, "SciPy solve_ivp DOP853 (Dormand-Prince 8(5,3))"),
        Method("Radau", "scipy", 5, "SciPy solve_ivp Radau IIA, implicit, for stiff problems", stiff=True),
        Method("BDF", "scipy", 5, "SciPy solve_ivp BDF (orders 1-5), implicit, for stiff problems", stiff=True),
        Method("LSODA", "scipy", 12, "SciPy solve_ivp LSODA (Adams/BDF switching)", stiff=True),
    )
}

_BY_LOWER = {name.lower(): m for name, m in METHODS.items()}


def get_method(name: str, *, key: str = "method") -> Method:
    """Look a method up by name (case-insensitive), with a did-you-mean on failure."""
    if not isinstance(name, str):
        raise InputError(f"`{key}` must be a method name such as 'ode45'; got {name!r}.", key=key)
    method = _BY_LOWER.get(name.lower())
    if method is None:
        close = difflib.get_close_matches(name.lower(), list(_BY_LOWER), n=1)
        hint = f" Did you mean '{_BY_LOWER[close[0]].name}'?" if close else ""
        raise InputError(
            f"`{key}` is {name!r}, which is not a method odelab knows.{hint} "
            f"Known methods: {', '.join(METHODS)}.",
            key=key,
        )
    return method
