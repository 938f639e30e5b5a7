"""Why an integration stopped: one set of codes for every driver (Python and compiled).

The drivers return a :class:`Status`; the numba kernels return its integer value (an
``IntEnum`` compares equal to it) and :class:`~odelab.solution.Solution` carries it as
``reason``. A terminal event or an output function's stop ends a run early without failing.
"""

from __future__ import annotations

from enum import IntEnum

__all__ = ["Status"]


class Status(IntEnum):
    """Why a driver stopped (the values are those the compiled loops return)."""

    SUCCESS = 0  #: reached the end of tspan
    STEP_UNDERFLOW = 1  #: the step size fell to hmin and the error test still failed
    NONFINITE = 2  #: a derivative (or the solution) became NaN or infinite
    MAX_STEPS = 3  #: the max_steps guard stopped the integration
    FUN_RAISED = 4  #: the right-hand side (or an events or output function) raised
    TERMINAL_EVENT = 5  #: a terminal event stopped the integration (not a failure)
    OUTPUT_STOP = 6  #: the output function asked to stop (not a failure)

    @property
    def failed(self) -> bool:
        """Whether the run stopped short of ``tf`` for a reason the user must act on."""
        return self in _FAILURES

    @property
    def label(self) -> str:
        """``Solution.status``: ``"failed"`` or ``"success"``."""
        return "failed" if self in _FAILURES else "success"


_FAILURES = frozenset({Status.STEP_UNDERFLOW, Status.NONFINITE, Status.MAX_STEPS, Status.FUN_RAISED})
