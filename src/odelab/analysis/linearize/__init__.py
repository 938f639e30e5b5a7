"""Operating points, linearisation, and how good the linear model is.

The lab's third part: a nonlinear model x' = f(t, x, u), y = h(t, x, u) is replaced near an
operating point (x̄, ū) with f(x̄, ū) = 0 by its tangent model in incremental variables
x̂ = x - x̄, û = u - ū, ŷ = y - ȳ::

    x̂' = A x̂ + B û,   ŷ = C x̂ + D û,   A = ∂f/∂x, B = ∂f/∂u, C = ∂h/∂x, D = ∂h/∂u.

For the mass-spring-damper m x'' + b x' + f_K(x) = f this is exactly "find x̄ with
f_K(x̄) = f̄ and replace f_K by its tangent k(x̄) = f_K'(x̄)".

Functions
---------
:func:`operating_point`
    Solve f(x̄, ū) = 0 (optionally holding states fixed, or solving for inputs).
:func:`jacobians`
    A, B, C, D to near machine precision: complex-step differentiation when the model
    allows it, Ridders' extrapolated central differences otherwise.
:func:`linearize`
    The incremental :class:`~odelab.systems.statespace.StateSpace`, carrying its
    :class:`OperatingPoint`.
:func:`compare_linearization`, :func:`amplitude_study`
    Simulate both models and measure how far apart they are, and for how large an input
    the linear model stays within a threshold.
"""

from odelab.analysis.linearize.amplitude import AmplitudeStudy, amplitude_study
from odelab.analysis.linearize.comparison import (
    ErrorMeasure,
    LinearizationComparison,
    compare_linearization,
)
from odelab.analysis.linearize.jacobian import (
    COMPLEX_STEP as COMPLEX_STEP,  # public, not in __all__
)
from odelab.analysis.linearize.jacobian import jacobians
from odelab.analysis.linearize.model import linearize
from odelab.analysis.linearize.operating_point import (
    EQUILIBRIUM_TOL,
    NoEquilibriumError,
    NotAnEquilibriumWarning,
    OperatingPoint,
    operating_point,
)

__all__ = [
    "AmplitudeStudy",
    "ErrorMeasure",
    "LinearizationComparison",
    "NoEquilibriumError",
    "NotAnEquilibriumWarning",
    "OperatingPoint",
    "EQUILIBRIUM_TOL",
    "amplitude_study",
    "compare_linearization",
    "jacobians",
    "linearize",
    "operating_point",
]
