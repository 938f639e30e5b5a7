"""Fitting an FMU's parameters: the model's values at the measured times and their Jacobian by
central differences.

An FMU's binary cannot be differentiated as odelab differentiates its own equations (forward
sensitivities of the expression trees), so [fit] on ``kind = "fmu"`` runs the FMU once at the
trial parameters and twice more per parameter, at ``p_i (1 +- h)``. The step balances the
difference formula's truncation error, O(h^2), against the solver's error divided by h: with
the fit's tolerance ``rtol`` (default 1e-10) the step is ``h = rtol**(1/3)`` relative
(4.6e-4; at least 1e-8 absolute for a parameter at 0), which leaves the Jacobian about
``rtol**(2/3)`` = 2e-7 relative: the estimates are unchanged by it (the Jacobian steers the
iterations and scales the uncertainties; the residuals, which the estimates solve, are exact to
the solver's tolerance), the standard errors carry its 2e-7. A difference that would leave a
parameter's bounds is taken one-sided, inward.

Pure: nothing prints; a failed run is returned as its status and message, which the fit counts
as a failed trial.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Callable

import numpy as np

from odelab.fmi.simulate import FmuRun, run_fmu

__all__ = ["FmuFitModel"]

#: the smallest absolute difference step (a parameter whose value is 0)
MIN_STEP = 1e-8


@dataclass(frozen=True, eq=False)
class FmuFitModel:
    """One FMU case's model as a function of the fitted parameters.

    ``parameter_values(P)`` gives, for a column of fitted values, the values of ``dependent`` (the
    fitted parameters, then the [parameters] computed from them); those that are the FMU's own
    parameters (``variables``) are set before each run. ``quantities`` are the FMU's states or
    outputs the data measure.
    """

    run: FmuRun
    x0: np.ndarray
    dependent: tuple[str, ...]
    parameter_values: Callable
    variables: dict  # parameter name -> the FMU's Var
    states: tuple[str, ...]
    outputs: tuple[str, ...]
    quantities: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    runs: list = field(default_factory=lambda: [0])  # the FMU's runs so far (one counter, shared by copies)

    def simulate(self, p: np.ndarray, times: np.ndarray, *, t0: float, tf: float, method: str, rtol: float,
                 atol: float, max_steps: int | None):
        """The quantities (k, nq) at ``times`` for parameters ``p``, or None and the run's status and message."""
        values = dict(self.run.values)
        for name, value in zip(self.dependent, self.parameter_values(np.asarray(p, dtype=float)[:, None])):
            if name in self.variables:
                values[self.variables[name]] = float(np.real(np.ravel(value)[0]))
        run = FmuRun(self.run.model, self.run.interface, values, self.run.signals)
        self.runs[0] += 1
        tspan = np.unique(np.concatenate([[t0], np.asarray(times, dtype=float), [tf]]))
        options = {"rtol": rtol, "atol": atol}
        if max_steps:
            options["max_steps"] = max_steps
        t, x, _u, _stats, status, message, *_ = run_fmu(run, self.x0, tspan, method, options)
        run_info = SimpleNamespace(status=status, message=message)
        if status != "success":
            return None, run_info
        # the row at each measured time; after an event at that very time, the row after it (MATLAB's)
        rows = np.searchsorted(t, times, side="right") - 1
        if np.any(rows < 0) or not np.array_equal(t[np.clip(rows, 0, None)], times):
            return None, SimpleNamespace(status="failed", message=f"the FMU's run ended at t = {t[-1]:.10g}, before "
                                                                  "the last measured time.")
        y = run.last[1] if run.last is not None else np.zeros((t.size, 0))
        columns = [x[rows, self.states.index(q)] if q in self.states else y[rows, self.outputs.index(q)]
                   for q in self.quantities]
        return np.column_stack(columns), run_info

    def solve(self, p: np.ndarray, times: np.ndarray, *, rtol: float, **run) -> tuple:
        """(y (k, nq), dy/dp (k, nq, m), the run's status and message): central differences, or one-sided
        at a bound; y None when a run failed."""
        p = np.asarray(p, dtype=float)
        y, info = self.simulate(p, times, rtol=rtol, **run)
        if y is None:
            return None, None, info
        rel = rtol ** (1.0 / 3.0)
        dy = np.empty((*y.shape, p.size))
        for i in range(p.size):
            h = max(rel * abs(p[i]), MIN_STEP)
            if np.isfinite(self.upper[i] - self.lower[i]):  # at least one side fits between the bounds
                h = min(h, 0.25 * (self.upper[i] - self.lower[i]))
            up, down = p[i] + h <= self.upper[i], p[i] - h >= self.lower[i]
            plus, minus = p.copy(), p.copy()
            plus[i] += h if up else 0.0
            minus[i] -= h if down else 0.0
            y_plus, info = self.simulate(plus, times, rtol=rtol, **run) if up else (y, info)
            if y_plus is None:
                return None, None, info
            y_minus, info = self.simulate(minus, times, rtol=rtol, **run) if down else (y, info)
            if y_minus is None:
                return None, None, info
            dy[..., i] = (y_plus - y_minus) / (plus[i] - minus[i])
        return y, dy, SimpleNamespace(status="success", message="")
