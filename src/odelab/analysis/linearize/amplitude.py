"""For how large an input does the linear model stay good? :func:`amplitude_study`."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.analysis.linearize._system import _names
from odelab.analysis.linearize.comparison import (
    LinearizationComparison,
    compare_linearization,
)
from odelab.exceptions import InputError
from odelab.solvers.registry import DEFAULT_METHOD


@dataclass(frozen=True)
class AmplitudeStudy:
    """How the linearisation error grows with the size of the input.

    Attributes
    ----------
    amplitudes
        The amplitudes studied, increasing.
    quantity
        The name (output or state) whose error decides ``max_amplitude_within``.
    threshold
        The largest acceptable relative error.
    relative_error, absolute_error
        The max relative / absolute error of ``quantity``, one per amplitude.
    max_rel_error, max_abs_error
        Name (every state and output) -> array of errors, one per amplitude.
    comparisons
        The :class:`LinearizationComparison` of each amplitude.
    max_amplitude_within
        The largest *tested* amplitude a such that the relative error of ``quantity`` is
        within ``threshold`` (<=) for a and every smaller tested amplitude, and every run up
        to a succeeded; None if the smallest amplitude already exceeds it. No interpolation.
    threshold_amplitude
        An estimate of the amplitude where the error reaches ``threshold``: linear
        interpolation of log(error) against log(amplitude) between ``max_amplitude_within``
        and the next tested amplitude (the error is close to a power law c a^p there). None
        when the threshold is not crossed within the tested range.
    """

    amplitudes: np.ndarray
    quantity: str
    threshold: float
    relative_error: np.ndarray
    absolute_error: np.ndarray
    max_rel_error: Mapping[str, np.ndarray]
    max_abs_error: Mapping[str, np.ndarray]
    comparisons: tuple[LinearizationComparison, ...] = field(repr=False)
    max_amplitude_within: float | None = None
    threshold_amplitude: float | None = None

    def slope(self, name: str | None = None) -> float:
        """The least-squares slope p of log(relative error) against log(amplitude).

        The relative error behaves like c a^p: p = 2 about a point where the nonlinearity
        is odd (the first neglected term is cubic), p = 1 where a quadratic term remains.
        ``name`` defaults to ``quantity``; amplitudes with zero or non-finite error are left out.
        """
        name = self.quantity if name is None else name
        if name not in self.max_rel_error:
            raise InputError(f"{name!r} is not a state or output of the study; use one of {list(self.max_rel_error)}.", key="name")
        err = np.asarray(self.max_rel_error[name], dtype=float)
        ok = np.isfinite(err) & (err > 0)
        if np.count_nonzero(ok) < 2:
            raise InputError(f"the slope needs at least two amplitudes with a positive, finite error for {name!r}.", key="name")
        return float(np.polyfit(np.log(self.amplitudes[ok]), np.log(err[ok]), 1)[0])

    def __repr__(self) -> str:
        return (
            f"AmplitudeStudy(quantity={self.quantity!r}, threshold={self.threshold:g}, "
            f"amplitudes={self.amplitudes.tolist()}, relative_error="
            f"{[float(f'{e:.3g}') for e in self.relative_error]}, "
            f"max_amplitude_within={self.max_amplitude_within}, "
            f"threshold_amplitude={self.threshold_amplitude})"
        )


def amplitude_study(
    system,
    linear,
    make_input: Callable[[float], Any],
    amplitudes: Sequence[float],
    x_init,
    tspan,
    *,
    threshold: float = 0.05,
    quantity: str | None = None,
    method: str = DEFAULT_METHOD,
    **options,
) -> AmplitudeStudy:
    """For how large an input does the linear model stay good? Compare at several amplitudes.

    Parameters
    ----------
    system, linear
        The nonlinear system and its linearisation (with an operating point).
    make_input
        ``make_input(a)`` returns the input signal(s) for amplitude ``a``, e.g.
        ``lambda a: Step(time=1, initial=f_bar, final=f_bar + a)``.
    amplitudes
        Positive amplitudes (sorted here). To study negative inputs, let ``make_input``
        flip the sign.
    x_init, tspan, method, **options
        As for :func:`compare_linearization`; the same for every amplitude.
    threshold
        The acceptable relative error (default 5 %).
    quantity
        The output or state whose relative error is judged; default the first output.

    Returns
    -------
    AmplitudeStudy
        A failed run (e.g. the nonlinear model blows up) counts as exceeding the threshold.
    """
    if not callable(make_input):
        raise InputError(f"`make_input` must be a function of the amplitude; got {make_input!r}.", key="make_input")
    try:
        a = np.array(amplitudes, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"`amplitudes` must be numbers; got {amplitudes!r}.", key="amplitudes") from None
    if a.size == 0 or not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise InputError(
            f"`amplitudes` must be positive, finite numbers (at least one); got {a.tolist()}. "
            "To study negative inputs, let `make_input` flip the sign.",
            key="amplitudes",
        )
    a = np.unique(a)
    if not (isinstance(threshold, (int, float)) and math.isfinite(threshold) and threshold > 0):
        raise InputError(f"`threshold` must be positive; got {threshold!r}.", key="threshold")
    states, outputs = _names(system, "states"), _names(system, "outputs")
    if quantity is None:
        quantity = outputs[0] if outputs else states[0]
    elif quantity not in outputs and quantity not in states:
        raise InputError(
            f"`quantity` must be an output ({', '.join(outputs)}) or a state "
            f"({', '.join(states)}); got {quantity!r}.",
            key="quantity",
        )

    comparisons = tuple(
        compare_linearization(system, linear, make_input(float(ai)), x_init, tspan, method=method, **options)
        for ai in a
    )
    names = list(dict.fromkeys([*states, *outputs]))
    rel = {n: np.array([c.max_rel_error[n] for c in comparisons]) for n in names}
    abs_ = {n: np.array([c.max_abs_error[n] for c in comparisons]) for n in names}
    err = np.array([c.error(quantity).max_rel_error for c in comparisons])
    err_abs = np.array([c.error(quantity).max_abs_error for c in comparisons])
    for arr in (*rel.values(), *abs_.values(), err, err_abs):
        arr.setflags(write=False)
    a.setflags(write=False)

    ok = np.array([c.success for c in comparisons]) & (err <= threshold)
    k = int(np.argmin(ok)) if not ok.all() else a.size  # index of the first amplitude not within
    max_within = float(a[k - 1]) if k > 0 else None
    threshold_amplitude = None
    if 0 < k < a.size and comparisons[k].success and err[k - 1] > 0 and np.isfinite(err[k]):
        la, lb = math.log(a[k - 1]), math.log(a[k])
        ea, eb = math.log(err[k - 1]), math.log(err[k])
        if eb > ea:
            threshold_amplitude = float(math.exp(la + (math.log(threshold) - ea) * (lb - la) / (eb - ea)))
    return AmplitudeStudy(
        amplitudes=a,
        quantity=quantity,
        threshold=float(threshold),
        relative_error=err,
        absolute_error=err_abs,
        max_rel_error=rel,
        max_abs_error=abs_,
        comparisons=comparisons,
        max_amplitude_within=max_within,
        threshold_amplitude=threshold_amplitude,
    )
