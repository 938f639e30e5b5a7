"""Input signals u(t), as Simulink's source blocks.

Every signal is a frozen dataclass and a vectorised callable: ``u(t)`` takes a float or an
array of times and returns a float or an array of the same shape. Signals combine with
``+``, ``-``, and ``*`` / ``/`` by numbers (:class:`Sum`, :class:`Scaled`, :class:`Constant`).

:class:`Terms` writes exponentials, polynomials and damped sines directly as terms of the
exact form below.

Two more methods serve the rest of odelab:

``breakpoints(t0, tf)``
    The times strictly between t0 and tf (either order), sorted increasingly, where the
    signal or its first derivative jumps. :func:`odelab.systems.simulate.simulate` restarts
    the solver at each one, so a step is not smeared over a long step of the integrator.
``exact_terms()``
    The signal written exactly as a piecewise sum of :class:`Term` objects,

        c * (t - tau)**k * exp(lam*(t - tau)) * cos(w*(t - tau))    (or sin),

    as an :class:`ExactForm`, or ``None`` when there is no such form (:class:`Function`,
    and sums or scalings of one). A :class:`Table` has one: linear interpolation is exactly
    piecewise linear.
    :func:`odelab.analysis.lti.lti_response` turns each piece into an exosystem and computes
    the response of a linear system exactly.

Convention at a jump: every signal here is *right-continuous*, u(T) is the value after the
jump (Simulink's Step block outputs the final value at the step time). Code that needs the
value before a jump at T evaluates just below T (``numpy.nextafter(T, -inf)``).

The package: :mod:`~odelab.signals.base` (Signal, its arithmetic, the exact form and the
registry), :mod:`~odelab.signals.sources` (step, ramp, sine, pulse, terms),
:mod:`~odelab.signals.tables` (lookup-table interpolation and the Table signal),
:mod:`~odelab.signals.expression` and :mod:`~odelab.signals.inputs` (a system's inputs).
"""

from odelab.signals.base import (
    MAX_PIECES,
    SIGNALS,
    Constant,
    ExactForm,
    Function,
    Piece,
    Scaled,
    Signal,
    SignalContext,
    SignalKey,
    Sum,
    Term,
    as_signal,
    plain_description,
    register_signal,
)
from odelab.signals.expression import Expression
from odelab.signals.inputs import MAX_RECORDED_JUMPS, as_signals, input_jumps
from odelab.signals.sources import Pulse, Ramp, Sine, Step, Terms
from odelab.signals.tables import (
    EXTRAPOLATIONS,
    INTERPOLATIONS,
    Table,
    interpolate_1d,
    interpolate_2d,
    spline_pieces,
)

__all__ = [
    "SIGNALS",
    "SignalContext",
    "SignalKey",
    "plain_description",
    "register_signal",
    "Signal",
    "Step",
    "Ramp",
    "Sine",
    "Pulse",
    "Table",
    "interpolate_1d",
    "interpolate_2d",
    "spline_pieces",
    "Function",
    "Sum",
    "Scaled",
    "Constant",
    "Expression",
    "Terms",
    "Term",
    "Piece",
    "ExactForm",
    "as_signal",
    "as_signals",
    "input_jumps",
    "MAX_PIECES",
    "MAX_RECORDED_JUMPS",
    "INTERPOLATIONS",
    "EXTRAPOLATIONS",
]

# the types of experiment files, in the order their messages list them
for _cls in (Step, Ramp, Sine, Pulse, Table, Expression, Constant):
    register_signal(_cls)
del _cls

