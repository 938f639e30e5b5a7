"""MATLAB's ``ode113``: variable-step, variable-order Adams-Bashforth-Moulton PECE.

The method is Shampine & Gordon's ``STEP`` and ``INTRP`` (L. F. Shampine, M. K. Gordon,
*Computer Solution of Ordinary Differential Equations: the Initial Value Problem*, Freeman,
1975, chapters 5-7), which MATLAB's ``ode113`` implements (Shampine & Reichelt, *The MATLAB ODE
Suite*, SIAM J. Sci. Comput. 18(1), 1997, Sec. 3):

* the solution is carried as the value ``y_n`` and the *modified divided differences*
  ``phi_1 .. phi_{k+1}`` of ``f`` at the last k+1 points, with ``psi_i = t_{n+1} - t_{n+1-i}``;
  the coefficients ``alpha, beta, sigma`` and the integration coefficients ``g`` follow from
  the step sizes by the recurrences of Sec. 5 (``g`` through the work vectors ``v, w``), and
  are recomputed only while the step has changed within the last k steps (``ns``);
* one step is PECE: predict ``p = y + h sum_{i<=k} g_i phi*_i`` (Adams-Bashforth of order k),
  evaluate ``f(t+h, p)``, estimate the local errors at orders k, k-1, k-2, and if the step is
  accepted correct with the order-k+1 Adams-Moulton formula ``y = p + h g_{k+1} (f - phi_1)``
  (local extrapolation: the error estimate is the order-k corrector's) and evaluate again: two
  evaluations per step;
* the order starts at 1 and rises by one each step, the step doubling, until an order would be
  lowered or reaches 12 ("phase 1"); afterwards it goes down when the estimates at orders k-1
  (and k-2) are no larger than at order k, up when the order-k+1 estimate is smaller after k+1
  steps of one size; the step doubles when the error at the new order is 2^-(k+1) of the
  tolerance, else keeps its size unless that error exceeds half the tolerance, when it shrinks
  by ``(0.5 rtol/err)^(1/(k+1))`` clipped to [0.5, 0.9];
* a rejected step restores ``phi`` and ``psi`` and halves the step, on the third consecutive
  failure drops to order 1, and from the fourth shrinks by ``sqrt(0.5 rtol/err)`` when smaller;
* output between steps is ``INTRP``: the order-k+1 interpolating polynomial through the step's
  end, evaluated with its own ``g, rho`` recurrences (MATLAB's ``ntrp113``).

MATLAB's ``ode113`` differs from ``STEP`` in the error norm (the MATLAB weight
``max(|y|, atol/rtol)`` and the max norm, or the 2-norm with ``NormControl``, tested against
``rtol``), its initial step, hmin ``16 eps(t)``, MaxStep and landing on ``tfinal``; this module
follows MATLAB there. Like ``ode45`` in :mod:`odelab.solvers.engine` the driver is plain arrays
and scalars. :func:`ode113` is the public ``odelab.ode113``; :func:`drive_multistep` the registry's driver of
its kind (the explicit pairs' preparation and output, :func:`odelab.solvers.api.drive_adaptive`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from odelab.solution import Solution
from odelab.solvers.api import drive_adaptive, solve
from odelab.solvers.controller import clamp_step, first_step, given_step
from odelab.solvers.dense import clip_nonnegative, query_times
from odelab.solvers.ordered import backwards, combine, norm as _norm2
from odelab.solvers.output import DriverResult, NonNegative, StepOutput
from odelab.solvers.status import Status

__all__ = ["ode113", "drive_multistep", "MAX_ORDER", "integrate_ode113", "AdamsDenseOutput", "ntrp113"]

MAX_ORDER = 12  # highest predictor order k; the corrector (local extrapolation) is order k+1 <= 13
# Shampine & Gordon's gstar_i: the constant-step error constants |gamma*_i| (book, Table 5.1 / STEP's
# data statement), used to estimate the errors at orders k-2 .. k+1.
GSTAR = np.array([np.nan, 0.5, 0.0833, 0.0417, 0.0264, 0.0188, 0.0143, 0.0114, 0.00936, 0.00789, 0.00679,
                  0.00592, 0.00524, 0.00468])  # 1-based
_accumulate = np.add.accumulate
_max = np.maximum.reduce  # ndarray.max without its Python wrapper (the same value, NaN included)
_POW2 = [2.0 ** i for i in range(MAX_ORDER + 2)]
_GSTAR = GSTAR.tolist()  # the same numbers as Python floats (the loop's scalar arithmetic)
_NCOL = MAX_ORDER + 3  # phi columns 1 .. k+2 (1-based; column 0 unused, always zero)
_SMALL = 16  # up to this many components, the error norms' maxima are taken by Python (cheaper than numpy's)
_V0 = [0.0] + [1.0 / (iq * (iq + 1)) for iq in range(1, MAX_ORDER + 2)]  # v_iq of a constant step (1-based)


def _inv_weight(y, threshold, norm_control):
    if norm_control:
        return 1.0 / max(_norm2(y), float(threshold))
    return 1.0 / np.maximum(np.abs(y), threshold)


def _wnorm(v, invwt, norm_control) -> float:
    if norm_control:
        return _norm2(v) * invwt
    return float(_max(np.abs(v * invwt)))


def _interpolation_coefficients(hi: np.ndarray, psi: np.ndarray, ki: int):
    """INTRP's ``g`` and ``rho`` for offsets ``hi`` (m,) from the step's end; shapes (m, ki).

    ``psi`` holds ``psi_1 .. psi_{ki-1}`` (0-based), one row per offset (m, >= ki-1) or one for
    all (>= ki-1,). ``g_j`` weighs ``phi_j`` in the value,
    ``rho_j`` in the derivative (Shampine & Gordon, Sec. 6, subroutine INTRP).
    """
    m = hi.size
    g = np.ones((m, ki))
    rho = np.ones((m, ki))
    w = np.broadcast_to(1.0 / np.arange(1, ki + 1), (m, ki)).copy()
    term = np.zeros(m)
    for j in range(2, ki + 1):
        psi_j = psi[..., j - 2]
        gamma = (hi + term) / psi_j
        eta = hi / psi_j
        top = ki + 1 - j
        w[:, :top] = gamma[:, None] * w[:, :top] - eta[:, None] * w[:, 1:top + 1]
        g[:, j - 1] = w[:, 0]
        rho[:, j - 1] = gamma * rho[:, j - 2]
        term = psi_j
    return g, rho


def ntrp113(tq, t, y, phi, psi, ki, nonnegative=None):
    """The Adams interpolant of one step at times ``tq`` (m,): values (m, n) and slopes (m, n).

    ``t, y`` are the step's end and the solution there; ``phi`` (ki, n) the differences after
    the step and ``psi`` (ki-1,) the spacings (MATLAB's ``ntrp113``).
    """
    hi = np.asarray(tq, dtype=float).reshape(-1) - t
    g, rho = _interpolation_coefficients(hi, psi, ki)
    values = y + hi[:, None] * combine(g, phi)  # sums in index order (ordered.py): no BLAS
    slopes = combine(rho, phi)
    if nonnegative is not None:
        part = values[:, nonnegative]
        neg = part < 0
        values[:, nonnegative] = np.where(neg, 0.0, part)
        slopes[:, nonnegative] = np.where(neg, 0.0, slopes[:, nonnegative])
    return values, slopes


@dataclass(frozen=True, eq=False)
class AdamsDenseOutput:
    """The piecewise Adams interpolant of a whole ode113 solution (MATLAB's ``sol.idata`` for ode113).

    Attributes
    ----------
    t, t_end
        Start and end of each accepted step (N,); a terminal event's step ends at the event.
    t_ref, y_ref
        Where each step's polynomial is anchored: the end of the step as taken and the
        solution there, (N,) and (N, n).
    order
        Number of differences of each step's polynomial (``k + 1``), (N,).
    offsets, phi
        Step i's differences are ``phi[offsets[i] : offsets[i] + order[i]]`` of the flat array phi.
    psi
        ``psi_1 .. psi_12`` of each step, (N, 12) (unused entries 1).
    y_final
        The state at the end (returned exactly there).
    nonnegative
        Indices of components clipped at zero, or None.
    """

    t: np.ndarray
    t_end: np.ndarray
    t_ref: np.ndarray
    y_ref: np.ndarray
    order: np.ndarray
    offsets: np.ndarray
    phi: np.ndarray
    psi: np.ndarray
    y_final: np.ndarray
    nonnegative: np.ndarray | None = None

    @property
    def t_start(self) -> float:
        return float(self.t[0])

    @property
    def t_stop(self) -> float:
        return float(self.t_end[-1])

    def __call__(self, tq, derivative: bool = False):
        """States at the times ``tq``: shape (n,) for a scalar, (m, n) for a sequence; with
        ``derivative=True``, ``(states, slopes)`` (the interpolant's d/dt, MATLAB's ``ntrp113`` ``ypint``)."""
        times, scalar = query_times(tq, self.t_start, self.t_stop)
        tdir = 1.0 if self.t_end[0] > self.t[0] else -1.0
        # Step i covers (t_i, t_end_i]: a time on a boundary takes the step that ends there.
        idx = np.clip(np.searchsorted(tdir * self.t_end, tdir * times, side="left"), 0, self.t.size - 1)
        n = self.y_ref.shape[1]
        width = int(self.order.max())
        phi = np.zeros((times.size, width, n), dtype=self.phi.dtype)
        orders = self.order[idx]
        for j in range(width):
            has = orders > j
            phi[has, j] = self.phi[self.offsets[idx[has]] + j]
        hi_all = times - self.t_ref[idx]
        values = np.empty((times.size, n), dtype=self.y_ref.dtype)
        slopes = np.empty_like(values) if derivative else None
        # One INTRP recurrence per distinct order (its length depends on the order).
        for ki in np.unique(orders):
            sel = np.flatnonzero(orders == ki)
            g, rho = _interpolation_coefficients(hi_all[sel], self.psi[idx[sel]], int(ki))
            values[sel] = self.y_ref[idx[sel]] + hi_all[sel, None] * combine(g, phi[sel, :ki])
            if derivative:
                slopes[sel] = combine(rho, phi[sel, :ki])
        values[times == self.t_stop] = self.y_final
        if derivative and self.nonnegative is not None:
            part = slopes[:, self.nonnegative]
            slopes[:, self.nonnegative] = np.where(values[:, self.nonnegative] < 0, 0.0, part)
        clip_nonnegative(values, self.nonnegative)
        if derivative:
            return (values[0], slopes[0]) if scalar else (values, slopes)
        return values[0] if scalar else values

    def extended(self, other: "AdamsDenseOutput") -> "AdamsDenseOutput":
        """This interpolant followed by ``other`` (which must start where this one ends)."""
        return AdamsDenseOutput(
            t=np.concatenate([self.t, other.t]), t_end=np.concatenate([self.t_end, other.t_end]),
            t_ref=np.concatenate([self.t_ref, other.t_ref]), y_ref=np.concatenate([self.y_ref, other.y_ref]),
            order=np.concatenate([self.order, other.order]),
            offsets=np.concatenate([self.offsets, other.offsets + self.phi.shape[0]]),
            phi=np.concatenate([self.phi, other.phi]), psi=np.concatenate([self.psi, other.psi]),
            y_final=other.y_final, nonnegative=self.nonnegative,
        )


class _Adams:
    """Shampine & Gordon's method state, 1-based as in the book: the modified divided differences
    ``phi[1..k+2]`` (rows of an array), the spacings ``psi``, the coefficients ``alpha, beta,
    sigma``, the integration coefficients ``g`` and their work vector ``v`` (Python lists),
    the order ``k`` and the bookkeeping of which coefficients are still valid (``ns``)."""

    __slots__ = ("phi", "psi", "alpha", "beta", "sig", "v", "g", "k", "klast", "hlast", "ns", "phase1",
                 "g_order", "g_arr", "anchor", "nonnegative", "zero", "small", "row", "lead", "back", "trio")

    def __init__(self, f0: np.ndarray, dtype, nonnegative=None):
        self.nonnegative = nonnegative
        self.anchor = (0.0, f0, 1)  # (t, y, k+1) of the last accepted step's interpolant
        self.phi = np.zeros((_NCOL, f0.size), dtype=dtype)
        self.phi[1] = f0
        phi = self.phi  # views of its rows, made once (indexing an array costs more than a list):
        self.row = list(phi)  # phi_i
        self.lead = [phi[1:j + 1] for j in range(_NCOL)]  # phi_1 .. phi_j
        self.back = [phi[j:0:-1] for j in range(_NCOL)]  # phi_j .. phi_1
        self.trio = [phi[max(j - 1, 0):j + 2] for j in range(_NCOL)]  # phi_{j-1} .. phi_{j+1}
        self.zero = np.zeros_like(f0, dtype=dtype)  # a row of phi set to zero (a copy: cheaper than a fill)
        self.small = f0.size <= _SMALL
        self.psi = [0.0] * 14
        self.alpha = [0.0] * 14
        self.beta = [0.0] * 14
        self.sig = [0.0] * 15
        self.sig[1] = 1.0
        self.v = [0.0] * 15
        self.g = [0.0] * 15
        self.g[1], self.g[2] = 1.0, 0.5
        self.k = 1
        self.g_order = 0  # the order g_arr = g[1..k] was copied for (0: none)
        self.g_arr = None
        self.klast = 0
        self.hlast = 0.0
        self.ns = 0
        self.phase1 = True

    def coefficients(self, h: float, ns: int, k: int) -> None:
        """The coefficients of a step of size ``h`` at order ``k`` (book, Sec. 5): those from ``ns``
        on (``ns - 1``: the steps of this size so far; the others are still valid)."""
        psi, alpha, beta, sig, v, g = self.psi, self.alpha, self.beta, self.sig, self.v, self.g
        self.g_order = 0  # g changes: the array copy is stale
        b = beta[ns] = 1.0
        alpha[ns] = 1.0 / ns
        temp1 = h * ns
        s = sig[ns + 1] = 1.0
        for i in range(ns + 1, k + 1):
            temp2 = psi[i - 1]
            psi[i - 1] = temp1
            b = beta[i] = b * temp1 / temp2
            temp1 = temp2 + h
            a = alpha[i] = h / temp1
            s = sig[i + 1] = i * a * s
        psi[k] = temp1
        if ns == 1:  # constant-step values of the integration coefficients
            v[1:k + 1] = w = _V0[1:k + 1]  # w: the work vector 0-based, w[iq - 1] = w_iq
        else:
            if k > self.klast:  # the order went up: the new diagonal entry of v
                v[k] = _V0[k]
                for j in range(1, ns - 1):
                    v[k - j] -= alpha[j + 1] * v[k - j + 1]
            a = alpha[ns]
            for iq in range(1, k + 2 - ns):
                v[iq] -= a * v[iq + 1]
            w = v[1:k + 2 - ns]
            g[ns + 1] = w[0]
        for i in range(ns + 2, k + 2):
            a = alpha[i - 1]
            for iq in range(k + 2 - i):
                w[iq] -= a * w[iq + 1]
            g[i] = w[0]

    def predict(self, y: np.ndarray, h: float) -> np.ndarray:
        """The coefficients of a step ``h``, phi -> phi*, and the prediction ``p = y + h sum g_i
        phi*_i``; phi becomes the differences at ``t + h``."""
        ns = 0 if h != self.hlast else self.ns
        if ns <= self.klast:
            ns += 1
        self.ns = ns
        k, row = self.k, self.row
        if k >= ns:  # the step size changed within the last k steps
            self.coefficients(h, ns, k)
            if k > ns:
                self.phi[ns + 1:k + 1] *= np.array(self.beta[ns + 1:k + 1])[:, None]
        row[k + 2][...] = row[k + 1]
        row[k + 1][...] = self.zero
        if self.g_order != k:
            self.g_arr = backwards(np.array(self.g[1:k + 1]))  # read backwards: numpy's own loop, not BLAS
            self.g_order = k
        # sum_i g_i phi_i in index order, whatever the BLAS (ordered.py: a negatively strided vector and a
        # 3-D operand keep numpy.dot off gemv, whose kernels differ by CPU in their last bits)
        p = y + h * self.g_arr.dot(self.lead[k][None])[0]
        backwards_rows = self.back[k]  # phi_i <- phi_i + ... + phi_k: numpy.cumsum's sums, in place
        _accumulate(backwards_rows, 0, None, backwards_rows)
        return p

    def errors(self, yp: np.ndarray, p: np.ndarray, h: float, absh: float, invwt, norm_control: bool):
        """The local errors at orders k, k-1, k-2 as if the step had been constant, the order they
        suggest and the corrected solution: ``(err, erk, erkm1, knew, ynew)``."""
        k, phi, g, sig = self.k, self.phi, self.g, self.sig
        phikp1 = yp - self.row[1]
        if norm_control:
            temp3 = _wnorm(phikp1, invwt, True)
            nkm1 = _wnorm(phi[k] + phikp1, invwt, True) if k >= 2 else 0.0
            nkm2 = _wnorm(phi[k - 1] + phikp1, invwt, True) if k >= 3 else 0.0
        else:
            # the three weighted max norms in one array operation: rows k-1, k and k+1 of phi
            # (row k+1 is zero after the prediction, row 0 always) plus phikp1
            rows = np.abs((self.trio[k] + phikp1) * invwt)
            if self.small:
                nkm2, nkm1, temp3 = rows.tolist()
                if sum(nkm2) + sum(nkm1) + sum(temp3) < math.inf:  # no NaN (nor inf): Python's max is numpy's
                    nkm2, nkm1, temp3 = max(nkm2), max(nkm1), max(temp3)
                else:  # numpy's maximum: NaN wherever a component is NaN
                    nkm2, nkm1, temp3 = _max(rows, axis=1).tolist()
            else:
                nkm2, nkm1, temp3 = _max(rows, axis=1).tolist()
            if k < 3:
                nkm2 = 0.0
                if k < 2:
                    nkm1 = 0.0
        err = absh * (g[k] - g[k + 1]) * temp3
        erk = absh * sig[k + 1] * _GSTAR[k] * temp3
        erkm1 = absh * sig[k] * _GSTAR[k - 1] * nkm1 if k >= 2 else 0.0
        erkm2 = absh * sig[k - 1] * _GSTAR[k - 2] * nkm2 if k >= 3 else 0.0
        knew = k
        if k == 2 and erkm1 <= 0.5 * erk:
            knew = 1
        if k > 2 and max(erkm1, erkm2) <= erk:
            knew = k - 1
        return err, erk, erkm1, knew, p + (h * g[k + 1]) * phikp1

    def restore(self, h: float) -> None:
        """A rejected step: restore phi and psi (book, block 3)."""
        k, phi, psi = self.k, self.phi, self.psi
        self.phase1 = False
        phi[1:k + 1] = (phi[1:k + 1] - phi[2:k + 2]) / np.array(self.beta[1:k + 1])[:, None]
        for i in range(2, k + 1):
            psi[i - 1] = psi[i] - h

    def accept(self, yp: np.ndarray, h: float, knew: int, erk: float, erkm1: float, absh: float, invwt,
               norm_control: bool, rtol: float) -> float:
        """An accepted step: the differences after the corrected evaluation ``yp``, the order for
        the next step (book, block 4) and its size: doubled in phase 1 or when the error at the
        new order is 2^-(k+1) of half the tolerance, shrunk when it exceeds half the tolerance."""
        k, row = self.k, self.row
        self.klast = k
        self.hlast = h
        new, last = row[k + 1], row[k + 2]
        np.subtract(yp, row[1], out=new)
        np.subtract(new, last, out=last)  # phi_{k+2}: the difference of order k+2 (for erkp1)
        lead = self.lead[k]
        lead += new
        if knew == k - 1 or k == MAX_ORDER:
            self.phase1 = False
        if self.phase1:
            self.k = k + 1
            return 2.0 * absh
        if knew == k - 1:
            k, erk = k - 1, erkm1
        elif k + 1 <= self.ns:
            erkp1 = absh * _GSTAR[k + 1] * (_wnorm(last, invwt, True) if norm_control
                                            else float(_max(np.abs(last * invwt))))
            if k == 1:
                if erkp1 < 0.5 * erk:
                    k, erk = 2, erkp1
            elif erkm1 <= min(erk, erkp1):
                k, erk = k - 1, erkm1
            elif erkp1 < erk and k < MAX_ORDER:
                k, erk = k + 1, erkp1
        self.k = k
        if 0.5 * rtol >= erk * _POW2[k + 1]:
            return 2.0 * absh
        if 0.5 * rtol < erk:
            return absh * max(0.5, min(0.9, (0.5 * rtol / erk) ** (1.0 / (k + 1))))
        return absh

    def value_at(self, tq: float) -> np.ndarray:
        """The last accepted step's interpolant at one time (events)."""
        t, y, ki = self.anchor
        return ntrp113(np.array([tq]), t, y, self.phi[1:ki + 1], np.array(self.psi[1:ki]), ki, self.nonnegative)[0][0]

    def values(self, times, rows) -> None:
        """The interpolant at the vector-tspan entries inside the step, into ``rows``."""
        t, y, ki = self.anchor
        rows[...] = ntrp113(np.array(times), t, y, self.phi[1:ki + 1], np.array(self.psi[1:ki]), ki,
                            self.nonnegative)[0]

    def interior(self, times) -> np.ndarray:
        """The interpolant at the step's interior Refine times."""
        t, y, ki = self.anchor
        return ntrp113(times, t, y, self.phi[1:ki + 1], np.array(self.psi[1:ki]), ki, self.nonnegative)[0]


def _shrink_after_failure(absh: float, hmin: float, failed: int, knew: int, erk: float, rtol: float):
    """ode113's step after its ``failed``-th consecutive rejection: halved, on the third failure
    at order 1, from the fourth by ``sqrt(0.5 rtol/erk)`` when smaller; ``(absh, k)``."""
    reduce = 0.5
    if failed == 3:
        knew = 1
    elif failed > 3:
        reduce = min(0.5, math.sqrt(0.5 * rtol / erk))
        knew = 1
    return max(reduce * absh, hmin), knew


def _dense_output(store, orders, psi_rows, cut, nonnegative, y_final) -> AdamsDenseOutput | None:
    """The piecewise interpolant from the step records (phi), each step's order ``k + 1`` and its
    spacings ``psi_rows`` (``psi_1 .. psi_12``, those beyond the step's ``k`` unused); each step's
    polynomial is anchored at its end, except a terminal event's step: ``cut`` holds its anchor
    ``(t, y)`` (or None). Returns ``y_final`` (the output's last row) at its end."""
    if not store.count:
        return None
    (phi,) = store.fields
    order = np.array(orders, dtype=np.intp)
    t_ref, y_ref = store.t[1:].copy(), store.y[1:].copy()
    if cut is not None:
        t_ref[-1], y_ref[-1] = cut
    psi = np.array(psi_rows)
    psi[np.arange(MAX_ORDER) >= order[:, None] - 1] = 1.0  # unused entries 1
    offsets = np.concatenate([[0], np.cumsum(order)[:-1]]).astype(np.intp)
    flat = phi[np.arange(MAX_ORDER + 1) < order[:, None]]  # each step's first order[i] rows, in turn
    return AdamsDenseOutput(t=store.t[:-1].copy(), t_end=store.t[1:].copy(), t_ref=t_ref, y_ref=y_ref,
                            order=order, offsets=offsets, phi=flat, psi=psi, y_final=y_final.copy(),
                            nonnegative=nonnegative)


def integrate_ode113(fun, tspan, y0, f0, rtol, threshold, hmax, htry, refine, norm_control, max_steps,
                     events=None, v0=None, nonnegative=None, output_fcn=None) -> DriverResult:
    """Integrate with Shampine & Gordon's Adams PECE method as MATLAB's ``ode113`` drives it.

    Arguments are those of :func:`odelab.solvers.engine.integrate_adaptive` without the
    tableau; the result's ``steps`` is an :class:`AdamsDenseOutput` (or None). Statistics count
    as MATLAB's: each attempt evaluates ``f`` once (at the prediction), each accepted step once
    more (at the correction); the caller adds the evaluation at ``t0``.
    """
    n = y0.size
    t0, tfinal = float(tspan[0]), float(tspan[-1])
    tdir = 1.0 if tfinal > t0 else -1.0
    nn = None if nonnegative is None else NonNegative(nonnegative, threshold, norm_control)
    t, y = t0, y0.copy()
    if htry != htry:  # NaN: MATLAB's ode113 first step, Shampine & Gordon's h = 0.25 sqrt(tol / ||y'||)
        rh = _wnorm(f0, _inv_weight(y, threshold, norm_control), norm_control) / (0.25 * math.sqrt(rtol))
        absh = first_step(rh, abs(float(tspan[1]) - t0), hmax, t0)
    else:
        absh = given_step(htry, t0, hmax)
    state = _Adams(f0, y0.dtype, nonnegative)
    # each step's record: its differences phi_1 .. phi_13 (those beyond k+1 unused), its order k+1
    # and its spacings psi_1 .. psi_12 (lists); its polynomial is anchored at the step's end
    out = StepOutput(tspan, y0, refine, [((MAX_ORDER + 1, n), y0.dtype)], events, v0, output_fcn)
    add, per_step, phi_rows, psi = out.store.add, out.per_step, state.phi[1:MAX_ORDER + 2], state.psi
    orders, psi_rows = [], []
    cut_ref = None  # a terminal event's step: the anchor (t, y) of its polynomial, beyond the cut
    nsteps = nfailed = nfevals = 0
    status = success = Status.SUCCESS  # a local: the enum's attribute lookup costs more than a step's test
    exception = None
    h = tdir * absh
    try:
        while True:
            hmin, absh, done = clamp_step(t, tfinal, absh, hmax)  # stretched to land on tfinal
            h = tfinal - t if done else tdir * absh
            invwt = _inv_weight(y, threshold, True) if norm_control else 1.0 / np.maximum(np.abs(y), threshold)
            failed = 0
            while True:
                p = state.predict(y, h)
                tnew = tfinal if done else t + h
                yp = fun(tnew, p)
                nfevals += 1
                err, erk, erkm1, knew, ynew = state.errors(yp, p, h, absh, invwt, norm_control)
                if nn is not None and err <= rtol and nn.negative(ynew):
                    # a negative value of a non-negative component counts as error
                    err_nn = (_norm2(nn.excess(ynew)) * invwt if norm_control else nn.error(ynew))
                    if err_nn > rtol:
                        err = err_nn
                if err > rtol:  # failed: restore t, phi and psi, then halve (book, block 3)
                    nfailed += 1
                    if absh <= hmin:
                        status = Status.STEP_UNDERFLOW
                        break
                    state.restore(h)
                    failed += 1
                    absh, state.k = _shrink_after_failure(absh, hmin, failed, knew, erk, rtol)
                    h = tdir * absh
                    done = False
                elif err <= rtol:
                    break
                else:  # NaN: a derivative or the prediction is not finite
                    status = Status.NONFINITE
                    break
            if status != success:
                break
            nsteps += 1
            # correct (order k+1, local extrapolation) and evaluate; update the differences
            tlast, ylast, y = t, y, ynew
            if nn is not None:
                nn.clip(y)
            yp = fun(tnew, y)
            nfevals += 1
            ki = state.k + 1  # this step's interpolant: phi_1 .. phi_{k+1} and psi_1 .. psi_k after it
            absh_next = state.accept(yp, h, knew, erk, erkm1, absh, invwt, norm_control, rtol)
            state.anchor = (tnew, y, ki)
            t_end, y_end, stop = tnew, y, False
            if events is not None:
                cut = out.locate(state.value_at, tlast, ylast, tnew, y)
                if cut is not None:
                    (t_end, y_end), done, stop, cut_ref = cut, True, True, (tnew, y)
                    status = Status.TERMINAL_EVENT
            add(t_end, y_end, phi_rows)
            orders.append(ki)
            psi_rows.append(psi[1:MAX_ORDER + 1])
            if per_step and out.emit(tlast, t_end, y_end, stop, state.values, state.interior):
                status = Status.OUTPUT_STOP
                t = t_end
                break
            absh, t = absh_next, t_end
            if done:
                break
            if max_steps and nsteps >= max_steps:
                status = Status.MAX_STEPS
                break
    except Exception as exc:  # the user's right-hand side (or events function) failed
        status = Status.FUN_RAISED
        exception = exc
    t_arr, y_arr = out.finish()
    return DriverResult(t_arr, y_arr, nsteps, nfailed, nfevals, status, t, abs(h), exception, out.found,
                        _dense_output(out.store, orders, psi_rows, cut_ref, nonnegative, y_arr[-1]))


def drive_multistep(fun, tspan, y0, m, options: dict) -> Solution:
    """The driver of the methods of kind ``"multistep"`` (:data:`odelab.solvers.registry.DRIVERS`): the explicit
    pairs' preparation and output, stepped by :func:`integrate_ode113`."""
    return drive_adaptive(fun, tspan, y0, m, options, multistep=integrate_ode113)


def ode113(fun, tspan, y0, **options) -> Solution:
    """Solve a non-stiff ODE with MATLAB's ``ode113``: variable-order Adams-Bashforth-Moulton PECE.

    Shampine & Gordon's method (orders 1-13 as MATLAB counts them): two evaluations of ``fun``
    per step, so it wins at tight tolerances and when ``fun`` is expensive. Options as
    :func:`odelab.ode45` (``RelTol``, ``AbsTol``, ``MaxStep``, ``InitialStep``, ``Refine``
    (default 1), ``NormControl``, ``Events``, ``NonNegative``, ``Mass``, ``OutputFcn``...);
    ``deval``/``sol(t)`` evaluate the Adams interpolant (MATLAB's ``ntrp113``).

    Examples
    --------
    >>> import numpy as np, odelab
    >>> sol = odelab.ode113(lambda t, y: np.cos(t), [0, np.pi], 2.0)
    >>> sol.stats
    Stats(nsteps=14, nfailed=0, nfevals=29)
    """
    return solve(fun, tspan, y0, method="ode113", **options)
