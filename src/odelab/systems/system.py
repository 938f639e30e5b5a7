"""One built case's system: what it computes, as one typed object every consumer reads.

Each kind of system (equations, state space, network, diagram, delays, implicit, FMU) is built
by its own builder (:mod:`odelab.experiment.kinds`, :mod:`odelab.experiment.build`); what the
builders make is handed on as one :class:`System`: the right-hand side with its inputs applied,
the outputs, the exact Jacobian, the input signals, the events, the closed form where one
exists, the model it was built from and its source for the compiled backend. The solvers, the
linearisation, the fitting, the compiled backend, the reference and estimate solves and the
report read a case's system from ``problem.system`` and nowhere else.

It pickles field by field: the functions are the typed objects of :mod:`odelab.systems.fields`,
:mod:`odelab.systems.outputs` and :mod:`odelab.systems.jacobian`, whose compiled expressions
travel as their texts (:class:`odelab.expressions.compile.Portable`), so a built case goes to a
Dask worker as it is (:func:`odelab.run.executors.travels` names the two that cannot: an FMU's
and a user's Python function's).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:  # the types only
    import numpy as np

    from odelab.experiment.events import EventSet
    from odelab.fmi.simulate import FmuRun
    from odelab.solvers.compiled import CompiledSystem
    from odelab.systems.diagram.compile import CompiledDiagram
    from odelab.systems.network import Network
    from odelab.systems.nonlinear import NonlinearSystem
    from odelab.systems.statespace import StateSpace

__all__ = ["System"]

# A plain class with __slots__, not a dataclass (as odelab.systems.fields explains: a dataclass costs
# its module ~3 M instructions at import, and this one is imported by every run).
_FIELDS = ("states", "inputs", "outputs", "fun", "output_fn", "input_fn", "jacobian", "signals", "events",
           "exact_fn", "linear", "model", "compiled", "diagram", "network", "fmu")


class System:
    """A built case's system (read-only once built; :meth:`replace` makes a changed copy).

    Attributes
    ----------
    states, inputs, outputs
        The names, in order.
    fun
        ``fun(t, x) -> dx/dt`` with the inputs applied (``None`` for an FMU, which steps itself;
        for an implicit system the residual ``F(t, y, y')``).
    output_fn
        ``(t (N,), x (N, n)) -> (N, ny)``, or ``None`` without outputs.
    input_fn
        ``t (N,) -> (N, nu)``, or ``None`` without inputs.
    jacobian
        The exact ``df/dx``: ``J(t, x)`` or a constant matrix, for the stiff solvers; ``None`` where
        the system does not give one.
    signals
        One :mod:`odelab.signals` signal per input.
    events
        The compiled [events], or ``None``.
    exact_fn
        ``t (N,) -> {name: (N,)}`` for the states and outputs, where a closed form exists.
    linear
        Whether the system is linear (an LTI reference is possible).
    model
        The :class:`~odelab.systems.statespace.StateSpace` or
        :class:`~odelab.systems.nonlinear.NonlinearSystem` built, if one was.
    compiled
        The compiled backend's description (its source texts), where the system allows one.
    diagram, network, fmu
        A diagram's compiled blocks, a network's derivation, an FMU's run, by kind.
    """

    __slots__ = _FIELDS

    def __init__(self, *, states: tuple[str, ...], inputs: tuple[str, ...] = (), outputs: tuple[str, ...] = (),
                 fun: Callable | None = None, output_fn: Callable | None = None, input_fn: Callable | None = None,
                 jacobian: Callable | np.ndarray | None = None, signals: tuple = (), events: EventSet | None = None,
                 exact_fn: Callable | None = None, linear: bool = False,
                 model: StateSpace | NonlinearSystem | None = None, compiled: CompiledSystem | None = None,
                 diagram: CompiledDiagram | None = None, network: Network | None = None,
                 fmu: FmuRun | None = None) -> None:
        values = locals()
        for name in _FIELDS:
            object.__setattr__(self, name, values[name])

    def __setattr__(self, name, value):
        raise AttributeError(f"a System is read-only once built: use system.replace({name}=...)")

    def __delattr__(self, name):
        raise AttributeError("a System is read-only once built")

    def replace(self, **changes) -> System:
        """A copy with ``changes`` (field names as in the constructor)."""
        unknown = set(changes) - set(_FIELDS)
        if unknown:
            raise TypeError(f"System has no field {sorted(unknown)[0]!r}")
        return System(**{name: changes.get(name, getattr(self, name)) for name in _FIELDS})

    def __getstate__(self):
        return tuple(getattr(self, name) for name in _FIELDS)

    def __setstate__(self, state):
        for name, value in zip(_FIELDS, state):
            object.__setattr__(self, name, value)

    def __repr__(self) -> str:
        kind = next((k for k in ("fmu", "diagram", "network") if getattr(self, k) is not None), None) or (
            type(self.model).__name__ if self.model is not None else "equations")
        return (f"System({kind}: states {list(self.states)}, inputs {list(self.inputs)}, "
                f"outputs {list(self.outputs)})")
