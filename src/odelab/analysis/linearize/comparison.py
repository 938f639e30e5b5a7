"""How good is the linear model? :func:`compare_linearization` simulates both models."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.analysis.linearize._system import _check_system, _names
from odelab.analysis.linearize.operating_point import OperatingPoint
from odelab.exceptions import InputError
from odelab.solvers.registry import DEFAULT_METHOD
from odelab.systems.nonlinear import as_vector

# ---------------------------------------------------------------------------------------
# How good is the linear model?
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ErrorMeasure:
    """How far the linear model is from the nonlinear one for one state or output.

    Attributes
    ----------
    max_abs_error
        max_t |z_nl(t) - z_lin(t)|, with z_lin in absolute variables (x̄ or ȳ added back).
    max_rel_error
        ``max_abs_error / peak_deviation``.
    peak_deviation
        max_t |z_nl(t) - z̄|: the size of the incremental response, the normalisation.

    Notes
    -----
    The relative error is normalised by the peak incremental response, not pointwise: a
    pointwise |z_nl - z_lin| / |z_nl - z̄| is undefined where the response crosses the
    operating point (and |z_nl - z_lin| / |z_nl| measures x̄, not the model). When the
    response does not move at all (peak 0), the relative error is 0 if the models agree
    exactly and inf otherwise.
    """

    max_abs_error: float
    max_rel_error: float
    peak_deviation: float


def _error_measure(z_nl: np.ndarray, z_lin: np.ndarray, z_bar: float) -> ErrorMeasure:
    if z_nl.size == 0:
        return ErrorMeasure(math.nan, math.nan, math.nan)
    abs_err = float(np.max(np.abs(z_nl - z_lin)))
    peak = float(np.max(np.abs(z_nl - z_bar)))
    if peak > 0:
        rel = abs_err / peak
    else:
        rel = 0.0 if abs_err == 0 else math.inf
    return ErrorMeasure(abs_err, rel, peak)


@dataclass(frozen=True)
class LinearizationComparison:
    """The nonlinear and the linear model simulated with the same input, side by side.

    Attributes
    ----------
    t
        The common output times, shape (N,).
    x_nonlinear, x_linear
        States, shape (N, nx), both in absolute variables (x̄ added back to the linear run).
    y_nonlinear, y_linear
        Outputs, shape (N, ny), both absolute (ȳ added back).
    u
        The input applied to the nonlinear model, shape (N, nu).
    states, inputs, outputs
        Names.
    operating_point
        The linear model's :class:`OperatingPoint`.
    state_errors, output_errors
        Name -> :class:`ErrorMeasure`.
    status, message
        ``"success"``, or ``"failed"`` when either simulation stopped early (the errors then
        cover the times both reached); the message says which and why.
    nonlinear, linear
        The two :class:`~odelab.systems.simulate.Response` objects as simulated (the linear
        one in incremental variables).
    """

    t: np.ndarray
    x_nonlinear: np.ndarray
    x_linear: np.ndarray
    y_nonlinear: np.ndarray
    y_linear: np.ndarray
    u: np.ndarray
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    operating_point: OperatingPoint
    state_errors: Mapping[str, ErrorMeasure]
    output_errors: Mapping[str, ErrorMeasure]
    status: str = "success"
    message: str = ""
    nonlinear: Any = field(default=None, repr=False, compare=False)
    linear: Any = field(default=None, repr=False, compare=False)

    @property
    def success(self) -> bool:
        return self.status == "success"

    def error(self, name: str) -> ErrorMeasure:
        """The :class:`ErrorMeasure` of an output or, failing that, a state, by name."""
        if name in self.output_errors:
            return self.output_errors[name]
        if name in self.state_errors:
            return self.state_errors[name]
        raise InputError(
            f"{name!r} is neither an output ({', '.join(self.outputs)}) nor a state "
            f"({', '.join(self.states)}).",
            key="quantity",
        )

    @property
    def max_abs_error(self) -> dict[str, float]:
        """Name -> max absolute error, states then outputs (an output sharing a state's name wins)."""
        return {k: e.max_abs_error for k, e in {**self.state_errors, **self.output_errors}.items()}

    @property
    def max_rel_error(self) -> dict[str, float]:
        """Name -> max error relative to the peak incremental response (see ErrorMeasure)."""
        return {k: e.max_rel_error for k, e in {**self.state_errors, **self.output_errors}.items()}

    def __repr__(self) -> str:
        rel = ", ".join(f"{k}={v:.3g}" for k, v in self.max_rel_error.items())
        return f"LinearizationComparison(status={self.status!r}, points={self.t.size}, max_rel_error: {rel})"


def _deviation_signals(u, inputs: tuple[str, ...], u_bar: np.ndarray):
    """The input of the linear model, û = u - ū, one signal per input."""
    from odelab.signals import as_signals

    signals = as_signals(u, inputs)
    return tuple(s - float(ub) if ub != 0 else s for s, ub in zip(signals, u_bar))


def _common_times(t_nl: np.ndarray) -> np.ndarray:
    """The nonlinear run's output times as a strictly increasing tspan for the linear run.

    A run restarted at a breakpoint may report that time twice (before and after the
    jump); the linear run is asked for each time once and its values are spread back.
    """
    return np.unique(t_nl)


def compare_linearization(
    system,
    linear,
    u,
    x_init,
    tspan,
    *,
    method: str = DEFAULT_METHOD,
    **options,
) -> LinearizationComparison:
    """Simulate the nonlinear system and its linearisation with the same input; compare.

    Parameters
    ----------
    system
        The nonlinear system.
    linear
        Its linearisation, a StateSpace from :func:`linearize` (it must carry an
        ``operating_point``).
    u
        The input of the nonlinear system: a signal (one input), a sequence or a mapping of
        signals, or None (zero input).
    x_init
        The nonlinear system's initial state x(0).
    tspan
        ``[t0, tf]`` or output times, as for :func:`~odelab.systems.simulate.simulate`.
    method, **options
        Solver and its options (``rtol``, ``atol``, ``max_step``...), used for both runs.

    Returns
    -------
    LinearizationComparison

    Notes
    -----
    The linear model runs in incremental variables, as in the lab: input û = u - ū, initial
    state x̂(0) = x(0) - x̄; then x̄ and ȳ are added back. It is evaluated at the nonlinear
    run's output times (passed as its ``tspan``), so both are compared point by point on
    the same grid, and the comparison measures the model, not an interpolation. The
    relative errors are normalised by the peak incremental response, see
    :class:`ErrorMeasure`.
    """
    from odelab.systems.simulate import simulate

    _check_system(system)
    op = getattr(linear, "operating_point", None)
    if not isinstance(op, OperatingPoint):
        raise InputError(
            "`linear` has no operating point: build it with linearize(system, ...), which "
            "records x̄, ū and ȳ, so the comparison knows what to add back.",
            key="linear",
        )
    states, inputs, outputs = (_names(system, w) for w in ("states", "inputs", "outputs"))
    for what, mine, theirs in (
        ("states", states, tuple(linear.states)),
        ("inputs", inputs, tuple(linear.inputs)),
        ("outputs", outputs, tuple(linear.outputs)),
    ):
        if len(mine) != len(theirs):
            raise InputError(
                f"`linear` has {len(theirs)} {what} ({', '.join(theirs)}) but `system` has "
                f"{len(mine)} ({', '.join(mine)}): it is not a linearisation of this system.",
                key="linear",
            )
    x_init = as_vector(x_init, states, "x_init", word="state")

    nl = simulate(system, tspan, x_init, u, method=method, **options)
    t = np.asarray(nl.t, dtype=float)
    du = _deviation_signals(u, inputs, op.u)
    t_lin = _common_times(t)
    if t_lin.size >= 2:
        lin = simulate(linear, t_lin, x_init - op.x, du if inputs else None, method=method, **options)
    else:  # the nonlinear run stopped at once; nothing to compare
        lin = None

    n = t.size
    if lin is not None and lin.t.size == t_lin.size and np.array_equal(lin.t, t_lin):
        index = np.searchsorted(t_lin, t)
        x_lin = np.asarray(lin.x)[index] + op.x
        y_lin = np.asarray(lin.y)[index] + op.y
        n_ok = n
    else:  # the linear run stopped early (or never ran): compare where both have values
        reached = 0 if lin is None else int(np.searchsorted(t, lin.t[-1], side="right")) if lin.t.size else 0
        n_ok = min(reached, n)
        x_lin = np.full((n, len(states)), np.nan)
        y_lin = np.full((n, len(outputs)), np.nan)
        if lin is not None and n_ok:
            index = np.searchsorted(np.asarray(lin.t), t[:n_ok])
            x_lin[:n_ok] = np.asarray(lin.x)[index] + op.x
            y_lin[:n_ok] = np.asarray(lin.y)[index] + op.y
    x_nl, y_nl = np.asarray(nl.x, dtype=float), np.asarray(nl.y, dtype=float)

    state_errors = {
        s: _error_measure(x_nl[:n_ok, i], x_lin[:n_ok, i], op.x[i]) for i, s in enumerate(states)
    }
    output_errors = {
        s: _error_measure(y_nl[:n_ok, i], y_lin[:n_ok, i], op.y[i]) for i, s in enumerate(outputs)
    }
    problems = []
    if nl.status != "success":
        problems.append(f"the nonlinear run failed: {nl.message}")
    if lin is None:
        problems.append("the linear run was not started (the nonlinear run gave fewer than 2 times)")
    elif lin.status != "success":
        problems.append(f"the linear run failed: {lin.message}")
    if problems:
        status = "failed"
        message = "; ".join(problems) + f" The errors cover t <= {t[n_ok - 1]:g}." if n_ok else "; ".join(problems)
    else:
        status, message = "success", "Both runs reached the end of the time span."
    return LinearizationComparison(
        t=t,
        x_nonlinear=x_nl,
        x_linear=x_lin,
        y_nonlinear=y_nl,
        y_linear=y_lin,
        u=np.asarray(nl.u, dtype=float),
        states=states,
        inputs=inputs,
        outputs=outputs,
        operating_point=op,
        state_errors=state_errors,
        output_errors=output_errors,
        status=status,
        message=message,
        nonlinear=nl,
        linear=lin,
    )
