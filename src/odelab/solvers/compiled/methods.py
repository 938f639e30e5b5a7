"""Which methods the compiled backend runs, read from the registry's capabilities.

``Method.compiled`` says whether it runs a method; :func:`method_refusal` says why not in words
that list the methods it does run (from :data:`odelab.solvers.registry.METHODS`), for the
backend's messages (:mod:`odelab.solvers.compiled`, :mod:`odelab.run.backend`).
"""

from __future__ import annotations

from odelab.solvers.registry import METHODS, methods_with

__all__ = ["STIFF_METHODS", "method_refusal"]

#: The stiff solvers the compiled backend runs (``Method.compiled``), lowest order first.
STIFF_METHODS = tuple(sorted(methods_with(lambda m: m.compiled and m.stiff), key=lambda name: METHODS[name].order))


def method_refusal(m) -> str | None:
    """Why the compiled backend does not run the method ``m`` (None if it does), read from the
    registry's capabilities (``Method.compiled``, ``delays``, ``stiff``, ``source``, its tableau):
    the methods it does run are listed from :data:`odelab.solvers.registry.METHODS`."""
    if m.compiled:
        return None
    if m.delays:
        return f"it solves ordinary differential equations, and {m.name} (delay equations) runs on the Python path"
    if m.stiff and m.source == "odelab":
        return f"the compiled stiff solvers are {', '.join(STIFF_METHODS)}: {m.name} runs on the Python path"
    if m.tableau is not None and not m.tableau.fsal:
        return (f"its kernels run FSAL pairs and fixed-step methods, and {m.name} is Verner's non-FSAL pair, which "
                "runs on the Python path")
    explicit = methods_with(lambda k: k.compiled and not k.stiff and k.adaptive)
    fixed = ", fixed-step" if methods_with(lambda k: k.compiled and not k.adaptive) else ""
    whose = "SciPy's" if m.source == "SciPy" else "not one of them"
    return f"it runs odelab's explicit Runge-Kutta methods ({', '.join(explicit)}{fixed}), and {m.name} is {whose}"
