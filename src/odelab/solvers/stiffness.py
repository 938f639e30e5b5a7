"""Is a run that hit its step limit stiff, or only long? A cheap indicator for the message.

An explicit Runge-Kutta method on a stiff problem is held at its **stability** limit: its step
h times the fastest eigenvalue of the Jacobian, |h lambda|, sits at the edge of the method's
stability region (about 3.3 for ode45, 2.5 for ode23 on the negative real axis) however smooth
the solution is. On a long non-stiff run the step is set by **accuracy** and |h lambda| stays
well inside. So, where the run stopped, estimate the spectral radius of the Jacobian (forward
differences: n + 1 evaluations, or a few power-iteration steps for large systems) and compare
|h| rho(J) with the method's stability boundary (Shampine & Gordon; Hairer & Wanner IV.2 use
the same test inside DOPRI5). A problem is stiff only if that fastest mode is also much faster
than the solution itself moves (rho(J) at least ten times |f| / max|y|); a crude tolerance on
a plain oscillator also reaches the stability edge, and is not stiff. Nothing here runs unless
a run has stopped at its step limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["STIFF_RATIO", "StepLimitDiagnosis", "diagnose_step_limit", "stability_boundary", "step_limit_advice"]

STIFF_RATIO = 0.5  # |h| rho(J) at least this fraction of the stability boundary: held by stability
SPREAD = 10.0  # and rho(J) at least this many times the solution's own rate |f| / |y|
_DENSE_MAX = 64  # up to this many states: the whole difference Jacobian and its eigenvalues
_POWER_STEPS = 30


@lru_cache(maxsize=64)
def _boundary(A: tuple, b: tuple) -> float:
    A = np.array(A, dtype=float)
    b = np.array(b, dtype=float)
    s = b.size
    # R(z) = 1 + sum_k z^k b^T A^(k-1) 1 for an explicit method (A strictly lower triangular)
    coef = [1.0]
    v = np.ones(s)
    for _ in range(s):
        coef.append(float(b @ v))
        v = A @ v
    x = np.linspace(0.0, 2.0 * s + 2.0, 40001)
    r = np.abs(np.polynomial.polynomial.polyval(-x, coef))
    outside = np.nonzero(r > 1.0 + 1e-9)[0]
    outside = outside[outside > 0]
    return float(x[outside[0] - 1]) if outside.size else float(x[-1])


def stability_boundary(A: np.ndarray, b: np.ndarray) -> float:
    """Where an explicit Runge-Kutta method's stability region ends on the negative real axis.

    The largest x with |R(-s)| <= 1 for all 0 <= s <= x, R the method's stability polynomial:
    2 for Euler, Heun and the midpoint rule, 2.51 for Kutta's third order and ode23, 2.79 for
    RK4, 3.31 for ode45 (Dormand-Prince).
    """
    b = np.asarray(b, dtype=float).reshape(-1)
    A = np.asarray(A, dtype=float)
    square = np.zeros((b.size, b.size))  # SciPy stores A without its last (zero) column
    square[:A.shape[0], :A.shape[1]] = A
    return _boundary(tuple(map(tuple, square.tolist())), tuple(b.tolist()))


@dataclass(frozen=True)
class StepLimitDiagnosis:
    """What the indicator found where a run stopped."""

    h: float  # the last step size
    rho: float  # the estimated spectral radius of the Jacobian there
    rate: float  # how fast the solution itself moves there: max|f| / (max|y| over the run)
    boundary: float  # the method's stability boundary

    @property
    def at_limit(self) -> bool:
        """|h| rho at least STIFF_RATIO of the stability boundary: the step is at the stability edge."""
        return self.h_rho >= STIFF_RATIO * self.boundary

    @property
    def stiff(self) -> bool:
        """At the stability edge, and the fastest mode much faster than the solution moves."""
        return self.at_limit and self.rho >= SPREAD * self.rate

    @property
    def h_rho(self) -> float:
        return abs(self.h) * self.rho


def _spectral_radius(fun, t: float, y: np.ndarray, f0: np.ndarray) -> float:
    n = y.size
    scale = np.maximum(np.abs(y), 1e-8 * max(1.0, float(np.max(np.abs(y))) if n else 1.0))
    if n <= _DENSE_MAX:
        J = np.empty((n, n))
        for j in range(n):
            d = math.sqrt(np.finfo(float).eps) * scale[j]
            yj = y.copy()
            yj[j] += d
            J[:, j] = (np.asarray(fun(t, yj), dtype=float).reshape(n) - f0) / ((y[j] + d) - y[j])
        return float(np.max(np.abs(np.linalg.eigvals(J)))) if np.all(np.isfinite(J)) else math.nan
    rng = np.random.default_rng(0)
    v = rng.standard_normal(n)
    v /= np.linalg.norm(v)
    size = float(np.linalg.norm(y)) or 1.0
    rho = math.nan
    for _ in range(_POWER_STEPS):
        d = math.sqrt(np.finfo(float).eps) * size
        w = (np.asarray(fun(t, y + d * v), dtype=float).reshape(n) - f0) / d
        norm = float(np.linalg.norm(w))
        if not math.isfinite(norm) or norm == 0.0:
            return rho if norm == 0.0 else math.nan
        rho, v = norm, w / norm
    return rho


def diagnose_step_limit(fun, t: float, y, h: float, A: np.ndarray, b: np.ndarray,
                        scale: float | None = None) -> StepLimitDiagnosis | None:
    """Whether the step ``h`` at ``(t, y)`` is held by stability (stiff) or by accuracy.

    ``A``, ``b``: the explicit method's tableau. ``scale``: the size of the solution over the
    run (max |y|; default |y| here), against which its rate of change |f| is measured. Returns
    None when no estimate can be made (the right-hand side raises or returns non-finite values
    there, or h is not a number).
    """
    try:
        y = np.array(y, dtype=float).reshape(-1)
        if not (math.isfinite(h) and h != 0.0 and y.size and np.all(np.isfinite(y))):
            return None
        f0 = np.asarray(fun(t, y.copy()), dtype=float).reshape(y.size)
        if not np.all(np.isfinite(f0)):
            return None
        rho = _spectral_radius(fun, t, y, f0)
        boundary = stability_boundary(A, b)
    except Exception:  # the indicator is a courtesy: a failing right-hand side leaves it out
        return None
    if not math.isfinite(rho):
        return None
    size = max(float(np.max(np.abs(y))), float(scale) if scale is not None and math.isfinite(scale) else 0.0)
    rate = float(np.max(np.abs(f0))) / size if size > 0 else math.inf
    return StepLimitDiagnosis(h=float(h), rho=rho, rate=rate, boundary=boundary)


def _round_up(n: float) -> int:
    """A budget a little above n, in two significant digits (41,000 rather than 40,317)."""
    n = max(1.0, 1.2 * n)
    unit = 10 ** max(0, int(math.floor(math.log10(n))) - 1)
    return int(math.ceil(n / unit) * unit)


def step_limit_advice(name: str, diagnosis: StepLimitDiagnosis | None, max_steps: int, t0: float, t_stop: float,
                      tf: float) -> str:
    """What to tell the user of a non-stiff method ``name`` stopped by ``max_steps`` at ``t_stop`` of [t0, tf]."""
    stiff_advice = ("use method 'ode15s' (or 'ode23s' at crude tolerances), which take a few hundred steps where "
                    "explicit methods need millions; or raise max_steps.")
    if diagnosis is None:
        return (f"the problem may be stiff (then {stiff_advice[:-1]}), or the run is just long (then raise "
                "max_steps: odelab run --max-steps N).")
    step = (f"the last step h = {abs(diagnosis.h):.3g} times the Jacobian's fastest rate |lambda| = "
            f"{diagnosis.rho:.3g} is {diagnosis.h_rho:.3g}")
    if diagnosis.stiff:
        return (f"the problem is probably stiff: {stiff_advice} Its steps are held by stability, not accuracy: "
                f"{step}, at {name}'s stability limit {diagnosis.boundary:.3g}.")
    if not diagnosis.at_limit:
        why = f"{step}, well inside {name}'s stability limit {diagnosis.boundary:.3g}"
    else:
        why = (f"the Jacobian's fastest rate, |lambda| = {diagnosis.rho:.3g}, is no faster than the solution itself "
               f"moves ({diagnosis.rate:.3g}), so the steps follow the solution")
    done = abs(t_stop - t0)
    needed = max_steps * abs(tf - t0) / done if done > 0 else math.inf
    pace = (f" At this pace the span needs about {needed:,.0f} steps: raise max_steps to {_round_up(needed):,} "
            f"(odelab run --max-steps {_round_up(needed)}, or max_steps under [solver])."
            if math.isfinite(needed) else " Raise max_steps (odelab run --max-steps N, or max_steps under [solver]).")
    return f"the run is long, not stiff: its steps are set by accuracy ({why}).{pace}"
