"""The result type every solver returns."""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Callable
from typing import Any

import numpy as np

from odelab.exceptions import InputError

__all__ = ["Solution", "Stats", "deval"]


@dataclass(frozen=True)
class Stats:
    """Step statistics, counted the way MATLAB's ``odeget(sol, 'stats')`` counts them.

    Attributes
    ----------
    nsteps
        Successful (accepted) steps.
    nfailed
        Failed attempts (rejected trial steps). ``None`` where the method does not let us
        count them (SciPy's implicit methods keep them internal).
    nfevals
        Calls of the right-hand side.
    npds, ndecomps, nsolves
        For odelab's stiff solvers (ode15s, ode23s...): partial derivatives (Jacobians)
        formed, LU decompositions and linear solves, as MATLAB's ``Stats`` prints them;
        ``None`` for explicit methods.
    """

    nsteps: int
    nfailed: int | None
    nfevals: int
    npds: int | None = None
    ndecomps: int | None = None
    nsolves: int | None = None

    def as_dict(self) -> dict:
        out = {"nsteps": self.nsteps, "nfailed": self.nfailed, "nfevals": self.nfevals}
        if self.npds is not None:
            out.update(npds=self.npds, ndecomps=self.ndecomps, nsolves=self.nsolves)
        return out

    def matlab(self) -> str:
        """The statistics as MATLAB's ``odeset('Stats', 'on')`` prints them."""
        lines = [f"{self.nsteps} successful steps", f"{self.nfailed if self.nfailed is not None else '?'} failed attempts",
                 f"{self.nfevals} function evaluations"]
        if self.npds is not None:
            lines += [f"{self.npds} partial derivatives", f"{self.ndecomps} LU decompositions",
                      f"{self.nsolves} solutions of linear systems"]
        return "\n".join(lines)

    def __repr__(self) -> str:
        extra = (f", npds={self.npds}, ndecomps={self.ndecomps}, nsolves={self.nsolves}"
                 if self.npds is not None else "")
        return f"Stats(nsteps={self.nsteps}, nfailed={self.nfailed}, nfevals={self.nfevals}{extra})"


@dataclass(frozen=True)
class Solution:
    """The solution of an initial value problem, as MATLAB's ``[t, y] = ode45(...)``.

    Attributes
    ----------
    t
        Output times, shape (N,).
    y
        States at the output times, shape (N, n): row i is the state at ``t[i]``.
    stats
        Step statistics.
    status
        ``"success"``, or ``"failed"`` when integration stopped early; ``t`` and ``y`` then
        hold the solution up to where it stopped.
    message
        Why it stopped, where and what to do about it.
    reason
        Why it stopped, as a code (:class:`odelab.solvers.status.Status`: ``SUCCESS``,
        ``TERMINAL_EVENT``, ``STEP_UNDERFLOW``...); None for SciPy's methods.
    method
        The method's registry name (``"ode45"``, ``"rk4"``, ``"Radau"``...).
    warnings
        Notes about the options (e.g. a RelTol raised to MATLAB's minimum).
    te, ye, ie
        Located events (MATLAB's ``[t, y, te, ye, ie] = ode45(...)``): times (k,), states
        (k, n) and 0-based indices (k,) into the events function's values, in the order found.
    interpolant
        The solution's dense output (:class:`odelab.solvers.dense.DenseOutput`), used by
        :meth:`deval`; None for methods without one.
    setup
        What :func:`odelab.odextend` needs to continue the solution (function and options).
    """

    t: np.ndarray
    y: np.ndarray
    stats: Stats
    status: str = "success"
    message: str = "The solver reached the end of the time span."
    method: str = ""
    warnings: tuple[str, ...] = field(default_factory=tuple)
    te: np.ndarray = field(default_factory=lambda: np.empty(0))
    ye: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    ie: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=int))
    interpolant: Any = field(default=None, repr=False)
    setup: Any = field(default=None, repr=False)
    reason: Any = None

    def deval(self, t, derivative: bool = False):
        """The solution at ``t`` (a time or a sequence) from the method's interpolant (MATLAB's ``deval``).

        Returns shape (n,) for one time, (k, n) for k times; with ``derivative=True`` the pair
        ``(y, yp)``, MATLAB's ``[y, yp] = deval(sol, t)``. See :func:`odelab.deval`.
        """
        return deval(self, t, derivative=derivative)

    def __call__(self, t) -> np.ndarray:
        """``sol(t)`` is ``sol.deval(t)``."""
        return self.deval(t)

    @property
    def success(self) -> bool:
        return self.status == "success"

    def __iter__(self):
        """Unpack as MATLAB does: ``t, y = odelab.ode45(...)``."""
        yield self.t
        yield self.y

    def __repr__(self) -> str:
        return (
            f"Solution(method={self.method!r}, status={self.status!r}, points={self.t.size}, "
            f"states={self.y.shape[1] if self.y.ndim == 2 else 0}, nsteps={self.stats.nsteps}, "
            f"nfailed={self.stats.nfailed}, nfevals={self.stats.nfevals})"
        )


#: The methods that have dense output, for deval's message: the solver registry installs its own
#: list here when it is imported (a solution is only ever made by a solver, so it always is by then);
#: the registry imports this module, never the other way round.
DENSE_METHODS: Callable[[], str] = lambda: "a method with dense output"


def deval(sol, t, derivative: bool = False):
    """Evaluate a solution anywhere in its span with the method's own interpolant (MATLAB's ``deval``).

    Parameters
    ----------
    sol : Solution
        A solution of a method with dense output (ode23, ode45, ode78, ode89, ode113, ode23t,
        ode23tb, or anything :func:`odelab.solve` ran with them).
    t : float or sequence of float
        Times inside ``[sol.t[0], sol.t[-1]]``.
    derivative : bool
        Also return the slope of the interpolant there (MATLAB's ``[y, yp] = deval(sol, t)``,
        "Slope of Interpolating Function").

    Returns
    -------
    numpy.ndarray or (numpy.ndarray, numpy.ndarray)
        Shape (n,) for a scalar ``t``, (k, n) for k times (rows are states, as in ``sol.y``;
        MATLAB's ``deval`` returns the transpose). With ``derivative=True`` the pair
        ``(y, yp)``, both of that shape: ``yp`` is d/dt of the interpolant, which equals
        ``f(t, y)`` at the ends of the steps of ode23/ode45 and approximates it in between.

    Examples
    --------
    >>> import numpy as np, odelab
    >>> sol = odelab.ode45(lambda t, y: -y, [0, 1], 1.0)
    >>> bool(abs(odelab.deval(sol, 0.5)[0] - np.exp(-0.5)) < 1e-4)
    True
    """
    interpolant = getattr(sol, "interpolant", None)  # any result with an interpolant (duck-typed)
    if interpolant is None:
        method = getattr(sol, "method", "") or "this method"
        raise InputError(
            f"this solution has no dense output: {method} does not provide one. Solve with {DENSE_METHODS()}, "
            "or with a vector tspan of the times you need.",
            key="sol",
        )
    if derivative:
        return interpolant(t, derivative=True)
    return interpolant(t)
