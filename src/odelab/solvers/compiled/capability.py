"""Whether the compiled backend can run a case, and the reason when it cannot.

Checked where a case is built (``[solver] backend = "compiled"`` refused with the reason) and
where the engine is chosen (:mod:`odelab.run.backend`); the reasons come from the methods'
capabilities (:func:`odelab.solvers.compiled.methods.method_refusal`), the system's and the
options'.
"""

from __future__ import annotations

from odelab.exceptions import ExperimentError
from odelab.solvers.compiled import PYTHON_ONLY_OPTIONS, method_refusal, unavailable

__all__ = ["check_backend", "why_not_compiled"]


def why_not_compiled(method, compiled, options=None) -> str | None:
    """Why the compiled backend cannot run this method, system and options (None if it can)."""
    reason = method_refusal(method)
    if reason:
        return reason
    if compiled is None:
        return ("it compiles systems written as expressions (equations, a state-space model, a diagram of linear "
                "blocks); this system is a Python function or a diagram with nonlinear blocks")
    if method.stiff:
        from odelab.solvers.compiled.stiff import why_not_stiff

        reason = why_not_stiff(method.name, compiled, options)
        if reason:
            return reason
    python_only = [name for name in PYTHON_ONLY_OPTIONS if (options or {}).get(name) is not None]
    if python_only:
        return f"`{python_only[0]}` calls back into Python"
    reason = compiled.why_not()
    if reason:
        return reason
    reason = unavailable()
    if reason:
        return reason
    return None


def check_backend(backend: str, method, compiled, key: str, options=None, events=None) -> None:
    """Refuse ``backend = "compiled"`` where it cannot run, naming the key and the fix."""
    if backend != "compiled":
        return
    reason = why_not_compiled(method, compiled, options)
    if reason is None and events is not None and not compiled.events:
        reason = "the compiled loop locates [events] of expression systems only"
    if reason:
        raise ExperimentError(f"`{key}` is \"compiled\", but the compiled backend cannot run this case: {reason}. "
                              "Use backend = \"auto\" (or \"python\").", key=key)
