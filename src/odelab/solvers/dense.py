"""Dense output: each step's continuous extension, the interpolant ``Solution.deval`` asks.

An embedded Runge-Kutta step from ``(t, y)`` with step ``h`` and stage derivatives ``K`` (s, n)
has a continuous extension (MATLAB's ``ntrp23``/``ntrp45``; Shampine & Reichelt, *The MATLAB
ODE Suite*, SIAM J. Sci. Comput. 18(1), 1997, Sec. 4)

    y(t + s h) = y + h * sum_j K_j * sum_m D[j, m] * s**(m+1),      0 <= s <= 1,

with ``D`` the tableau's ``dense`` array. The same formula serves the solver's ``Refine``
output, MATLAB's vector-``tspan`` output, event location (:mod:`odelab.solvers.events`) and
``deval`` (:func:`odelab.solution.deval`); a new method plugs in by giving its tableau a
``dense`` array. ``odextend`` lives beside ``solve`` (:mod:`odelab.solvers.api`).

With ``NonNegative`` components the interpolated values of those components are clipped at
zero (and their slopes zeroed where clipped), as MATLAB's ``ntrp45`` does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from odelab.exceptions import InputError
from odelab.solvers.ordered import backwards, combine, stage

__all__ = ["basis_slopes", "basis_values", "clip_nonnegative", "query_times", "refine_weights", "step_value",
           "step_slopes", "StageCompletion", "DenseOutput"]


#: Times a deval evaluates at once (DenseOutput.__call__): larger queries go block by block, so that
#: evaluating a long solution at a million times (the error estimate's second solve) does not hold the
#: stages of every time at once (about 1 kB a time for ode45: 8 MB a block).
DEVAL_BLOCK = 8192


def query_times(tq, start: float, stop: float) -> tuple[np.ndarray, bool]:
    """``deval``'s times as a flat float array, and whether a scalar was given.

    Refuses anything but real numbers, and times outside [start, stop] (MATLAB's deval does not
    extrapolate), with the message users see.
    """
    tq_arr = np.asarray(tq)
    if np.iscomplexobj(tq_arr) or not np.issubdtype(tq_arr.dtype, np.number) or tq_arr.dtype == bool:
        raise InputError(f"`t` must be a time or a sequence of times; got {tq!r}.", key="t")
    times = np.atleast_1d(tq_arr).astype(float).ravel()
    lo, hi = sorted((start, stop))
    outside = (times < lo) | (times > hi) | ~np.isfinite(times)
    if outside.any():
        bad = float(times[int(np.argmax(outside))])
        raise InputError(
            f"cannot evaluate the solution at t = {bad:g}: it covers [{lo:g}, {hi:g}] only "
            "(MATLAB's deval refuses to extrapolate too). Use odextend to continue the solution.",
            key="t",
        )
    return times, tq_arr.ndim == 0


def clip_nonnegative(values: np.ndarray, nonnegative) -> np.ndarray:
    """Set the ``nonnegative`` components of ``values`` below zero to zero, in place (MATLAB's NonNegative)."""
    if nonnegative is not None:
        part = values[..., nonnegative]
        values[..., nonnegative] = np.where(part < 0, 0.0, part)
    return values


def basis_values(s, columns: int, basis: str = "monomial") -> np.ndarray:
    """The functions the columns of a ``dense`` array multiply, at the fractions ``s``: (columns, k).

    ``"monomial"``: s, s^2, ..., s^columns (ode23/ode45). ``"chebyshev"``: T_0, ..., T_(columns-1)
    of ``2s - 1`` (Verner's interpolants, whose powers-of-s coefficients reach 1.4e6).
    """
    s = np.atleast_1d(np.asarray(s, dtype=float))
    if basis == "monomial":
        return np.cumprod(np.broadcast_to(s, (columns, s.size)), axis=0)
    x = 2.0 * s - 1.0
    out = np.empty((columns, s.size))
    out[0] = 1.0
    if columns > 1:
        out[1] = x
    for k in range(2, columns):
        out[k] = 2.0 * x * out[k - 1] - out[k - 2]
    return out


def basis_slopes(s, columns: int, basis: str = "monomial") -> np.ndarray:
    """d/ds of :func:`basis_values`, shape (columns, k)."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    if basis == "monomial":
        # (m + 1) s^m with s^m as a running product (numpy's ``**`` on arrays may use the CPU's
        # vectorised pow, whose last bit differs from the C library's)
        powers = np.cumprod(np.vstack([np.ones((1, s.size)), np.broadcast_to(s, (columns - 1, s.size))]), axis=0)
        return np.arange(1, columns + 1)[:, None] * powers
    # d/ds T_k(2s - 1) = 2 k U_(k-1)(2s - 1), with U the Chebyshev polynomials of the second kind
    x = 2.0 * s - 1.0
    u = np.empty((columns, s.size))
    u[0] = 1.0
    if columns > 1:
        u[1] = 2.0 * x
    for k in range(2, columns):
        u[k] = 2.0 * x * u[k - 1] - u[k - 2]
    out = np.zeros((columns, s.size))
    out[1:] = 2.0 * np.arange(1, columns)[:, None] * u[:-1]
    return out


def refine_weights(fractions, dense: np.ndarray, basis: str = "monomial") -> np.ndarray:
    """Each stage's weight in the extension at the fractions ``s`` of a step: (len(s), stages).

    Row j is ``sum_m dense[:, m] * basis_m(s_j)`` (summed for m = 0, 1, ...; no BLAS), what
    ``Refine``'s interior points multiply ``h K`` by, the same in every engine.
    """
    return combine(basis_values(fractions, dense.shape[1], basis).T, dense.T)


def step_value(tq: float, t: float, y: np.ndarray, h: float, K: np.ndarray, dense: np.ndarray,
               nonnegative=None, basis: str = "monomial") -> np.ndarray:
    """The step's continuous extension at one time ``tq`` (MATLAB's ``ntrp45(tq, t, y, ..., h, f)``).

    ``y + sum_j w_j K_j`` with the stage weights ``w_j = sum_m (h D[j, m]) basis_m(s)``, both
    sums in :mod:`odelab.solvers.ordered`'s order (the compiled loops' too).
    """
    if basis == "monomial":
        powers = np.cumprod(np.full(dense.shape[1], (tq - t) / h))
    else:
        powers = basis_values((tq - t) / h, dense.shape[1], basis)[:, 0]
    weights = backwards(powers) @ (h * dense).T
    value = y + backwards(weights) @ K
    return clip_nonnegative(value, nonnegative) if nonnegative is not None else value


def step_slopes(tq: np.ndarray, t: float, y: np.ndarray, h: float, K: np.ndarray, dense: np.ndarray,
                nonnegative=None, basis: str = "monomial") -> np.ndarray:
    """Derivatives of the continuous extension at the times ``tq`` (k,), shape (k, n).

    MATLAB uses these when a terminal event shortens the last step to ``[t, te]``: the stage
    derivatives of the shortened step are replaced by the extension's slopes at its nodes, so
    that output on the shortened step interpolates the same curve.
    """
    s = (np.asarray(tq, dtype=float) - t) / h
    q = dense.shape[1]
    # d/ds of s^(m+1) is (m+1) s^m; divided by h for d/dt, times the h in front: cancels.
    dpow = basis_slopes(s, q, basis)  # (q, k)
    slopes = combine(combine(dpow.T, dense.T), K)
    if nonnegative is not None:
        powers = basis_values(s, q, basis)
        values = y[None, :] + combine(combine(powers.T, (h * dense).T), K)
        part = slopes[:, nonnegative]
        slopes[:, nonnegative] = np.where(values[:, nonnegative] < 0, 0.0, part)
    return slopes


class StageCompletion:
    """Evaluates the interpolation stages of a non-FSAL pair's steps when ``deval`` first needs them.

    ``ode78``/``ode89`` (Verner's pairs) need a few stages beyond the step's own for their
    continuous extension; the engine evaluates them only for steps it interpolates itself
    (``Refine``, output times, events). The other steps are completed here, on first use,
    with the same formula: stage ``s+1+j`` is ``f(t + c_j h, y + h A_j . K)``, in the
    increment form the engine uses (``K`` holds ``K_0`` and ``K_j - K_0``; ``A_extra`` acts on them).
    """

    def __init__(self, fun, A_extra: np.ndarray, c_extra: np.ndarray, stages: int, complete: np.ndarray):
        self.fun = fun
        self.A_extra = A_extra
        self.c_extra = c_extra
        self.stages = stages
        self.complete = np.array(complete, dtype=bool)
        self.nfevals = 0  # evaluations made after the integration (not in the solver's Stats)

    def __call__(self, dense: "DenseOutput", idx: np.ndarray) -> None:
        todo = np.unique(idx[~self.complete[idx]])
        s = self.stages
        for i in todo:
            t, h, y, K = float(dense.t[i]), float(dense.h[i]), dense.y[i], dense.K[i]
            for j, cj in enumerate(self.c_extra):
                row = s + 1 + j  # the engine's stage sum, bit for bit (odelab.solvers.ordered)
                K[row] = self.fun(t + cj * h, stage(y, self.A_extra[j, :row] * h, K[:row]))
                K[row] -= K[0]
            self.nfevals += self.c_extra.size
            self.complete[i] = True


@dataclass(frozen=True, eq=False)
class DenseOutput:
    """The piecewise continuous extension of a whole solution (MATLAB's ``sol.idata``).

    Attributes
    ----------
    t, h
        Start and size of each accepted step, shape (N,).
    y
        State at the start of each step, shape (N, n).
    K
        Stage derivatives of each step, shape (N, s, n).
    coefficients
        The method's continuous-extension array ``D`` (s, q).
    y_final
        The state at the end of the last step (returned exactly at that time).
    nonnegative
        Indices of components clipped at zero, or None.
    completion
        For a non-FSAL pair, the :class:`StageCompletion` that evaluates a step's interpolation
        stages the first time that step is evaluated; None otherwise.
    basis
        What the columns of ``coefficients`` multiply (:func:`basis_values`).
    """

    t: np.ndarray
    h: np.ndarray
    y: np.ndarray
    K: np.ndarray
    coefficients: np.ndarray
    y_final: np.ndarray
    nonnegative: np.ndarray | None = None
    completion: StageCompletion | None = None
    basis: str = "monomial"

    @property
    def t_start(self) -> float:
        return float(self.t[0])

    @property
    def t_end(self) -> float:
        return float(self.t[-1] + self.h[-1])

    def __call__(self, tq, derivative: bool = False):
        """States at the times ``tq``: shape (n,) for a scalar, (k, n) for a sequence.

        With ``derivative=True``, ``(states, slopes)``: the slopes are the interpolant's
        derivative d/dt at those times (MATLAB's ``[y, yp] = deval(sol, t)``).
        """
        times, scalar = query_times(tq, self.t_start, self.t_end)
        if times.size <= DEVAL_BLOCK:
            values, slopes = self._evaluate(times, derivative)
        else:  # a block at a time: the temporaries (stages, weights: ~1 kB a time) stay bounded, the bits the same
            n = self.y.shape[1]
            values = np.empty((times.size, n), dtype=np.result_type(self.y, self.K))
            slopes = np.empty_like(values) if derivative else None
            for lo in range(0, times.size, DEVAL_BLOCK):
                part, part_slopes = self._evaluate(times[lo:lo + DEVAL_BLOCK], derivative)
                values[lo:lo + DEVAL_BLOCK] = part
                if derivative:
                    slopes[lo:lo + DEVAL_BLOCK] = part_slopes
        if derivative:
            return (values[0], slopes[0]) if scalar else (values, slopes)
        return values[0] if scalar else values

    def _evaluate(self, times: np.ndarray, derivative: bool):
        """``(values, slopes or None)`` at the checked ``times``; each time's row from its own step alone."""
        tdir = 1.0 if self.h[0] > 0 else -1.0
        # Step i covers [t_i, t_i + h_i); a time on a step boundary takes the later step at s = 0,
        # which is that step's stored start state exactly.
        idx = np.searchsorted(tdir * self.t, tdir * times, side="right") - 1
        idx = np.clip(idx, 0, self.t.size - 1)
        if self.completion is not None:
            self.completion(self, idx)
        h = self.h[idx]
        s = (times - self.t[idx]) / h
        q = self.coefficients.shape[1]
        K = self.K[idx]
        # step_value's formula for all times at once (the same bits): stage weights, then stages
        powers = basis_values(s, q, self.basis).T  # (k, q)
        D_T = self.coefficients.T  # (q, stages)
        weights = combine(powers, h[:, None, None] * D_T[None, :, :])
        values = self.y[idx] + combine(weights, K)
        values[times == self.t_end] = self.y_final
        if derivative:
            # d/ds of the basis, divided by h for d/dt, times the h in front: cancels
            slopes = combine(combine(basis_slopes(s, q, self.basis).T, D_T[None, :, :]), K)
        if self.nonnegative is not None:
            if derivative:
                part = slopes[:, self.nonnegative]
                slopes[:, self.nonnegative] = np.where(values[:, self.nonnegative] < 0, 0.0, part)
            clip_nonnegative(values, self.nonnegative)
        return values, (slopes if derivative else None)

    def extended(self, other: "DenseOutput") -> "DenseOutput":
        """This extension followed by ``other`` (which must start where this one ends)."""
        for part in (self, other):  # complete every step now: the joined arrays are new
            if part.completion is not None:
                part.completion(part, np.arange(part.t.size))
        return DenseOutput(
            t=np.concatenate([self.t, other.t]),
            h=np.concatenate([self.h, other.h]),
            y=np.concatenate([self.y, other.y]),
            K=np.concatenate([self.K, other.K]),
            coefficients=self.coefficients,
            y_final=other.y_final,
            nonnegative=self.nonnegative,
            basis=self.basis,
        )
